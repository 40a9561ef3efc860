"""The ``raymitsuba`` command line (click): ``check``, ``render``, ``fit``, ``convert``.

Every scene error is printed as ``FILE:LINE:COLUMN: error: ...`` and exits with
status 2; nothing in the input produces a traceback.
"""

from __future__ import annotations

import gc
import sys

import click

from raymitsuba.cli_common import EXIT_SCENE_ERROR, dialect_option


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="raymitsuba")
def main():
    """raymitsuba: render .RAY scenes with Mitsuba 3, differentiably."""


@main.command()
@click.argument("scenes", nargs=-1, required=True, type=click.Path())
@dialect_option
@click.pass_context
def check(ctx, scenes, dialect):
    """Validate .RAY SCENES and print a short summary of each.

    The summary (the dialect, objects and lights by kind, materials, the world bounding box
    of the finite objects) goes to stdout; errors and warnings go to stderr as
    FILE:LINE:COLUMN: error|warning: message. Exit status 0 when every scene is
    valid, 2 when any has an error.
    """
    from raymitsuba.summary import check_scenes

    def echo(text, err=False):
        stream = sys.stderr if err else sys.stdout
        encoding = getattr(stream, "encoding", None) or "utf-8"
        # file names may carry undecodable bytes (surrogates): never fail to print them
        click.echo(text.encode(encoding, "backslashreplace").decode(encoding), err=err)

    ctx.exit(0 if check_scenes(scenes, echo, dialect) else EXIT_SCENE_ERROR)


# The render, fit and convert commands live in modules of their own.
from raymitsuba.convert_cli import convert  # noqa: E402
from raymitsuba.fit_cli import fit  # noqa: E402
from raymitsuba.render_cli import render  # noqa: E402

main.add_command(render)
main.add_command(fit)
main.add_command(convert)


def run():
    """The ``raymitsuba`` console script and ``python -m raymitsuba``: :func:`main`, then exit.

    On the way out, every object still alive is frozen (``gc.freeze``) so that the
    interpreter's shutdown does not trace them again in its final garbage collections:
    with Mitsuba, Dr.Jit and numpy loaded that took ~0.1 s of a ~1 s render command.
    Output files are complete and closed by then; atexit handlers still run and objects
    freed by reference counting are still finalized; the OS reclaims the rest.
    """
    try:
        main()  # click's standalone mode: always ends with SystemExit
    finally:
        gc.freeze()


if __name__ == "__main__":
    run()
