"""``raymitsuba render``: a .RAY scene to an image file."""

from __future__ import annotations

import sys
import time

import click

from raymitsuba import images
from raymitsuba.cli_common import (EXIT_FAILURE, dialect_option, error_message, fail,
                                   parse_or_exit, report)

COMMAND = "raymitsuba"


class Progress:
    """A tqdm bar over the generations of the ray tree, shown only on a terminal and
    only once a render has taken more than two seconds (tqdm is imported only then)."""

    DELAY = 2.0  # seconds

    def __init__(self, total: int):
        self.total = total
        self.enabled = sys.stderr.isatty()
        self.start = time.monotonic()
        self.bar = None

    def __call__(self, done: int):
        if self.bar is None:
            if not self.enabled or time.monotonic() - self.start < self.DELAY:
                return
            from tqdm import tqdm

            self.bar = tqdm(total=self.total, desc="rendering", unit="gen", leave=False)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None


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
@click.option("--srgb", is_flag=True,
              help="Encode 8-bit output with the sRGB curve and decode 8-bit textures from it.")
@dialect_option
def render(scene, output, width, height, spp, max_depth, srgb, dialect):
    """Render the .RAY file SCENE to OUTPUT."""
    try:
        images.check_writable(output)
    except images.ImageError as e:
        raise click.BadParameter(str(e), param_hint="--output")
    model = parse_or_exit(scene, dialect)
    report(model.warnings)

    from raymitsuba import api, backend
    from raymitsuba._llvm import LLVMError

    progress = Progress(max_depth + 1)
    try:
        backend.mitsuba(mitsuba_integrators=False)  # raywhitted only: skip Mitsuba's integrators
        loaded = api.load(model, width=width, height=height, spp=spp, max_depth=max_depth, srgb=srgb)
        loaded.integrator.progress = progress
        image = api.render(loaded).numpy()
        progress.close()
        images.write(output, image, srgb=srgb)
    except LLVMError as e:
        fail(COMMAND, str(e), EXIT_FAILURE)
    except KeyboardInterrupt:
        fail(COMMAND, "interrupted; no output written", 130)
    except Exception as e:  # Mitsuba's own errors (e.g. a texture it cannot decode)
        fail(COMMAND, f"{scene}: {error_message(e)}", EXIT_FAILURE)
    finally:
        progress.close()
