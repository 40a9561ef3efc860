"""``raymitsuba compare``: is an image right, and where is it not?

``raymitsuba compare IMAGE REFERENCE`` scores one image against a reference image or a
.RAY scene (rendered at IMAGE's size; its unstable pixels left out: see
:mod:`raymitsuba.compare.stable`). With ``{stem}`` in IMAGE it is a batch:
``raymitsuba compare 'submissions/{stem}.png' scenes/*.ray --report report.html`` scores
each scene against the image named by its file name without the extension (a missing
image is reported as missing). The batch runs serially, one scene after the other, each
one a call of the pure function :func:`raymitsuba.compare.compare`.

Exit status: 0 every image passed ``--min-match``; 1 one failed or is missing (batch);
2 bad input (an unreadable image, sizes that differ, a scene error, a bad option), in a
batch after every other scene was scored.
"""

from __future__ import annotations

import json
import os
import sys

import click

from raymitsuba.cli.common import EXIT_FAILURE, EXIT_SCENE_ERROR, fail
from raymitsuba.cli.options import dialect_option, render_options
from raymitsuba.compare import MIN_MATCH, TOLERANCE

COMMAND = "raymitsuba compare"
STEM = "{stem}"


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
                   "side (PNG; in a batch, a name with {stem}).")
@click.option("--report", type=click.Path(dir_okay=False), help="Write an HTML report.")
@click.option("--csv", "csv_path", type=click.Path(dir_okay=False),
              help="Write the figures as CSV.")
@render_options("spp", "max_depth", "srgb",
                srgb="8-bit images hold sRGB-encoded values (decoded before comparing); "
                     "a scene's textures are decoded likewise.")
@dialect_option
def compare(image, references, tolerance, min_match, all_pixels, as_json, diff, report,
            csv_path, dialect, spp, max_depth, srgb):
    """Compare IMAGE with REFERENCE: an image (.exr .png .jpg .npy .ppm) or a .RAY scene.

    With {stem} in IMAGE, compare every REFERENCE scene with the image named after it."""
    from raymitsuba import compare as comparing
    from raymitsuba.compare import report as reporting

    batch = STEM in image
    if not batch and len(references) != 1:
        raise click.UsageError("give one REFERENCE, or {stem} in IMAGE for a batch")
    _check_output(diff, "--diff", (".png",))
    _check_output(report, "--report", (".html", ".htm"))
    _check_output(csv_path, "--csv", (".csv",))
    if batch and diff is not None and STEM not in diff:
        raise click.BadParameter("in a batch, name the pictures with {stem}", param_hint="--diff")
    settings = comparing.Settings(tolerance=tolerance, min_match=min_match, srgb=srgb,
                                  dialect=dialect, stable=not all_pixels,
                                  options=dict(spp=spp, max_depth=max_depth))
    results = []
    for reference in references:
        stem = comparing.Result(reference, "", "").name
        path = image.replace(STEM, stem)
        result = comparing.compare(path, reference, settings)
        results.append(result)
        if not batch and result.status in (comparing.ERROR, comparing.MISSING):
            fail(COMMAND, result.message, EXIT_SCENE_ERROR)
        if diff is not None and result.score is not None:
            from raymitsuba import images

            images.write(diff.replace(STEM, stem), result.diff_picture(srgb))
        if batch and not as_json:
            click.echo(_summary(result))
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
            if r.status == comparing.ERROR:
                click.echo(f"{COMMAND}: error: {r.message}", err=True)
        sys.exit(EXIT_SCENE_ERROR)
    if statuses - {comparing.PASS}:
        sys.exit(EXIT_FAILURE)
