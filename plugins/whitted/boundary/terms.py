"""The terms (the package docstring, "Pairs"): for each block of pairs, g evaluated at the
pairs' samples, at two points either side of the crossing along the axis and at two across
it, each set as one stack of rays (:meth:`Terms.g_at`; the helpers of stacked arrays), the
crossing and its rate, the edge's normal (:meth:`Terms.slope_across`), the jump f_L - f_R
(:meth:`Terms.jump`), the zero-valued surrogate with the term's derivative
(:meth:`Terms.surrogates`), the pixels it is shared by (:meth:`Terms.spread`,
:func:`spread_adjoint`), and the derivative in reverse (:meth:`Terms.backward`) and forward
mode (:meth:`Terms.forward`), pairs in chunks. Which g a kind of edge has: its own module
(:meth:`Terms.crossing` picks it at the first hit, ``chain.py``'s along the chain)."""

from typing import NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..hits import MESH, SMOOTH, SPHERE
from .lattice import (CHAIN_SHADOW, CHAIN_VISIBILITY, CHECKER, DEFAULT, NO_HIT, POINTS, SHADOW,
                      VISIBILITY, _host, across_crease, at, flat, picked, shadow_key)

PAIRS_PER_CHUNK = 1 << 16
LIMIT = 0.02  # lattice units: how close to a crossing its one-sided colors are traced
# ... of a visibility edge of the surface seen: closer, where the rays either side are
# checked to see L's and R's surfaces. A sphere's color changes like the square root of the
# distance to its rim: at LIMIT, f_L - f_R was off by about sqrt(LIMIT / k) of its rim's
# change over a pixel (a radius's weighted sums at k = 8: 1.55 % -> 0.50 %). At least
# FILM_ULPS of the film position's float32 resolution (k W 2^-24 lattice units).
RIM_LIMIT, FILM_ULPS = 2e-4, 4
# the crossing's refinement: g at two points either side of it, this share of its distance
# to the nearer sample away, at least REFINE_MIN lattice units (float32's g resolves it)
REFINE, REFINE_MIN = 0.25, 0.005
# How far past L's and R's values of g those beside the crossing may lie, as a share of
# their difference, for a pair that they do not bracket (a tolerance for a g nearly linear
# and for float rounding; a fold lies far outside: seed 5's g 36.9 against 2.4 and -3.3)
MONOTONE_SLACK = 0.05
# the pairs whose traced sides are checked against L's and R's keys (Terms.jump), and the
# bisections that find where the renderer's rays switch where they do not match
KEYED, SWITCH_STEPS = (SHADOW, CHAIN_VISIBILITY, CHAIN_SHADOW), 10
# The rays one round of those bisections traces at most: a round takes as many steps as
# fit (2^steps - 1 midpoints a pair) in one trace. A trace costs about 0.8 ms of Python and
# launches and 0.33 us a ray (benchmarks/edges_bench.py's cost scene, 256 x 192): this many
# rays cost about as much as the trace itself (its 27 pairs: 10 traces -> 2, 8.5 -> 2.9 ms)
SWITCH_RAYS = 1 << 11


def _groups(kind, light, depth):
    """((kind, light, depth), indices) for each combination the pairs hold (numpy each), in
    the combinations' order, each one's indices increasing. (One integer code a pair, in
    mixed radix: sorted as the triples are, and a 1-D sort, not np.unique's of rows.)"""
    columns = [np.asarray(v).astype(np.int64).ravel() for v in (kind, light, depth)]
    if not len(columns[0]):
        return []
    code = np.zeros(len(columns[0]), np.int64)
    for column in columns:
        low = column.min()
        code = code * (column.max() - low + 1) + (column - low)
    _, inverse, counts = np.unique(code, return_inverse=True, return_counts=True)
    members = np.split(np.argsort(inverse.ravel(), kind="stable"), np.cumsum(counts)[:-1])
    return [(tuple(int(column[where[0]]) for column in columns), where) for where in members]


def spread_adjoint(grad_in, pixel, fraction):
    """Each term's weight: the image's adjoint ``grad_in`` (numpy (H W, 3)) at the pixels
    it goes to (``pixel``, (n, 3)), by its fraction in each (``fraction``, (n, 3); see
    :meth:`Boundary.spread`): float32 (n, 3). (By np.take and a sum written out: numpy's
    indexing of an array of vectors by an index array, and einsum, are each about three
    times slower.)"""
    adjoint = np.take(grad_in, pixel, axis=0)
    return (fraction[:, 0:1] * adjoint[:, 0] + fraction[:, 1:2] * adjoint[:, 1]
            + fraction[:, 2:3] * adjoint[:, 2]).astype(np.float32)


def one_or_both(below, above):
    """The mean of two one-sided differences (numpy, per pair); where one is not finite (a
    ray that sees nothing there, so g is undefined) the other; where neither is, 0."""
    ok_b, ok_a = np.isfinite(below), np.isfinite(above)
    below, above = np.where(ok_b, below, 0.0), np.where(ok_a, above, 0.0)
    return np.where(ok_b & ok_a, 0.5 * (below + above), np.where(ok_b, below, above))


