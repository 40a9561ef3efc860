"""What the ``raymitsuba`` commands share: their exit statuses and how they print errors.

* 0: done;
* :data:`EXIT_FAILURE` (1): the work itself failed (LLVM, Mitsuba, writing the output);
* :data:`EXIT_SCENE_ERROR` (2): the input is wrong -- a scene error, printed as
  ``FILE:LINE:COLUMN: error: ...`` diagnostics, a bad option or an unreadable input
  file -- like click's own usage errors. Nothing is written then.
"""

from __future__ import annotations

import sys

import click

from raymitsuba.util import error_message  # noqa: F401  (the commands' one-line errors)

EXIT_FAILURE = 1
EXIT_SCENE_ERROR = 2


def report(diagnostics) -> None:
    """Print diagnostics (errors and warnings) to stderr, one ``Diagnostic.format()`` each."""
    for d in diagnostics:
        click.echo(d.format(), err=True)


def parse_or_exit(path: str, dialect: str = "auto"):
    """The scene parsed from ``path`` in ``dialect``; on errors, print its diagnostics and
    exit with :data:`EXIT_SCENE_ERROR`."""
    from raymitsuba.format import parser
    from raymitsuba.model import RayError

    try:
        return parser.parse_file(path, dialect)
    except RayError as e:
        report(e.diagnostics)
        sys.exit(EXIT_SCENE_ERROR)


def fail(command: str, message: str, code: int) -> None:
    """Print ``COMMAND: error: MESSAGE`` to stderr and exit with ``code``."""
    click.echo(f"{command}: error: {message}", err=True)
    sys.exit(code)


def summarise(command: str, items, manifest: str) -> None:
    """The end of a batch (raymitsuba.batch's items): a line for each item that failed (a
    scene's own errors were reported as FILE:LINE:COLUMN already), one line of counts,
    then exit 2 if a scene had an error, 1 if an item failed or was cancelled, else 0."""
    counts = {}
    for item in items:
        counts[item.status] = counts.get(item.status, 0) + 1
        if item.status in ("failed", "error") and not item.error.startswith(item.scene):
            click.echo(f"{command}: error: {item.scene}: {item.error}", err=True)
    said = ", ".join(f"{counts[s]} {s}" for s in ("done", "skipped", "error", "failed",
                                                   "cancelled") if s in counts)
    click.echo(f"{command}: {len(items)} scenes: {said} (manifest: {manifest})", err=True)
    if counts.get("error"):
        sys.exit(EXIT_SCENE_ERROR)
    if counts.get("failed") or counts.get("cancelled"):
        sys.exit(EXIT_FAILURE)
