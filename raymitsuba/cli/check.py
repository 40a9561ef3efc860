"""``raymitsuba check``: validate .RAY scenes and summarise each."""

from __future__ import annotations

import sys

import click

from raymitsuba.cli.common import EXIT_SCENE_ERROR
from raymitsuba.cli.options import dialect_option


@click.command()
@click.argument("scenes", nargs=-1, required=True, type=click.Path())
@click.option("--params", "list_params", is_flag=True,
              help="List every parameter key of each scene instead of its summary, one line "
                   "each: KEY LINE:COL VALUE [VALUE ...] (the position of its first number, "
                   "its numbers as written).")
@dialect_option
@click.pass_context
def check(ctx, scenes, dialect, list_params):
    """Validate .RAY SCENES and print a short summary of each.

    The summary (the dialect, objects and lights by kind, materials, the world bounding box
    of the finite objects) goes to stdout; errors and warnings go to stderr as
    FILE:LINE:COLUMN: error|warning: message. Exit status 0 when every scene is
    valid, 2 when any has an error.
    """
    from raymitsuba.format.summary import check_scenes

    def echo(text, err=False):
        stream = sys.stderr if err else sys.stdout
        encoding = getattr(stream, "encoding", None) or "utf-8"
        # file names may carry undecodable bytes (surrogates): never fail to print them
        click.echo(text.encode(encoding, "backslashreplace").decode(encoding), err=err)

    ctx.exit(0 if check_scenes(scenes, echo, dialect, list_params) else EXIT_SCENE_ERROR)
