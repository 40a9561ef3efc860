"""``raymitsuba render``: a .RAY scene to an image file."""

from __future__ import annotations

import gc
import sys
import time

import click
import numpy as np

from raymitsuba import images
from raymitsuba.cli.common import (EXIT_FAILURE, EXIT_SCENE_ERROR, error_message, fail,
                                   parse_or_exit, report, summarise)
from raymitsuba.cli.options import BATCH_OPTIONS, batch_options, dialect_option, render_options

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
@click.argument("scenes", nargs=-1, required=True, type=click.Path(dir_okay=False),
                metavar="SCENE...")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False),
              help="Output image: .exr (linear float), .png/.jpg (8-bit), .npy (float32 H x W x "
                   "3). With several scenes a template naming each: {stem}, {name}, {parent}, "
                   "{index} (e.g. 'out/{stem}.png', 'frames/{index:04d}.png').")
@render_options("width", "height", "spp", "max_depth", "aa", "memory_budget", "bailout",
                "time_limit", "srgb", "sphere_set")
@click.option("--tiles", type=click.IntRange(1), default=None, metavar="N",
              help="Render each image as N bands of rows, each a task for a worker (the same "
                   "image, bit for bit); finished bands are kept, so an interrupted render "
                   "resumes.")
@batch_options()
@dialect_option
def render(scenes, output, dialect, tiles, **options):
    """Render the .RAY file SCENE to OUTPUT; several SCENEs (or --tiles) in one batch on Dask
    workers, local or a cluster's."""
    batch = {name: options.pop(name) for name in BATCH_OPTIONS}
    outputs = output_names(output, scenes)
    if len(scenes) == 1 and not tiles and not any(batch.values()):
        return render_one(scenes[0], outputs[0], dialect, options)
    render_batch(scenes, outputs, dialect, tiles, batch, options)


def output_names(template, scenes):
    """The output of each scene: ``template`` filled (raymitsuba.batch.templates), or a
    usage error (status 2) before anything runs."""
    if len(scenes) == 1 and "{" not in template:
        names = [template]
    else:
        from raymitsuba.batch.templates import TemplateError, expand

        try:
            names = expand(template, scenes)
        except TemplateError as e:
            raise click.BadParameter(str(e), param_hint="--output")
    for name in names:
        try:
            images.check_writable(name)
        except images.ImageError as e:
            raise click.BadParameter(str(e), param_hint="--output")
    return names


def render_one(scene, output, dialect, options):
    """Today's single render, in this process."""
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


class BatchProgress:
    """A tqdm bar over a batch's items (pixels with tiles), on a terminal only."""

    def __init__(self, unit):
        self.unit = unit
        self.bar = None

    def __call__(self, done, total):
        if not sys.stderr.isatty():
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=total, desc="rendering", unit=self.unit,
                            unit_scale=self.unit == "px", leave=False)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def render_batch(scenes, outputs, dialect, tiles, batch, options):
    """Several scenes, or tiles, on Dask workers (raymitsuba.batch.render_many): every
    scene parsed first (errors reported as FILE:LINE:COLUMN, those scenes not rendered), a
    line for each item that failed, a one-line summary; exit status 0 (all rendered), 1
    (some failed) or 2 (a scene had an error)."""
    from raymitsuba.batch import render_many
    from raymitsuba.batch.manifest import default_path

    progress = BatchProgress("px" if tiles else "scene")
    manifest = batch.pop("manifest") or default_path(outputs)
    try:
        items = render_many(scenes, outputs, tiles=tiles, dialect=dialect, report=report,
                            progress=progress, manifest=manifest, **batch, **options)
    except KeyboardInterrupt:
        fail(COMMAND, "interrupted; the outputs finished are kept (resume with "
             "--skip-existing)", 130)
    except Exception as e:  # the cluster: no scheduler at the address, a worker refused...
        fail(COMMAND, error_message(e), EXIT_FAILURE)
    finally:
        progress.close()
    summarise(COMMAND, items, manifest)
