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
from raymitsuba.cli.options import dialect_option, parse_size

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
@click.option("--width", default=None, type=click.IntRange(1, 16384),
              help="Image width [default: the MIT 6.837 viewport's, else 512].")
@click.option("--height", default=None, type=click.IntRange(1, 16384),
              help="Image height [default: the MIT 6.837 viewport's, else 512].")
@click.option("--spp", default=1, show_default=True, type=click.IntRange(1, 4096),
              help="Samples per pixel (1: the pixel centre; more: stratified, box filter).")
@click.option("--max-depth", default=5, show_default=True, type=click.IntRange(0, 64),
              help="Bounces after the camera ray.")
@click.option("--aa", default=None, type=click.FloatRange(0, min_open=True), metavar="THRESHOLD",
              help="Adaptive anti-aliasing: pixels that differ from a neighbour by more than "
                   "THRESHOLD (linear, e.g. 0.02) get 4x4 samples, then 8x8 where those "
                   "differ by more than 5x THRESHOLD. Default: off.")
@click.option("--memory-budget", default="2G", show_default=True, metavar="SIZE",
              help="Memory a chunk of camera rays may take (e.g. 512M, 4G).")
@click.option("--bailout", default=0.0, show_default=True, type=click.FloatRange(0, 1),
              help="Do not trace rays whose path weight (product of kr / kt from the camera) "
                   "is at most this (0: the exact ray tree; 1e-3 makes deep trees cheap).")
@click.option("--time-limit", default=3600.0, show_default=True, type=click.FloatRange(0),
              metavar="SECONDS", help="Refuse renders estimated to take longer (0: no limit).")
@click.option("--srgb", is_flag=True,
              help="Encode 8-bit output with the sRGB curve and decode 8-bit textures from it.")
@dialect_option
def render(scene, output, width, height, spp, max_depth, aa, memory_budget, bailout, time_limit,
           srgb, dialect):
    """Render the .RAY file SCENE to OUTPUT."""
    try:
        images.check_writable(output)
    except images.ImageError as e:
        raise click.BadParameter(str(e), param_hint="--output")
    budget = parse_size(memory_budget)
    model = parse_or_exit(scene, dialect)
    report(model.warnings)
    width, height = model.image_size(width, height)  # the options, else the viewport, else 512

    from raymitsuba import api, backend
    from raymitsuba._llvm import LLVMError

    progress = Progress(width * height)
    BudgetError = _NotYet  # the plugins' class, once Mitsuba is set up
    try:
        backend.mitsuba(mitsuba_integrators=False)  # raywhitted only: skip Mitsuba's integrators
        from raymitsuba.plugins.whitted.chunks import BudgetError

        loaded = api.load(model, width=width, height=height, spp=spp, max_depth=max_depth,
                          srgb=srgb, aa=aa, memory_budget=budget, bailout=bailout,
                          time_limit=time_limit)
        # The scene's objects (10^4s of them) live until the command exits: out of the cyclic
        # collector's sight, so that no collection re-scans them (0.09 s at 10^4 objects);
        # given back to it at the end (the command may run inside a longer process).
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
