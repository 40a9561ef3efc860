"""The ``raymitsuba`` command line (click): one module per subcommand.

=================  ==============================================================
module             what it owns
=================  ==============================================================
``common``         exit statuses, how errors are printed, reading a scene
``options``        the options several commands share, made from one record
``check``          ``raymitsuba check``
``render``         ``raymitsuba render``
``fit``            ``raymitsuba fit``
``convert``        ``raymitsuba convert``
``compare``        ``raymitsuba compare`` (and its batch report)
=================  ==============================================================

Every scene error is printed as ``FILE:LINE:COLUMN: error: ...`` and exits with
status 2; nothing in the input produces a traceback.
"""

from __future__ import annotations

import gc
import os

# The command line's own numpy work is small (Dr.Jit renders): OpenBLAS's thread pool, which
# numpy starts on import, buys nothing here and costs a short command's start-up a good share.
# Set before the subcommands import numpy, unless the user chose a number.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import click

from raymitsuba.cli import check, compare, convert, fit, render


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="raymitsuba")
def main():
    """raymitsuba: render .RAY scenes with Mitsuba 3, differentiably."""


main.add_command(check.check)
main.add_command(render.render)
main.add_command(fit.fit)
main.add_command(convert.convert)
main.add_command(compare.compare)


def run():
    """The ``raymitsuba`` console script and ``python -m raymitsuba``: :func:`main`, then exit.

    On the way out, every object still alive is frozen (``gc.freeze``) so that the
    interpreter's shutdown does not trace them again in its final garbage collections
    (with Mitsuba, Dr.Jit and numpy loaded, a noticeable share of a short render command).
    Output files are complete and closed by then; atexit handlers still run and objects
    freed by reference counting are still finalized; the OS reclaims the rest.
    """
    try:
        main()  # click's standalone mode: always ends with SystemExit
    finally:
        gc.freeze()


if __name__ == "__main__":
    run()
