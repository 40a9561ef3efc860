"""Collecting the diagnostics of one parse: errors and warnings at FILE:LINE:COLUMN.

A parse reports every problem it finds and carries on; :meth:`Diagnostics.result`
then sorts them by position and raises :class:`~raymitsuba.model.RayError` if any is
an error. The messages' shared wording (a "did you mean" hint, numbers as shown in
messages) lives here too.
"""

from __future__ import annotations

import difflib
from typing import List, Optional, Sequence, Tuple, Union

from raymitsuba.model import Diagnostic, RayError, Severity


class Diagnostics:
    """The diagnostics of one input named ``file``."""

    def __init__(self, file: str):
        self.file = file
        self.items: List[Diagnostic] = []
        self.n_errors = 0

    def add(self, severity: Severity, line: int, column: int, message: str, source: str) -> None:
        self.items.append(Diagnostic(severity, self.file, line, column, message, source))
        if severity is Severity.ERROR:
            self.n_errors += 1

    def error(self, line: int, column: int, message: str, source: str) -> None:
        self.add(Severity.ERROR, line, column, message, source)

    def warning(self, line: int, column: int, message: str, source: str) -> None:
        self.add(Severity.WARNING, line, column, message, source)

    def result(self) -> Tuple[Diagnostic, ...]:
        """Every diagnostic sorted by position; raises RayError if any is an error."""
        ordered = sorted(self.items, key=lambda d: (d.line, d.column))
        if self.n_errors:
            raise RayError(ordered)
        return tuple(ordered)


def did_you_mean(word: str, vocabulary: Sequence[str], cutoff: float = 0.6) -> Optional[str]:
    """The closest word of ``vocabulary`` to ``word`` (case-insensitive), or None."""
    lowered = {v.lower(): v for v in vocabulary}
    guess = difflib.get_close_matches(word.lower(), list(lowered), n=1, cutoff=cutoff)
    return lowered[guess[0]] if guess else None


def fmt(v: Union[float, Sequence[float]]) -> str:
    """A number or vector as messages show it."""
    if isinstance(v, (tuple, list)):
        return "(" + ", ".join(fmt(c) for c in v) + ")"
    return f"{v:g}"
