"""The pairs (the package docstring, "Pairs"): the kinds of edges the keys move
(:func:`moving_kinds`), the candidates (lattice neighbours whose keys differ), their
classification into kinds (:meth:`Pairs.classify`: every kind's, at the first hit and
along the chain) and which of them are formed (:meth:`Pairs.kept`,
:meth:`Pairs.moving_edges`)."""

from itertools import compress, repeat
from operator import attrgetter, is_not

import drjit as dr
import numpy as np

from .checker import crossed
from .lattice import (CHAIN_CHECKER, CHAIN_SHADOW, CHAIN_TIR, CHAIN_VISIBILITY, CHECKER,
                      KINDS, NO_HIT, POINTS, SHADOW, STOP, VISIBILITY, at, flat, nonzero)
from .shadows import shadow_differs


def moving_kinds(tracer, scene):
    """The kinds of pairs whose edges some key with its gradient enabled moves (empty: a
    derivative pass needs no boundary terms). A key that moves the geometry or the camera
    moves every kind; a material's eta, what is seen through glass (the specular chain's
    kinds); a light's position or direction, its shadow edges, the terminator and a spot's
    cone (the shadow kinds). The others' surrogates would have no derivative: their pairs
    are not formed."""
    if tracer.geometry_ad is not None and tracer.geometry_ad.moves():
        return set(range(KINDS))
    kinds = set()
    if tracer.surfaces is not None and eta_moves(tracer.surfaces.layout.materials):
        # eta moves what is seen through glass
        kinds |= {CHAIN_VISIBILITY, CHAIN_CHECKER, CHAIN_TIR, CHAIN_SHADOW}
    if any(light_moves(emitter) for emitter in scene.emitters()):
        kinds |= {SHADOW, CHAIN_SHADOW}
    return kinds


def eta_moves(materials):
    """Whether a key with its gradient enabled moves some material's eta (read live: a
    primal render reads the flags under ``dr.resume_grad``). Loops in C: a sphere set's
    10^5 table rows hold None until their keys are registered."""
    etas = list(map(attrgetter("ior"), materials))
    return any(map(dr.grad_enabled, compress(etas, map(is_not, etas, repeat(None)))))


def light_moves(emitter):
    """Whether a key with its gradient enabled moves ``emitter`` (its position or direction:
    its shadow edges, terminator and cone)."""
    return any(dr.grad_enabled(value) for value in
               (getattr(emitter, name, None) for name in ("position", "direction"))
               if value is not None)


