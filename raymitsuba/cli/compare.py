"""``raymitsuba compare``: is an image right, and where is it not?

``raymitsuba compare IMAGE REFERENCE`` scores one image against a reference image or a
.RAY scene (rendered at IMAGE's size; its unstable pixels left out: see
:mod:`raymitsuba.compare.stable`), in this process. With a placeholder in IMAGE it is a
batch: ``raymitsuba compare 'submissions/{stem}.png' scenes/*.ray --report report.html``
scores each scene against the image the template names for it (``{stem}``, ``{name}``,
``{parent}``, ``{index}``: :mod:`raymitsuba.batch.templates`; a missing image is reported
as missing), on Dask workers as ``raymitsuba render``'s batches run (``-j``,
``--threads``, ``--scheduler``; :func:`raymitsuba.batch.compare.compare_many`): every
scene parsed here first (errors reported as FILE:LINE:COLUMN, those scenes not scored),
the results back here, where the pictures, the report and the CSV are written, each
atomically. ``-j 1``, or a batch of one scene, runs in this process without Dask.

Exit status: 0 every image passed ``--min-match``; 1 one failed, is missing or (on a
worker that died) could not be compared (batch);
2 bad input (an unreadable image, sizes that differ, a scene error, a bad option), in a
batch after every other scene was scored.
"""

from __future__ import annotations

import json
import os
import sys

import click

from raymitsuba.cli.common import EXIT_FAILURE, EXIT_SCENE_ERROR, error_message, fail
from raymitsuba.cli.common import report as report_diagnostics
from raymitsuba.cli.options import batch_options, dialect_option, render_options
from raymitsuba.compare import MIN_MATCH, TOLERANCE

COMMAND = "raymitsuba compare"


def _check_output(path, flag, extensions):
    """A usage error (status 2, before any work) unless ``path`` (None: not asked for) has
    one of the ``extensions`` and its folder exists."""
    if path is None:
        return
    if not path.lower().endswith(extensions):
        raise click.BadParameter(f"{path}: expected a {' or '.join(extensions)} file",
                                 param_hint=flag)
    folder = os.path.dirname(path) or "."
    if not os.path.isdir(folder):
        raise click.BadParameter(f"{path}: no folder {folder}", param_hint=flag)


def _summary(result) -> str:
    s = result.score
    if s is None:
        return f"{result.name}: {result.status}: {result.message}"
    psnr = "inf" if s.psnr == float("inf") else f"{s.psnr:.2f} dB"
    return (f"{result.name}: {result.status} {s.match:.3f} % ({s.left_out} left out, "
            f"PSNR {psnr})")


def _templates(image, references, diff):
    """The image of each reference and the ``--diff`` picture of each (None: not asked
    for), from their templates (raymitsuba.batch.templates), or a usage error (status 2)
    before anything runs."""
    from raymitsuba.batch.templates import TemplateError, expand

    try:
        images = expand(image, references, distinct=False)
    except TemplateError as e:
        raise click.BadParameter(str(e), param_hint="IMAGE")
    try:
        diffs = None if diff is None else expand(diff, references)
    except TemplateError as e:
        raise click.BadParameter(str(e), param_hint="--diff")
    return images, diffs


@click.command()
@click.argument("image", type=click.Path(dir_okay=False))
@click.argument("references", nargs=-1, required=True, type=click.Path(dir_okay=False),
                metavar="REFERENCE...")
@click.option("--tolerance", type=click.FloatRange(0, 1), default=TOLERANCE,
              show_default="2/255",
              help="A pixel matches when its largest channel difference is at most this "
                   "(values in [0, 1]).")
@click.option("--min-match", type=click.FloatRange(0, 100), default=MIN_MATCH,
              show_default=True, metavar="PERCENT",
              help="Pass when at least this percent of the scored pixels match.")
@click.option("--all-pixels", is_flag=True,
              help="Score every pixel of a scene's reference (one render; no stability "
                   "renders).")
@click.option("--json", "as_json", is_flag=True, help="Print the figures as JSON.")
@click.option("--diff", type=click.Path(dir_okay=False),
              help="Write the image, the reference and a heat map of the difference side by "
                   "side (PNG; in a batch, a template like IMAGE's: 'diffs/{stem}.png').")
@click.option("--report", type=click.Path(dir_okay=False), help="Write an HTML report.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False),
              help="Write the figures as CSV.")
