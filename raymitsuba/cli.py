"""The ``raymitsuba`` command line (click): ``check``, ``render``, ``fit``.

Every scene error is printed as ``FILE:LINE:COLUMN: error: ...`` and exits with
status 2; nothing in the input produces a traceback.
"""

from __future__ import annotations

import sys

import click

EXIT_SCENE_ERROR = 2


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="raymitsuba")
def main():
    """raymitsuba: render .RAY scenes with Mitsuba 3, differentiably."""


@main.command()
@click.argument("scenes", nargs=-1, required=True, type=click.Path(dir_okay=False))
def check(scenes):
    """Validate .RAY SCENES and print a short summary of each."""
    raise NotImplementedError  # the parser issue fills this in


if __name__ == "__main__":
    sys.exit(main())