class Pairs:
    """The pairs of :class:`Boundary`'s lattice (a mixin of Boundary)."""

    def pairs(self):
        """Every lattice pair with an edge between: a dict of numpy arrays (one entry per
        pair): L, R, O as (Y, X), the kind, the light (shadows), and what g is made of.

        The pairs of each axis are classified among its candidates only: the pairs whose
        samples differ in some key (a few percent of the lattice; every other pair has no
        edge between), found by one pass of comparisons over the lattice."""
        found = []
        cols = self.t.shape[1]
        bounces = self.chain_bounces()
        for axis in (1, 0):  # rows (X, X + 1), then columns (Y, Y + 1)
            ly, lx = self.candidates(axis, bounces)
            L, R = (ly, lx), (ly + (axis == 0), lx + (axis == 1))
            index, kind, light, depth = self.classify(L, R, bounces)
            # whether the entry's pair has others (edges of several kinds or lights)
            shared = np.zeros(len(kind), bool)
            if index is not None:  # (a pair across several edges: one entry each)
                ly, lx = ly[index], lx[index]
                L, R = (ly, lx), (ly + (axis == 0), lx + (axis == 1))
                shared = np.bincount(index)[index] > 1
            keep = self.kept(kind)
            if not self.camera_moves:  # (if it does, every edge moves)
                where = np.flatnonzero(keep)
                keep[where] = self.moving_edges(kind[where], light[where],
                                                flat(L, cols)[where], flat(R, cols)[where])
            ly, lx = ly[keep], lx[keep]
            points = dict(L=(ly, lx), R=(ly + (axis == 0), lx + (axis == 1)))
            found.append(dict(axis=np.full(len(ly), axis), kind=kind[keep].astype(np.int64),
                              light=light[keep].astype(np.int64), shared=shared[keep],
                              depth=depth[keep].astype(np.int64), **points))
        return self.one_crossing_per_line(
            {name: (tuple(np.concatenate([f[name][i] for f in found]) for i in range(2))
                    if name in POINTS else np.concatenate([f[name] for f in found]))
             for name in found[0]})

    def candidates(self, axis, bounces):
        """(Y, X) of L of the pairs along ``axis`` (1: rows, 0: columns) whose samples differ
        in some key (the first hit's shape, face, light and checker cell, and those of the
        chain's first ``bounces`` bounces), row-major: the lattice's order. None along the
        ring: a pair has a sample of the image."""
        lights = len(self.lights)
        # (what blocks each light first, and where it stops: their shapes, shadows.py)
        # (without glass a shadow edge is where lit differs: the blockers add no pair)
        glass = self.glass
        planes = [self.shape, self.prim, *self.lit, self.cell[0], self.cell[1]]
        if glass:
            planes += [o[..., 0] for o in self.occluder] + [o[..., 0] for o in self.stopper]
        for d in range(bounces):
            planes += [self.chain_shape[d], self.chain_prim[d], self.chain_tir[d],
                       self.chain_cell[d][0], self.chain_cell[d][1]]
            planes += self.chain_lit[d * lights:(d + 1) * lights]
            if glass:
                planes += [o[..., 0] for o in self.chain_occluder[d * lights:(d + 1) * lights]]
                planes += [o[..., 0] for o in self.chain_stopper[d * lights:(d + 1) * lights]]
        # Each entry against the one ``step`` further in row-major order (its right or lower
        # neighbour), the planes flat: comparisons of contiguous arrays, three times faster
        # than of the lattice's 2-D views (a blocker's shape plane is copied so first)
        rows, cols = self.rows, self.cols
        step = 1 if axis == 1 else cols
        differs = np.zeros(rows * cols, bool)  # (by L's flat position)
        pair, other = differs[:-step], np.empty(rows * cols - step, bool)
        for plane in planes:
            values = plane.reshape(-1)
            np.not_equal(values[:-step], values[step:], out=other)
            pair |= other
        # None along the ring: rows (L on the ring's rows, or R past the last column),
        # columns (L on the ring's columns; past the last row none is compared)
        lattice = differs.reshape(rows, cols)
        if axis == 1:
            lattice[[0, rows - 1]] = False
            lattice[:, cols - 1] = False
        else:
            lattice[:, [0, cols - 1]] = False
        return nonzero(lattice)

    def classify(self, L, R, bounces):
        """(index, kind (int8; -1: none, or left out), light, depth) of the pairs (L, R)
        (numpy (Y, X) each, one entry per pair): what edge lies between their samples.
        Where edges of several kinds, or of several lights, lie between the two samples
        on one surface (a shadow edge across a checker line, two lights' shadow edges),
        the pair has an entry for each (appended after the others: ``index``, int64, the
        pair of each entry; None: one entry a pair, in order). Each is a crossing of its
        own, its g its edge's and its jump traced either side of it (``Terms.jump``). So is
        an edge seen along the specular chain between the samples of a pair across an edge
        on the surface seen (a shadow edge on a mirror, and another object's outline in its
        reflection)."""
        L, R = flat(L, self.cols), flat(R, self.cols)  # (read at: see flat)
        visibility = self.surface_differs(self.shape, self.prim, self.normal, L, R)
        kind = np.full(visibility.shape, -1, np.int8)  # (small types: a pass per array)
        light = np.zeros(visibility.shape, self.light_type)
        kind[visibility] = VISIBILITY
        same = ~visibility & (at(self.shape, L) != NO_HIT)
        extra = []  # (pairs, kind, light, depth) of the entries past each pair's first
        # On one surface: a shadow edge per light whose keys differ, checker lines (however
        # many: one crossing each, see one_crossing_per_line)
        edges = np.zeros(visibility.shape, np.int16)
        shadows = []
        for j in range(len(self.lights)):
            edge = same & shadow_differs(self.lit[j], self.occluder[j], self.stopper[j], L, R)
            edges += edge
            shadows.append(edge)
            kind[edge], light[edge] = SHADOW, j
        lines = crossed(self.cell, L, R)  # u and v lines crossed
        checker = same & (lines > 0)
        edges += checker
        kind[checker] = CHECKER
        several = same & (edges > 1)
        if several.any():
            extra += self._entries(several, shadows, checker, SHADOW, CHECKER, -1)
            kind[several] = -1  # (its entries: appended)
        # Seen along the specular chain (mirrors, glass): the first bounce whose key
        # differs, if the first hits are alike: total internal reflection switching at
        # the surface the bounce leaves, else a visibility edge, else checker lines and
        # shadow edges (an entry each, as on the surface seen).
        depth = np.full(visibility.shape, -1, np.int8)
        pending = same & (edges == 0)
        # (a pair across an edge on the surface seen: the first bounce whose keys differ adds
        # its edges' entries, as a pair across several edges on one surface has)
        surfaced = same & (edges > 0)
        for d in range(bounces):  # (past every chain's end: no pair)
            if not (pending.any() or surfaced.any()):
                break
            cs_l, cs_r = at(self.chain_shape[d], L), at(self.chain_shape[d], R)
            tir = at(self.chain_tir[d], L) != at(self.chain_tir[d], R)
            # (another surface: another shape, or a face of a mesh across a crease, as at
            # the first hit)
            shape_differs = self.surface_differs(self.chain_shape[d], self.chain_prim[d],
                                                 self.chain_normal[3 * d:3 * d + 3], L, R)
            lines = crossed(self.chain_cell[d], L, R)
            count = np.zeros(visibility.shape, np.int16)  # shadow edges at the bounce
            edges_at = []  # each light's
            for j in range(len(self.lights)):
                index = d * len(self.lights) + j
                edge = ~shape_differs & shadow_differs(
                    self.chain_lit[index], self.chain_occluder[index], self.chain_stopper[index],
                    L, R)
                count += edge
                edges_at.append(edge & ~tir)
            shadows = [pending & edge for edge in edges_at]
            for j, edge in enumerate(shadows):
                light[edge] = j
            differs = shape_differs | (lines > 0) | tir | (count > 0)
            here = pending & differs
            chained = (cs_l != STOP) & (cs_r != STOP)
            beside = surfaced & differs
            if beside.any():
                extra += self._chain_entries(beside, chained, tir, shape_differs, lines,
                                             edges_at, d)
            # (past both chains' ends their keys no longer differ)
            surfaced &= ~beside & ((cs_l != STOP) | (cs_r != STOP))
            ok = here & ~tir & chained & (shape_differs | ((lines > 0) & (count == 0))
                                          | ((lines == 0) & (count == 1)))
            kind[ok & shape_differs] = CHAIN_VISIBILITY
            kind[ok & ~shape_differs & (lines > 0)] = CHAIN_CHECKER
            kind[ok & ~shape_differs & (count == 1)] = CHAIN_SHADOW
            several = here & ~tir & chained & ~shape_differs & ((lines > 0) + count > 1)
            if several.any():
                extra += self._entries(several, shadows, here & (lines > 0), CHAIN_SHADOW,
                                       CHAIN_CHECKER, d)
            # total internal reflection switching at the bounce's surface: what the two
            # chains meet after it differs because of it
            switch = here & tir
            kind[switch] = CHAIN_TIR
            depth[ok | switch] = d
            pending &= ~here
        if not extra:
            return None, kind, light, depth
        pairs, kinds, lights, depths = (np.concatenate(a) for a in zip(*extra))
        return (np.concatenate([np.arange(len(kind)), pairs]),
                np.concatenate([kind, kinds.astype(kind.dtype)]),
                np.concatenate([light, lights.astype(light.dtype)]),
                np.concatenate([depth, depths.astype(depth.dtype)]))

    @staticmethod
    def _entries(several, shadows, checker, shadow_kind, checker_kind, depth):
        """The entries (pairs, kind, light, depth) of the pairs ``several`` (bool) across
        more than one edge: one for each light whose shadow edge (``shadows``, bool per
        light) lies between the samples, and one for the checker lines (``checker``)."""
        out = []
        for j, edge in enumerate(shadows):
            where = np.flatnonzero(several & edge)
            out.append((where, np.full(len(where), shadow_kind), np.full(len(where), j),
                        np.full(len(where), depth)))
        where = np.flatnonzero(several & checker)
        out.append((where, np.full(len(where), checker_kind), np.zeros(len(where), int),
                    np.full(len(where), depth)))
        return out

    @classmethod
    def _chain_entries(cls, pairs, chained, tir, shape_differs, lines, shadows, depth):
        """The entries (as :meth:`_entries`) of the edges at the chain's bounce ``depth``
        between the samples of ``pairs`` (bool), as a pair with no other edge is classified
        there: total internal reflection switching at the surface it leaves, else, where
        both chains reach the bounce (``chained``), another surface (a visibility edge), else
        a shadow edge for each light (``shadows``, bool per light) and the checker lines."""
        out = []
        pairs_tir, pairs = pairs & tir, pairs & ~tir & chained
        for kind, where in ((CHAIN_TIR, pairs_tir), (CHAIN_VISIBILITY, pairs & shape_differs)):
            where = np.flatnonzero(where)
            out.append((where, np.full(len(where), kind), np.zeros(len(where), int),
                        np.full(len(where), depth)))
        on = pairs & ~shape_differs
        return out + cls._entries(on, shadows, on & (lines > 0), CHAIN_SHADOW, CHAIN_CHECKER,
                                  depth)

    def moving_edges(self, kind, light, L, R):
        """Where the edge between the samples of the pairs (L, R) (flat positions, see
        :func:`flat`) of ``kind`` (and ``light``: a shadow's) moves, the camera still: a
        visibility edge where either sample sees a moving shape, a checker line on one, a
        shadow edge whose surface, light or blocker moves, and every edge seen along the
        specular chain (not told apart: kept). Elsewhere g reads nothing a key moves: the
        term is zero, and its pair is not formed (a fit of one object's pose, the camera
        still: the checker lines of a floor that does not move, four fifths of the pairs
        of benchmarks/edges_bench.py's scene, cost nothing)."""
        moves = (kind >= CHAIN_VISIBILITY) | self.moves(at(self.shape, L)) \
            | self.moves(at(self.shape, R))
        shadow = np.flatnonzero(kind == SHADOW)
        if len(shadow):
            moves[shadow] |= self.light_moves[light[shadow]]
            for blocker in self.blockers(self.occluder, self.stopper, light[shadow], L[shadow],
                                         R[shadow]):
                moves[shadow] |= self.moves(blocker[:, 0])
        return moves

    def moves(self, shape):
        """Whether the shapes ``shape`` (registry ids, numpy; NO_HIT: none) move."""
        return np.take(self.shape_moves, shape, mode="clip")  # (NO_HIT: the last entry)

    def kept(self, kind):
        """Where a pair of ``kind`` (int8 array; -1: none, or left out) is formed."""
        if self.formed[1:].all():
            return kind >= 0
        keep = np.zeros(kind.shape, bool)
        for formed in np.flatnonzero(self.formed[1:]):
            keep |= kind == formed
        return keep
