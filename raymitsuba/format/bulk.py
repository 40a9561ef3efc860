"""What both parsers' bulk paths share: the chunk size, and the numbers of many lines read
at once.

Each dialect's parser reads runs of *simple* lines (a command word and its numbers, ASCII,
no comment) in chunks, all of a chunk's numbers in one call, and sends every other line
down its exact, line-by-line path; the two paths give the same scene and the same
diagnostics (``tests/format/test_fast_path.py`` compares them).
"""

from __future__ import annotations

from itertools import chain, compress, repeat
from operator import eq, itemgetter
from typing import List, Optional, Tuple

from fastnumbers import RAISE, try_float

#: Lines per chunk of a bulk path: enough that the work per chunk vanishes, few enough that
#: the chunk's lists stay small.
CHUNK = 4096

OPERANDS = itemgetter(slice(1, None))


def operands(words: List[List[str]]) -> Optional[list]:
    """The operands of each line's tokens ``words`` (the command word first) as a tuple of
    floats, or None when one is not a finite float literal (or the sum of all overflows).

    The numbers are read all at once, by ``fastnumbers.try_float`` (the fast_float algorithm,
    correctly rounded: the bits ``float`` reads; it refuses what ``float`` refuses, and
    refuses ``_`` in a number, which then takes the line-by-line path); the lines of one
    token count share one flat list, regrouped into tuples by ``zip``.
    """
    counts = list(map(len, words))
    tuples_of = {}
    total = 0.0
    try:
        for n in set(counts):
            if n == 1:
                tuples_of[1] = repeat(())
                continue
            same = compress(words, map(eq, counts, repeat(n)))
            flat = try_float(list(chain.from_iterable(map(OPERANDS, same))), map=list,
                             on_fail=RAISE)
            total += sum(flat)
            tuples_of[n] = zip(*[iter(flat)] * (n - 1))
    except ValueError:  # a bad number somewhere
        return None
    if total - total != 0.0:
        return None
    return list(map(next, map(tuples_of.__getitem__, counts)))


def finite_operands(toks: List[str]) -> Optional[Tuple[float, ...]]:
    """The operands of the tokens ``toks`` of one line as floats if every one is a finite float
    literal, else None (the exact path reports)."""
    try:
        values = tuple(map(float, toks[1:]))
    except ValueError:
        return None
    total = sum(values)
    return values if total - total == 0.0 else None


def each_operands(words: List[List[str]]) -> list:
    """:func:`operands` of ``words``; where a number is bad, each line's :func:`finite_operands`
    (None for the lines that hold one)."""
    values = operands(words)
    return list(map(finite_operands, words)) if values is None else values
