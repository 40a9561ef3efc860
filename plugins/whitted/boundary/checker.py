"""Checker lines (the package docstring, "Pairs"): the checker cell of a hit (a key), how
many lines lie between two samples' cells, a checker pair repeated once per line
(:meth:`Checker.one_crossing_per_line`) and g of a line (:meth:`Checker.checker_crossing`),
at the first hit and along the specular chain."""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from .lattice import CHAIN_CHECKER, CHECKER, POINTS, at, flat, picked
from .terms import on_lanes, stacked

# a checker pair with more lines than this between its samples is left out (the pattern
# finer than the lattice there: aliased; its lines' terms nearly cancel)
CHECKER_LINES = 8


def crossed(cells, left, right):
    """How many checker lines (u and v) lie between the cells at the flat positions ``left``
    and ``right`` (numpy, see :func:`flat`) of ``cells`` (planes of u and v cells, (2,
    ...)): an int8 array."""
    return (at(cells[0], left) != at(cells[0], right)).view(np.int8) \
        + (at(cells[1], left) != at(cells[1], right)).view(np.int8)


class Checker:
    """The checker lines of :class:`Boundary` (a mixin of Boundary)."""

    def checker_cell(self, terms, si, hit):
        """(floor(u / size), floor(v / size)) of each hit on a checkered surface, else (0, 0)
        (Dr.Jit Floats)."""
        layout = terms.surfaces.layout
        if layout.checker_size is None:
            return dr.zeros(mi.Vector2f, dr.width(hit))
        slot = terms.surfaces.slot(si.shape, si.prim_index, hit)
        size = dr.gather(mi.Float, layout.checker_size, slot, hit)
        checkered = hit & (size > 0)
        size = dr.select(checkered, size, 1.0)
        return mi.Vector2f(dr.select(checkered, dr.floor(si.uv.x / size), 0.0),
                           dr.select(checkered, dr.floor(si.uv.y / size), 0.0))

    def checker_crossing(self, terms, si, coord, line, which, g, choices, name):
        """g = u / size - m (or v) of the pairs ``which`` (numpy mask), at the hits ``si`` of
        the stacked rays (the size: at L's hit); coord (0: u, 1: v) and the line m per pair
        (numpy). ``choices``: see g_at (the size, under ``name``)."""
        lanes = dr.width(si.t)
        count = len(which)
        made = choices.get((name, "checker"))
        if made is None:  # (L's: the first point set's lanes; not a parameter)
            slot = terms.surfaces.slot(si.shape, si.prim_index, si.is_valid())
            size = dr.gather(mi.Float, terms.surfaces.layout.checker_size, slot)
            size = dr.gather(mi.Float, size, dr.arange(mi.UInt32, count))
            made = choices[(name, "checker")] = (dr.select(size > 0, size, 1.0),)
        size = on_lanes(made[0], lanes)
        u = dr.select(jit_array(mi.Bool, stacked(coord == 0, lanes)), si.uv.x, si.uv.y)
        return dr.select(jit_array(mi.Bool, stacked(which, lanes)),
                         u / size - jit_array(mi.Float, stacked(line, lanes)), g)

    def one_crossing_per_line(self, pairs):
        """``pairs`` with each checker pair repeated once per checker line between its two
        samples (u lines, then v lines: where the pattern is finer than the lattice, or a
        corner passes between them; at most CHECKER_LINES, else left out; along the
        specular chain exactly one, else left out: through a glass ball's rim, where the
        lines crowd and u is far from linear, their crossings added more error than they
        took away, measured), and what each
        entry's g is: ``coord`` (0: u, 1: v; -1: not a checker line) and ``line`` m, the
        line's index (g = u / size - m: the line between the cells m - 1 and m). Each line
        is a crossing of its own, its jump traced either side of it."""
        chain = pairs["kind"] == CHAIN_CHECKER
        checker = (pairs["kind"] == CHECKER) | chain
        low, count = [], []
        for c in (0, 1):
            a, b = (self.checker_cells(c, pairs[name], chain, pairs["depth"])
                    for name in ("L", "R"))
            low.append(np.minimum(a, b))
            count.append(np.where(checker, np.abs(a - b), 0))
        lines = count[0] + count[1]
        most = np.where(chain, 1, CHECKER_LINES)
        entries = np.where(checker, np.where(lines <= most, lines, 0), 1)
        if (entries == 1).all():  # (one line each: the pairs as they are)
            index, out = np.arange(len(entries)), dict(pairs)
        else:
            index = np.repeat(np.arange(len(entries)), entries)
            out = {name: tuple(a[index] for a in value) if name in POINTS else value[index]
                   for name, value in pairs.items()}
        j = np.arange(len(index)) - np.repeat(np.cumsum(entries) - entries, entries)
        u = j < count[0][index]
        out["coord"] = np.where(checker[index], np.where(u, 0, 1), -1)
        out["line"] = np.where(u, low[0][index] + 1 + j,
                               low[1][index] + 1 + j - count[0][index]).astype(np.float32)
        return out

    def checker_cells(self, c, points, chain, depth):
        """The checker cells (coordinate ``c``: 0 u, 1 v; int64) at the lattice ``points``
        (y, x) of each pair: the first hit's, or where ``chain``, those of the chain's
        bounce ``depth``."""
        positions = flat(points, self.cols)
        cells = at(self.cell[c], positions).astype(np.int64)
        if chain.any():
            where = np.flatnonzero(chain)
            cells[where] = picked([bounce[c] for bounce in self.chain_cell], depth[where],
                                  positions[where])
        return cells