def within(gl, gr, *values, slack=MONOTONE_SLACK):
    """Where ``values`` (numpy, per pair) all lie within the range of g's values ``gl`` and
    ``gr`` at a pair's samples, widened by ``slack`` times its width either side."""
    low, high = np.minimum(gl, gr), np.maximum(gl, gr)
    margin = slack * (high - low)
    inside = np.ones(np.shape(gl), bool)
    for value in values:
        inside &= (value >= low - margin) & (value <= high + margin)
    return inside


def _evaluated(si):
    """``si`` with the fields read here evaluated once (each ``.numpy()`` or later kernel
    would otherwise trace the rays again)."""
    dr.eval(si.t, si.p, si.n, si.sh_frame.n, si.uv, si.shape, si.prim_index)
    return si


def stacked(values, lanes):
    """A per-pair numpy array (P pairs) repeated for each point set of stacked rays of
    ``lanes`` lanes (point set i at lanes i P .. (i + 1) P - 1)."""
    return np.tile(values, (lanes // len(values),) + (1,) * (values.ndim - 1))


def at_l_and_r(value, count):
    """The values of a stacked array at L and at R (point sets 0 and 1, ``count`` pairs): two
    arrays of ``count`` lanes, on the device."""
    lane = dr.arange(mi.UInt32, count)
    return (dr.gather(type(value), value, lane),
            dr.gather(type(value), value, lane + dr.opaque(mi.UInt32, count)))


def on_lanes(value, lanes):
    """A per-pair Dr.Jit array (P lanes) repeated for each point set of stacked rays of
    ``lanes`` lanes (the device's :func:`stacked`)."""
    count = dr.width(value)
    return dr.gather(type(value), value, dr.arange(mi.UInt32, lanes) % dr.opaque(mi.UInt32, count))


def signs_differ(a, b):
    """Whether the signs of ``a`` and ``b`` (Floats) differ, as numpy's ``np.sign(a) !=
    np.sign(b)`` decides it (zero has its own sign; a NaN differs from everything)."""
    def sign(x):
        return dr.select(x > 0, 1, dr.select(x < 0, -1, 0))

    return (sign(a) != sign(b)) | dr.isnan(a) | dr.isnan(b)


def lanes_of(stack, i, count):
    """Point set i of a stacked Float (``count`` pairs): its lanes i P .. (i + 1) P - 1. (Its
    adjoint scatters directly: by default the LLVM backend would expand the stack per thread
    with its size a constant of the kernel, compiled anew for each count of pairs.)"""
    lane = dr.arange(mi.UInt32, count) + dr.opaque(mi.UInt32, i * count)
    return dr.gather(mi.Float, stack, lane, mode=dr.ReduceMode.Direct)


class Ends:
    """The two samples of each pair of a block, L and R: their lattice points (``L``, ``R``:
    (y, x), numpy), flat positions (``l``, ``r``: see :func:`flat`) and what their first
    hits are (``shape``, ``prim``, ``t``: (at L, at R) each), read once for the block: g's
    evaluations, the one-sided colors and the rim correction all read them."""

    def __init__(self, boundary, L, R):
        self.L, self.R = L, R
        self.l, self.r = flat(L, boundary.cols), flat(R, boundary.cols)
        self.shape, self.prim, self.t = (
            (at(plane, self.l), at(plane, self.r))
            for plane in (boundary.shape, boundary.prim, boundary.t))


class Traced(NamedTuple):
    """Rays traced at s sets of n lattice points (:meth:`Terms.traced`)."""

    colors: np.ndarray  # (s, n, 3)
    shapes: np.ndarray  # (s, n): the first hit's shape id (NO_HIT: none)
    normals: np.ndarray  # (s, n, 3): its face's normal (si.n)
    keys: object  # (s, len(keyed)) int64: the edge's keys at the keyed points, or None
    paths: object = None  # per set, the Path of its points ``paths[set]``, or None


class Path(NamedTuple):
    """What the specular chains of n samples meet past their first hit (numpy): per bounce,
    the shape met (``shapes``, (n, bounces)) and per light whether it lights it
    (``chain_lit``, (n, bounces, lights)). Bounces past those held: the chain's keys past its
    end (lattice.DEFAULT: STOP, unlit). Not the lights of the first hit itself: a shadow
    edge or terminator on the surface is no squeezed edge (:meth:`Terms.jump`)."""

    shapes: np.ndarray
    chain_lit: np.ndarray

    @classmethod
    def of(cls, shapes, chain_lit, n, lights):
        """A Path from per-bounce and per-(bounce, light) lists of n entries (a bounce's
        ``lights`` in a row, as the lattice's ``chain_lit`` holds them)."""
        bounces = len(shapes)
        return cls(np.stack(shapes, -1) if bounces else np.zeros((n, 0), np.uint32),
                   np.stack(chain_lit, -1).reshape(n, bounces, lights) if bounces and lights
                   else np.zeros((n, bounces, lights), bool))

    def differs(self, other, past=None, lights_past=None):
        """Per sample, whether two Paths of the same samples' count differ: at every bounce,
        or (``past``, per sample) at the bounces past bounce ``past`` only (-1: every one);
        the lights at the bounces past ``lights_past`` (per sample; default ``past``)."""
        out = np.zeros(len(self.shapes), bool)
        bounces = max(self.shapes.shape[1], other.shapes.shape[1])
        lights_past = past if lights_past is None else lights_past
        for mine, theirs, fill, after in (
                (self.shapes, other.shapes, DEFAULT["chain_shape"], past),
                (self.chain_lit, other.chain_lit, DEFAULT["chain_lit"], lights_past)):
            mine, theirs = (np.concatenate([a, np.full((len(a), bounces - a.shape[1])
                                                       + a.shape[2:], fill, a.dtype)], 1)
                            for a in (mine, theirs))
            unequal = mine != theirs
            if after is not None:
                unequal &= (np.arange(bounces) > after[:, None]).reshape(
                    (len(after), bounces) + (1,) * (mine.ndim - 2))
            out |= np.any(unequal, axis=tuple(range(1, mine.ndim)))
        return out


def bisect_rounds(count, steps, rays):
    """The steps of each round of ``count`` bisections of ``steps`` steps (a list, summing
    to ``steps``): as many as keep a round's 2^bits - 1 midpoints a bisection within
    ``rays`` rays (at least one step a round)."""
    bits = max(1, min(steps, int(np.log2(rays // max(count, 1) + 1))))
    return [bits] * (steps // bits) + ([steps % bits] if steps % bits else [])


class Terms:
    """The terms of :class:`Boundary`'s pairs, their surrogates and the derivative (a mixin of
    Boundary: the lattice's keys and colors are its attributes)."""

    def surrogates(self, pairs, lo, hi):
        """(Color3f surrogate per pair lo .. hi - 1, zero-valued, with the derivative of the
        pair's term; the pixel each term goes to, numpy)."""
        terms = self.tracer.scene_terms(self.scene)  # attached: the keys' derivatives
        sl = slice(lo, hi)
        count = hi - lo
        points = {name: tuple(a[sl] for a in pairs[name]) for name in POINTS}
        L, ends = points["L"], Ends(self, points["L"], points["R"])
        kind, light, axis = pairs["kind"][sl], pairs["light"][sl], pairs["axis"][sl]
        # what picks g (see g_at); its choices made from L's and R's values, kept for the
        # second pass
        choices = {}
        crossing = (ends, kind, light, pairs["depth"][sl],
                    (pairs["coord"][sl], pairs["line"][sl]), choices)
        # g at the samples (detached): the crossing where it changes sign, linear between L
        # and R
        with dr.suspend_grad():
            _, (gl, gr) = self.g_at(terms, [points["L"], points["R"]], *crossing)
        valid = (np.sign(gl) != np.sign(gr)) & (gl != gr) & np.isfinite(gr - gl)
        w = np.clip(np.where(valid, gl / np.where(valid, gl - gr, 1.0), 0.5), 0.0, 1.0)
        # refined where g curves between L and R (a checker seen through a glass ball's
        # rim: its lines compressed, u far from linear): g at two points either side of the
        # crossing, REFINE of its distance to the nearer sample (at least REFINE_MIN):
        # their values bracket the crossing again, their difference is g's slope across
        # it (otherwise L's and R's secant). Their mean's derivative is g's at the crossing
        # (at its linear estimate where they do not bracket it): the one pass with
        # derivatives, two rays a pair.
        eps = np.clip(REFINE * np.minimum(w, 1.0 - w), REFINE_MIN, REFINE)
        beside = [self.along_axis(L, axis, w + side * eps) for side in (-1.0, 1.0)]
        g, (gm, gp) = self.g_at(terms, beside, *crossing)
        g_star = 0.5 * (lanes_of(g, 0, count) + lanes_of(g, 1, count))
        bracket = valid & (np.sign(gm) != np.sign(gp)) & np.isfinite(gp - gm)
        along = np.where(bracket, (gp - gm) / (2.0 * eps), gr - gl)  # dg per lattice unit
        w = np.where(bracket, np.clip(w - eps + 2.0 * eps * gm / np.where(bracket, gm - gp, 1.0),
                                      0.0, 1.0), w)
        # (g at the crossing: 0 where gm and gp bracket it, which placed it there; else their
        # mean, at the crossing's linear estimate, which stays)
        across = self.slope_across(terms, L, axis, w, eps,
                                   np.where(bracket, 0.0, 0.5 * (gm + gp)), crossing)
        normal2 = along ** 2 / np.maximum(along ** 2 + across ** 2, 1e-30)
        df = self.jump(ends, axis, w, kind, light, pairs["depth"][sl],
                       self.followed(ends, kind, choices), pairs["shared"][sl])
        # (a pair whose g beside the crossing is undefined, a ray there seeing nothing its
        # function reads, adds no term: selected out, as a product with 0 would carry NaN in
        # forward mode)
        valid &= np.isfinite(gm) & np.isfinite(gp)
        # (nor does one whose g beside the crossing neither brackets it nor lies within L's
        # and R's values: g is not monotone between the samples -- another face's function
        # past a fold, a mesh's outline seen in a mirror ball near its rim -- and neither
        # the crossing nor its rate is known at the lattice's resolution: the derivative of
        # g far from its zero is no rate of the edge, and made terms of 30 times a pair's
        # size)
        valid &= bracket | within(gl, gr, gm, gp)
        scale = np.where(valid, normal2 / (self.k ** 2 * np.where(valid, along, 1.0)), 0.0)
        rate = -(g_star - dr.detach(g_star)) * jit_array(mi.Float, scale.astype(np.float32))
        rate = dr.select(jit_array(mi.Bool, valid), rate, 0.0)
        surrogate = mi.Color3f(*(jit_array(mi.Float, df[:, c]) for c in range(3))) * rate
        rim = self.rim_correction(terms, terms.geometry, kind, axis, ends, w,
                                  np.where(valid, normal2, 0.0))
        if rim is not None:
            surrogate += rim
        return surrogate, self.spread(L, axis, w, np.abs(across) / np.maximum(np.abs(along), 1e-30))

    def g_at(self, terms, sets, ends, kind, light, depth, line, choices):
        """g at the point sets ``sets`` (a list of (y, x) lattice coordinates, numpy, one
        point per pair; ``ends``: the pairs' :class:`Ends`) traced as one stack of rays: (a
        Float of len(sets) P lanes, point set i at lanes i P .. (i + 1) P - 1, attached as
        ``terms`` and the camera's keys are; its values as numpy (len(sets), P)).
        ``choices`` (a dict): the picks made from L's and R's values (which function, which
        edge of a face) by an earlier call with the same pairs, or empty: made here, from
        the first two sets (then L and R), and kept in it."""
        table = terms.geometry
        ray = self.film_rays(*(np.concatenate([point[i] for point in sets]) for i in range(2)))
        dr.eval(ray)
        si = _evaluated(self.hits_at(table, ray, ends, kind))
        g = self.crossing(table, terms, ray, si, ends, kind, light, line, choices)
        if (depth >= 0).any():
            g = self.chain_crossing(table, terms, ray, si, ends, kind, depth, g, light, line,
                                    choices)
        # (the choices made here evaluated with g: a later call reads them, not their graph)
        dr.eval(g, [v for made in choices.values() for v in made if isinstance(v, dr.ArrayBase)])
        return g, dr.detach(g).numpy().astype(np.float64).reshape(len(sets), len(kind))

    def hits_at(self, table, ray, ends, kind):
        """The surface interactions of g_at's stacked rays ``ray``, a point set after another,
        for the pairs (L, R) of ``kind`` (their :class:`Ends`). Where L and R see one face
        of one shape (every kind but a visibility edge of the first hit, mostly), each ray's
        hit on that face, solved from the table (``HitTable.known_hits``: no ray tracing; g
        then is the function of that surface's, smooth where another hides it or where the
        face ends); elsewhere, and where the ray does not meet that face's plane or sphere,
        by the ray tracer. A visibility edge's rays have none (its g reads the rays only)."""
        if not table.supported:  # (coherent: the stack's rays in the lattice's order)
            return self.tracer.intersect(self.scene, table, ray, coherent=True)
        lanes = dr.width(ray.d)
        shape, prim = ends.shape[0], ends.prim[0]
        needed = kind != VISIBILITY
        known = needed & (shape == ends.shape[1]) & (prim == ends.prim[1]) & (shape != NO_HIT)
        pi = table.known_hits(ray, jit_array(mi.UInt32, stacked(np.where(known, shape, NO_HIT),
                                                                lanes)),
                              jit_array(mi.UInt32, stacked(prim, lanes)),
                              jit_array(mi.Float, stacked(ends.t[0], lanes)))
        traced = jit_array(mi.Bool, stacked(needed, lanes)) & ~pi.is_valid()
        found = self.scene.ray_intersect_preliminary(ray, coherent=True, active=traced)
        return table.intersect(self.scene, ray, True, dr.select(traced, found, pi))

    @staticmethod
    def along_axis(L, axis, offset):
        """The lattice points (y, x) ``offset`` lattice units from L along each pair's axis."""
        return (np.where(axis == 1, L[0], L[0] + offset), np.where(axis == 1, L[1] + offset, L[1]))

    def slope_across(self, terms, L, axis, w, eps, g_star, crossing):
        """g's slope across each pair's axis at its crossing (a fraction ``w`` of the way from
        L along ``axis``; ``g_star``, numpy, g there): g at the two points ``eps`` lattice
        units either side of the crossing across the axis, detached -- where g's points
        along the axis bracket the crossing, its slope along the axis is measured there too,
        at the same scale, so the edge's normal is g's gradient at one point (elsewhere that
        slope is L's and R's secant). (It was the centred differences at L and R, two
        lattice units wide, interpolated: where edges crowd, a shadow seen in a mirror ball
        near its rim, g's gradient changes within a lattice unit, and those normals weighed
        the rows' and the columns' terms wrongly; seed 5's fov, random_edges.py, k = 16: a
        change of fov moves each point of the image at a velocity known in closed form, and
        that shadow's pairs' rates along their axes came out 0.09 times what it gives along
        the normals their slopes made, at the median; 0.99 now.) A side whose ray sees
        nothing g reads, where it is undefined, is left out (one-sided); both: 0, the edge
        taken across the axis (``test_a_neighbour_that_sees_nothing_leaves_the_
        derivative_finite``)."""
        y, x = self.along_axis(L, axis, w)
        shifts = [(np.where(axis == 1, y + side * eps, y), np.where(axis == 1, x, x + side * eps))
                  for side in (-1.0, 1.0)]
        with dr.suspend_grad():
            _, (below, above) = self.g_at(terms, shifts, *crossing)
        return one_or_both((g_star - below) / eps, (above - g_star) / eps)

    def crossing(self, table, terms, ray, si, ends, kind, light, line, choices):
        """g at the stacked rays ``ray`` (see g_at), hitting ``si`` (a Float, attached)."""
        left, right = ((ends.shape[i], ends.prim[i], ends.t[i]) for i in (0, 1))
        # (the visibility edges' g; none among the pairs, as where only a light moves: zero,
        # which the other kinds' replace)
        choice = self.visibility(table, ray, left, right, choices, "first") \
            if (kind == VISIBILITY).any() else dr.zeros(mi.Float, dr.width(ray.d))
        if (kind == SHADOW).any():
            blockers = self.blockers(self.occluder, self.stopper, light, ends.l, ends.r)
            choice = self.shadow_crossing(table, ray, si, light, blockers, kind == SHADOW, choice,
                                          choices, "first")
        # checker lines
        if (kind == CHECKER).any():
            choice = self.checker_crossing(terms, si, *line, kind == CHECKER, choice,
                                           choices, "first")
        return choice

    def jump(self, ends, axis, w, kind, light, depth, followed, shared=None):
        """f_L - f_R across each pair's crossing: the colors of two rays traced just either
        side of it (LIMIT lattice units, RIM_LIMIT for a visibility edge of the surface seen;
        within the pair; both sides stacked, one trace), where they see what L and R see
        (else the colors of L and R themselves; ``shared``, per pair: one entry of several
        across the same samples, ``Pairs.classify``, whose f_L - f_R is no one edge's: 0).

        A shadow pair, or an edge seen along the chain, whose two sides' keys for that edge
        (:meth:`edge_key`) are not L's and R's -- g's crossing is not where the renderer's
        rays switch -- has its jump traced where they do, found by bisection between L and
        R (:meth:`switch`). So at a tessellated (smooth) mesh's silhouette casting a shadow:
        g is the inside function of the face that blocks the light, and where several of
        the mesh's thin faces lie between L's and R's shadow rays, the edge of that face
        that flips is an inner one, not the silhouette; both sides were traced in the
        shadow, and the term was lost (a cone's shadow, k = 16: 3.9 % of the sum of sizes
        off, per-pixel 48 %; then 0.4 % and 9 %, the crossing's place and rate that inner
        edge's; with the segment followed to the silhouette, Visibility.outline, 0.3 % and
        3.1 %). So too an edge seen in a mirror ball near
        its rim, where g along the chain is far from linear (a ball's radius, k = 8: 19 %
        -> 8.3 %).

        A visibility pair's near side (the surface whose outline the edge is) whose traced
        ray's path past the surface (:class:`Path`: the specular chain's shapes and the
        lights that reach each of its bounces) is not its sample's takes the sample's color:
        an edge squeezed between the outline and the sample (a mirror ball's rim holds what
        lies just outside it, unfolded, in a band thinner than the lattice at any k) moves
        with the outline (docs/gradients.md, 'Edges on random scenes': seed 17's ball radius
        at 128 x 96, k = 8, 40.5 % -> 5.7 % of the weighted sum). So too where the pair's
        segment was followed past the sample's face to the mesh's outline (``followed``,
        per pair: :meth:`Visibility.outline`): the faces between them, foreshortened near a
        smooth mesh's silhouette, squeeze its shading into a band that moves with the
        outline (a tessellated cone seen by a moving camera's fov, k = 16: the weighted
        sum 7.7 % of the sum of sizes off with the color at the outline, 0.5 % with the
        sample's). Not where only the lights
        of the surface itself differ: a shadow edge or the terminator on it is foreshortened
        near the outline, not squeezed into it, and is resolved as k grows (taking the
        sample's color there cost the random scenes' diffuse balls, seeds 11 and 25,
        their radius at every k).

        The same of a visibility edge seen along the chain at bounce d (an outline seen in a
        mirror): its near side is the surface nearer along the chain there, and its path is
        compared past bounce d (the bounces after it), and in the lights at bounce d too where
        the ray met a curved surface before d (:meth:`curved_before`): seen in a mirror ball
        near its rim, the outlined surface's terminator is squeezed into the band with the
        rest (random scene 30's translate, a cone's outline seen in a mirror ball, against
        benchmarks/random_edges.py's reference: 0.5 / 2.0 / 3.7 % of Sum |w FD| at k = 8 / 16 /
        32, growing with k, now 2.3 / 1.2 / 0.19 %, worse at k = 8 where a lattice unit holds
        the band); in a flat mirror it is only foreshortened, as on the surface seen (seed
        28's look-at, a mirror floor: 2.6 % at k = 8 either way, 5.5 % with the lights counted
        there too). Where its sides were traced again at the switch, their paths there are
        compared (a glass ball seen in a mirror floor, seed 4's look-at: the switch's side on
        the ball's rim sees what the rim refracts, squeezed; k = 4 / 8, 2.4 / 2.1 % of the sum
        of sizes off, 0.9 / 0.2 % with the rule)."""
        count = len(kind)
        rim = max(RIM_LIMIT, FILM_ULPS * self.k * max(self.width, self.height) * 2.0 ** -24)
        limit = np.where(kind == VISIBILITY, rim, LIMIT)
        step = np.minimum(limit, 0.5 * np.minimum(w, 1.0 - w))
        points = [self.along_axis(ends.L, axis, w + offset) for offset in (-step, step)]
        keyed = np.flatnonzero(np.isin(kind, KEYED))
        edge = (kind[keyed], light[keyed], depth[keyed])
        # (visibility edges: of the surface seen, and seen along the chain at bounce
        # ``past``; their near sides, the surface whose outline the edge is)
        visible = np.flatnonzero((kind == VISIBILITY) | (kind == CHAIN_VISIBILITY))
        past = np.where(kind[visible] == VISIBILITY, -1, depth[visible])
        t_l, t_r = ends.t[0][visible], ends.t[1][visible]
        seen_along = past >= 0
        if seen_along.any():
            bounce = past[seen_along]
            t_l[seen_along] = picked(self.chain_t, bounce, ends.l[visible[seen_along]])
            t_r[seen_along] = picked(self.chain_t, bounce, ends.r[visible[seen_along]])
        nearer = t_l <= t_r  # (L's side, else R's)
        near = [visible[nearer], visible[~nearer]]
        near_past = [past[nearer], past[~nearer]]
        sides = self.traced(points, keyed, *edge, paths=near if len(visible) else None)
        colors, keys = sides.colors, sides.keys
        same = self.same_surfaces(sides, ends)
        # a visibility pair's near side (the surface whose outline it is) whose path past the
        # surface differs from its sample's: the sample's color. Near a curved outline the
        # surface's own look is squeezed into a band by it (foreshortening; a mirror ball's
        # rim holds what lies behind it, unfolded): an edge in that band, between the
        # crossing and the sample, is no pair's, and moves with the outline. (Where the
        # sides were traced again at the switch, below, their paths there.)
        def squeezed(paths, s, which):
            """Whether the near sides ``near[s][which]`` traced with ``paths`` differ from
            their samples past their bounce (and in the lights at it, seen past a curved
            surface), or were followed to a mesh's outline."""
            entries, bounce = near[s][which], near_past[s][which]
            held = self.path_at((ends.l, ends.r)[s][entries])
            lights_past = np.where(self.curved_before(ends.shape[s][entries], held, bounce),
                                   bounce - 1, bounce)
            return paths.differs(held, bounce, lights_past) | followed[entries]

        off = [np.zeros(0, bool)] * 2
        if len(visible):
            off = [squeezed(sides.paths[s], s, slice(None)) for s in (0, 1)]
        if len(keyed):
            key_l, key_r = (self.edge_key(end[keyed], *edge) for end in (ends.l, ends.r))
            lost = np.flatnonzero((keys[0] != key_l) | (keys[1] != key_r))
            if len(lost):
                pairs = keyed[lost]
                L = tuple(p[pairs] for p in ends.L)
                lo, hi = self.switch(L, axis[pairs], key_l[lost],
                                     *(e[lost] for e in edge))
                # (the lost pairs' near sides: their entries in near, and in pairs)
                again = [np.flatnonzero(np.isin(near[s], pairs)) for s in (0, 1)]
                switched = self.traced(
                    [self.along_axis(L, axis[pairs], at) for at in (lo, hi)],
                    paths=[np.searchsorted(pairs, near[s][again[s]]) for s in (0, 1)]
                    if len(visible) else None)
                colors[:, pairs] = switched.colors
                for s in (0, 1):
                    if len(again[s]):
                        off[s][again[s]] = squeezed(switched.paths[s], s, again[s])
        if shared is not None and len(visible):
            # (not an entry of a pair across several edges: the sample's color would carry
            # the others' jumps, which their own entries count)
            off = [off[s] & ~shared[near[s]] for s in (0, 1)]
        for s, point in enumerate((ends.L, ends.R)):
            if len(visible) and off[s].any():
                sides_off = near[s][off[s]]
                colors[s, sides_off] = self.colors_at(tuple(p[sides_off] for p in point))
        jump = colors[0] - colors[1]
        if not same.all():
            other = ~same
            jump[other] = self.colors_at(tuple(p[other] for p in ends.L)) \
                - self.colors_at(tuple(p[other] for p in ends.R))
            if shared is not None:  # (f_L - f_R of a pair across several edges is no
                jump[other & shared] = 0.0  # one edge's: that entry adds no term)
        return jump

    def same_surfaces(self, sides, ends):
        """Per pair: whether the rays traced either side of its crossing (``sides``, a
        :class:`Traced` of the two) see what its samples L and R (``ends``) see: the same
        shape, and on a mesh a face no crease away from the sample's (a closed mesh's faces,
        grown against cracks, stand a sliver past one another at its outline: a ray there
        meets the far side's face)."""
        same = (sides.shapes[0] == ends.shape[0]) & (sides.shapes[1] == ends.shape[1])
        for side, (shape, end) in enumerate(zip(ends.shape, (ends.l, ends.r))):
            mesh = np.flatnonzero(same & (shape != NO_HIT))
            mesh = mesh[self.kinds(shape[mesh]) & MESH != 0]
            n = np.stack([at(c, end[mesh]) for c in self.normal], -1)
            same[mesh[across_crease(n, sides.normals[side, mesh])]] = False
        return same

    def edge_key(self, flat_points, kind, light, depth):
        """The key that tells the sides of a pair's edge apart (numpy, per pair) at lattice
        samples (flat positions): for a shadow edge, whether its light lights the sample and
        else what blocks it (``shadows.shadow_key``); for an edge seen along the chain, the
        shape its bounce ``depth`` meets (a chain's shadow edge: the shadow key at that
        bounce)."""
        out = np.zeros(len(kind), np.int64)
        for (k, j, d), where in _groups(kind, light, depth):
            points = flat_points[where]
            if k == CHAIN_VISIBILITY:
                out[where] = at(self.chain_shape[d], points)
                continue
            index = j if k == SHADOW else d * len(self.lights) + j
            arrays = (self.lit, self.occluder, self.stopper) if k == SHADOW else \
                (self.chain_lit, self.chain_occluder, self.chain_stopper)
            out[where] = shadow_key(*(at(a[index], points) for a in arrays))
        return out

    def traced(self, points, keyed=None, kind=None, light=None, depth=None, paths=None):
        """The rays of the lattice points ``points`` (s sets of n (y, x)), traced: a
        :class:`Traced` of their colors, first hits' shapes and face normals, at the
        points ``keyed`` (indices into a set) of pairs of ``kind`` (``light``, ``depth``) the
        edge's keys ((s, len(keyed)), as :meth:`edge_key` reads them from the lattice, the
        samples' rule; None if none), and at each set's points ``paths[set]`` (indices
        into the set) their :class:`Path` (a list, one a set; None if none: only those
        points' chains are followed past the first hit, with the keyed chain edges')."""
        count, sets = len(points[0][0]), len(points)
        seen, keys = [], []  # (from the trace's own hits)
        follow = paths is not None and sum(len(p) for p in paths) > 0
        wanted = keyed is not None and len(keyed) > 0

        def first_hit(si, ray, hit, shadows):
            seen.append(dr.select(hit, dr.reinterpret_array(mi.UInt32, si.shape), NO_HIT))
            seen.append(si.n)
            if wanted or follow:
                keys.append(self.hit_keys(si, ray, hit, shadows))

        with dr.suspend_grad():
            ray = self.film_rays(*(np.concatenate([side[i] for side in points])
                                   for i in range(2)))
            color = self.tracer.trace(self.scene, ray, self.terms, first_hit=first_hit).color
            # (the first hit's lights: read for the keyed shadow edges only; a Path is the
            # chain's)
            dr.eval(color, seen, [keys[0][name] for name in ("lit", "occluder", "stopper")]
                    if wanted else [])
            colors = _host(color).reshape(sets, count, 3)
            shapes = seen[0].numpy().reshape(sets, count)
            normals = _host(seen[1]).reshape(sets, count, 3)
            if not (wanted or follow):
                return Traced(colors, shapes, normals, None)
            first = keys[0]
            along = np.isin(kind, (CHAIN_VISIBILITY, CHAIN_SHADOW)) if wanted else None
            chain = None
            if follow or along.any():
                # (the chains of the points whose keys are read: the paths' and the keyed
                # edges' along the chain)
                needed = np.zeros(sets * count, bool)
                for i in range(sets):
                    if follow:
                        needed[paths[i] + i * count] = True
                    if wanted:
                        needed[keyed[along] + i * count] = True
                chain = self.chain_keys(first["next"], first["go"] & jit_array(mi.Bool, needed),
                                        first["tir"], normals=False)
        found = None
        if follow:
            found = []
            for i, points_i in enumerate(paths):
                lanes = points_i + i * count
                found.append(Path.of([v[lanes] for v in chain["chain_shape"]],
                                     [v[lanes] for v in chain["chain_lit"]], len(lanes),
                                     len(self.lights)))
        if not wanted:
            return Traced(colors, shapes, normals, None, found)
        lanes = np.concatenate([keyed + i * count for i in range(sets)])  # (of every set)
        kind2, light2, depth2 = (np.tile(v, sets) for v in (kind, light, depth))
        out = np.zeros(len(lanes), np.int64)
        for (k, j, d), where in _groups(kind2, light2, depth2):
            if k == SHADOW:
                occluder = _host(first["occluder"][j])[lanes[where]]
                stopper = _host(first["stopper"][j])[lanes[where]] if first["stopper"] \
                    else occluder  # (no glass: the first blocker stops the light)
                out[where] = shadow_key(first["lit"][j].numpy()[lanes[where]], occluder,
                                        stopper)
            elif k == CHAIN_VISIBILITY:
                shape = chain["chain_shape"]
                out[where] = shape[d][lanes[where]] if d < len(shape) else \
                    DEFAULT["chain_shape"]
            else:
                lit, flat_j = chain["chain_lit"], d * len(self.lights) + j
                stoppers = chain["chain_stopper"] or chain["chain_occluder"]  # (as above)
                out[where] = shadow_key(*(keys[flat_j][lanes[where]] for keys in
                                          (lit, chain["chain_occluder"], stoppers))) \
                    if flat_j < len(lit) else shadow_key(False, np.full(2, NO_HIT),
                                                         np.full(2, NO_HIT))  # (past the end)
        return Traced(colors, shapes, normals, out.reshape(sets, len(keyed)), found)

    def curved_before(self, first, paths, past):
        """Per sample (the shapes of its first hit ``first`` and its :class:`Path` ``paths``),
        whether its ray met a curved surface (an analytic sphere or ellipsoid, or a smooth
        mesh: HitTable's SPHERE, SMOOTH) as its first hit or at a bounce of its chain before
        bounce ``past`` (per sample; -1: none).
        What such a mirror or glass shows near its rim is squeezed into a band there, and
        with an outline seen past it, the look of the outlined surface itself: its
        terminator, a shadow on it (:meth:`Terms.jump`); a flat mirror only reflects them.
        (Decided by shape: a smooth mesh's flat faces, a mirror cylinder's caps, count as
        curved.)"""
        out = np.zeros(len(past), bool)
        chain = np.flatnonzero(past >= 0)  # (only these have a bounce before theirs)
        if len(chain):
            shapes = np.concatenate([first[chain, None], paths.shapes[chain]], 1)
            curved = (self.kinds(shapes) & (SPHERE | SMOOTH)) != 0
            # (column 0 the first hit, column b + 1 the chain's bounce b: those before past)
            before = np.arange(shapes.shape[1]) <= past[chain, None]
            out[chain] = np.any(curved & before, axis=1)
        return out

    def path_at(self, flat_points):
        """The :class:`Path` s of the lattice's samples at ``flat_points``, as it holds them."""
        return Path.of([at(plane, flat_points) for plane in self.chain_shape],
                       [at(plane, flat_points) for plane in self.chain_lit], len(flat_points),
                       len(self.lights))

    def switch(self, L, axis, key_l, kind, light, depth, steps=SWITCH_STEPS):
        """Where along the pairs from L (lattice points, ``axis``) the edge's key (see
        :meth:`edge_key`) stops being L's (``key_l``): (lo, hi) offsets from L, 1 / 2^steps
        lattice units apart, the switch between them: a bisection, whose midpoints are
        traced several steps at a time (:func:`bisect_rounds`)."""
        count = len(axis)
        lo, hi = np.zeros(count), np.ones(count)
        every = np.arange(count)
        for bits in bisect_rounds(count, steps, SWITCH_RAYS):
            # every midpoint the next ``bits`` steps can visit: lo + j (hi - lo) / 2^bits,
            # j = 1 .. 2^bits - 1 (dyadic: the very offsets a step at a time would trace)
            parts = 1 << bits
            width = (hi - lo) / parts
            offsets = [lo + j * width for j in range(1, parts)]
            like_l = self.traced([self.along_axis(L, axis, at) for at in offsets], every, kind,
                                 light, depth).keys == key_l
            low, high = np.zeros(count, np.int64), np.full(count, parts)
            for _ in range(bits):
                mid = (low + high) // 2
                here = like_l[mid - 1, every]
                low, high = np.where(here, mid, low), np.where(here, high, mid)
            lo, hi = lo + low * width, lo + high * width
        return lo, hi

    def spread(self, L, axis, w, slope):
        """Where each pair's term goes: (pixel (n, 3), fraction (n, 3)) numpy. The crossing
        stands for the piece of edge inside its band (the lattice row, or column, of unit
        width), which runs along the axis over ``slope`` lattice units centred on the crossing:
        its term is shared by the pixels that piece lies in, by length (at most three)."""
        k = self.k
        ly, lx = L[0] - 1, L[1] - 1  # (the image's lattice point: the ring's at -1)
        band = np.where(axis == 1, ly, lx) // k  # the pixel row (rows) or column (columns)
        c = np.where(axis == 1, lx, ly) + 0.5 + w  # the crossing along the axis, lattice units
        lo, hi = c - 0.5 * slope, c + 0.5 * slope
        first = np.floor(c / k).astype(np.int64) - 1
        limit = np.where(axis == 1, self.width, self.height)
        pixels, fractions = [], []
        for i in range(3):
            along = first + i
            overlap = np.clip(np.minimum(hi, (along + 1) * k) - np.maximum(lo, along * k), 0, None)
            fraction = np.where(slope > 0, overlap / np.where(slope > 0, slope, 1.0),
                                float(i == 1))
            inside = (along >= 0) & (along < limit)
            fractions.append(np.where(inside, fraction, 0.0))
            along = np.clip(along, 0, limit - 1)
            pixels.append(np.where(axis == 1, band * self.width + along, along * self.width + band))
        return np.stack(pixels, -1), np.stack(fractions, -1)

    def backward(self, grad_in):
        """Propagate the image's adjoint ``grad_in`` (numpy (H W, 3)) through the terms."""
        self.trace_keys()
        pairs = self.pairs()
        total = len(pairs["kind"])
        for lo in range(0, total, PAIRS_PER_CHUNK):
            hi = min(lo + PAIRS_PER_CHUNK, total)
            with dr.resume_grad():
                surrogate, (pixel, fraction) = self.surrogates(pairs, lo, hi)
                weight = spread_adjoint(grad_in, pixel, fraction)
                dr.backward_from(surrogate * mi.Color3f(
                    *(jit_array(mi.Float, weight[:, c]) for c in range(3))),
                    flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)

    def forward(self, grads, last):
        """Add the terms' tangents to ``grads`` (numpy (H W, 3)), the parameters' tangents
        set; ``last``: clear them after."""
        self.trace_keys()
        pairs = self.pairs()
        total = len(pairs["kind"])
        for lo in range(0, max(total, 1), PAIRS_PER_CHUNK):
            hi = min(lo + PAIRS_PER_CHUNK, total)
            if hi <= lo:
                break
            with dr.resume_grad():
                surrogate, (pixel, fraction) = self.surrogates(pairs, lo, hi)
                final = last and hi == total
                dr.forward_to(surrogate, flags=dr.ADFlag.AllowNoGrad | (
                    dr.ADFlag.Default if final else dr.ADFlag.ClearEdges | dr.ADFlag.ClearInterior))
                tangent = _host(dr.grad(surrogate))
            for j in range(3):
                np.add.at(grads, pixel[:, j], tangent * fraction[:, j:j + 1])
