"""``raymitsuba render``: a .RAY scene to an image file."""

from __future__ import annotations

import gc
import sys
import time

import click
import numpy as np

from raymitsuba import images
from raymitsuba.cli.common import (EXIT_FAILURE, EXIT_SCENE_ERROR, error_message, fail,
                                   parse_or_exit, report)
from raymitsuba.cli.options import dialect_option, render_options

COMMAND = "raymitsuba"


class Progress:
    """A tqdm bar over the pixels rendered, chunk by chunk (its postfix counts the chunks;
    the ETA follows the pixels), shown only on a terminal and only once a render has taken
    more than two seconds (tqdm is imported only then). Anti-aliasing's passes add their
    pixels to the total as they are decided."""

    DELAY = 2.0  # seconds

    def __init__(self, total: int = 0):
        self.total = total
        self.enabled = sys.stderr.isatty()
        self.start = time.monotonic()
        self.bar = None

    def __call__(self, done: int, total: int | None = None, chunks: int | None = None):
        if total is not None:
            self.total = total
        if self.bar is None:
            if not self.enabled or time.monotonic() - self.start < self.DELAY:
                return
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, desc="rendering", unit="px", unit_scale=True,
                            leave=False)
        if self.bar.total != self.total:
            self.bar.total = self.total
        if chunks is not None:
            self.bar.set_postfix_str(f"{chunks} chunk{'s' if chunks != 1 else ''}", refresh=False)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class _NotYet(Exception):
    """Stands for an exception class not imported yet (never raised)."""


@click.command()
@click.argument("scene", type=click.Path(dir_okay=False))
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output image: .exr (linear float), .png/.jpg (8-bit), .npy (float32 H x W x 3).")
@render_options("width", "height", "spp", "max_depth", "aa", "memory_budget", "bailout",
                "time_limit", "srgb")
@dialect_option
def render(scene, output, dialect, **options):
    """Render the .RAY file SCENE to OUTPUT."""
    try:
        images.check_writable(output)
    except images.ImageError as e:
        raise click.BadParameter(str(e), param_hint="--output")
    model = parse_or_exit(scene, dialect)
    report(model.warnings)
    width, height = model.image_size(options["width"], options["height"])
    srgb, aa = bool(options["srgb"]), options["aa"]

    from raymitsuba import api, backend
    from raymitsuba._llvm import LLVMError

    progress = Progress(width * height)
    BudgetError = _NotYet  # the plugins' class, once Mitsuba is set up
    try:
        backend.mitsuba(mitsuba_integrators=False)  # raywhitted only: skip Mitsuba's integrators
        from raymitsuba.plugins.whitted.guards import BudgetError

        loaded = api.load(model, **options)
        # The scene's objects (10^4s of them) live until the command exits: out of the cyclic
        # collector's sight, so that no collection re-scans them; given back to it at the
        # end (the command may run inside a longer process).
        gc.freeze()
        integrator = loaded.integrator
        integrator.progress = progress
        if images.is_8bit(output) and not aa:
            # encoded chunk by chunk: no float copy of the whole image
            image = np.empty((width * height, 3), np.uint8)

            def store(first, values):
                image[first:first + len(values)] = images.encode_8bit(values, srgb)

            integrator.render_array(loaded.scene, store=store)
            image = image.reshape(height, width, 3)
        else:
            image = integrator.render_array(loaded.scene)
        progress.close()
        images.write(output, image, srgb=srgb)
    except BudgetError as e:
        fail(COMMAND, f"{scene}: {e}", EXIT_SCENE_ERROR)
    except LLVMError as e:
        fail(COMMAND, str(e), EXIT_FAILURE)
    except KeyboardInterrupt:
        fail(COMMAND, "interrupted; no output written", 130)
    except MemoryError:
        fail(COMMAND, f"{scene}: out of memory; lower --memory-budget or the image size",
             EXIT_FAILURE)
    except Exception as e:  # Mitsuba's own errors (e.g. a texture it cannot decode)
        fail(COMMAND, f"{scene}: {error_message(e)}", EXIT_FAILURE)
    finally:
        progress.close()
        gc.unfreeze()