@render_options("spp", "max_depth", "srgb",
                srgb="8-bit images hold sRGB-encoded values (decoded before comparing); "
                     "a scene's textures are decoded likewise.")
@batch_options("jobs", "threads", "scheduler")
@dialect_option
def compare(image, references, tolerance, min_match, all_pixels, as_json, diff, report,
            csv_path, dialect, spp, max_depth, srgb, jobs, threads, scheduler):
    """Compare IMAGE with REFERENCE: an image (.exr .png .jpg .npy .ppm) or a .RAY scene.

    With {stem} in IMAGE (or {name}, {parent}, {index}), compare every REFERENCE with the
    image named after it: a batch, on Dask workers (-j, --threads, --scheduler; -j 1: in
    this process). One comparison always runs in this process."""
    from raymitsuba import compare as comparing
    from raymitsuba.compare import report as reporting

    batch = "{" in image and _is_template(image)
    if not batch and len(references) != 1:
        raise click.UsageError("give one REFERENCE, or {stem} in IMAGE for a batch")
    paths, diffs = _templates(image, references, diff) if batch else ([image], [diff])
    for path in diffs if diff is not None else ():
        _check_output(path, "--diff", (".png",))
    _check_output(report, "--report", (".html", ".htm"))
    _check_output(csv_path, "--csv", (".csv",))
    settings = comparing.Settings(tolerance=tolerance, min_match=min_match, srgb=srgb,
                                  dialect=dialect, stable=not all_pixels,
                                  options=dict(spp=spp, max_depth=max_depth))
    if batch:
        results, said = _batch(paths, references, diffs, settings, as_json,
                               dict(jobs=jobs, threads=threads, scheduler=scheduler))
    else:
        result = comparing.compare(image, references[0], settings)
        if result.status in (comparing.ERROR, comparing.MISSING):
            fail(COMMAND, result.message, EXIT_SCENE_ERROR)
        if diff is not None:
            _write_diff(diff, result, srgb)
        results, said = [result], set()
    if report is not None:
        reporting.write_html(results, settings, report)
    if csv_path is not None:
        reporting.write_csv(results, csv_path)
    if as_json:
        records = [r.record() for r in results]
        click.echo(json.dumps(records if batch else records[0], indent=2))
    elif not batch:
        result = results[0]
        for line in result.score.lines():
            click.echo(line)
        click.echo(f"{result.status.upper()} (min match {min_match:g} %)")
    statuses = {r.status for r in results}
    if comparing.ERROR in statuses:
        for r in results:
            if r.status == comparing.ERROR and r.message not in said:  # (said: above)
                click.echo(f"{COMMAND}: error: {r.message}", err=True)
        sys.exit(EXIT_SCENE_ERROR)
    if statuses - {comparing.PASS}:
        sys.exit(EXIT_FAILURE)


def _is_template(image) -> bool:
    """Whether IMAGE has placeholders (a batch); a malformed one is a usage error."""
    from raymitsuba.batch.templates import TemplateError, placeholders

    try:
        return bool(placeholders(image))
    except TemplateError as e:
        raise click.BadParameter(str(e), param_hint="IMAGE")


def _write_diff(path, result, srgb):
    """The side-by-side picture of a scored ``result``, written atomically to ``path``."""
    if result.score is not None:
        from raymitsuba import images

        images.write(path, result.diff_picture(srgb))


def _batch(images, references, diffs, settings, as_json, where):
    """Every reference compared with its image (raymitsuba.batch.compare.compare_many): a
    line for each as it ends (unless ``as_json``), its --diff picture written (``diffs``:
    one path each, or None). Returns the results, in the references' order, and the lines
    of the errors reported already (the scenes' diagnostics)."""
    from raymitsuba.batch.compare import compare_many

    said = set()

    def report(diagnostics):
        report_diagnostics(diagnostics)
        said.update(d.format().splitlines()[0] for d in diagnostics)

    def ended(i, result):
        if diffs is not None:
            _write_diff(diffs[i], result, settings.srgb)
        if not as_json:
            click.echo(_summary(result))

    try:
        return compare_many(images, references, settings, report=report, on_result=ended,
                            **where), said
    except KeyboardInterrupt:
        fail(COMMAND, "interrupted; no report written", 130)
    except Exception as e:  # the cluster: no scheduler at the address, a worker refused...
        fail(COMMAND, error_message(e), EXIT_FAILURE)
