"""Shadow edges of point, spot and directional lights, and the terminator (the package
docstring, "Pairs"): where a light's shadow edge lies between two samples
(:func:`shadow_differs`), what blocks the light at each (:meth:`Shadows.blockers`) and g of
a shadow pair (:meth:`Shadows.shadow_crossing`): the blocker's inside function on the
shadow rays (``visibility.py``'s), or, where the unlit sample has no blocker, N.L (the
terminator: it has no code of its own but this) or a spot's cos a (``spot.py``). The same
functions serve the shadow edges seen along the specular chain (``chain.py``).

A light's keys at a sample (``samples.py``) are whether it lights it, what blocks it first
(the *occluder*) and, in a scene with glass, where the light stops (the *stopper*: the
renderer's shadow ray goes on through glass, kt once per crossing, and stops at an opaque
surface or past max_shadow_crossings crossings; NO_HIT where the light gets through;
without glass the occluder). A shadow edge lies between two samples where the light lights
one only, or where it is blocked at both, gets through glass at one at least, and the
occluders or the stoppers differ: an opaque ball's shadow inside a glass pane's (the glass
nearer the surface: the occluder the same, the stopper not), or a glass ball's shadow
meeting an opaque one's. Its g is the inside function of whichever of the two samples'
occluders and stoppers changes sign between their shadow rays (the one the other sample's
ray misses). Until 2026-12-07 the keys were the lit flag and the occluder, and pairs formed
where the lit flag differs: such edges had no term (a ball above a glass pane, moved: its
derivative was zero, ``tests/plugins/whitted/boundary/test_shadows.py``). What the keys
still do not tell apart has none: a third surface crossed between the occluder and the
stopper (a glass ball's shadow inside another's), and the terminator or a spot's cone inside
a glass blocker's shadow (blocked at one sample, facing away at the other)."""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..lift import lifted_point
from .lattice import NO_HIT, at, picked
from .spot import cone_crossing
from .terms import at_l_and_r, on_lanes, signs_differ, stacked
from .visibility import Faces


def shadow_differs(lit, occluder, stopper, L, R):
    """Whether a shadow edge of a light lies between the samples of the pairs (L, R) (numpy
    flat positions, see :func:`flat`), by that light's lattice arrays ``lit``, ``occluder``
    and ``stopper`` (of the first hit or of a bounce of the chain): lit at one only, or
    blocked at both, its light getting through glass at one at least, with another occluder
    or stopper (the module docstring; where it gets through at neither, both sides are dark
    and the edge has no jump: no pair, which would cost a checker line or an edge along the
    chain between the same samples theirs). Without glass (the stoppers' arrays are the
    occluders', ``Samples.stoppers_of_occluders``) it is where lit differs: the light gets
    through no blocker, and the blockers add no pair."""
    if stopper is occluder:
        return at(lit, L) != at(lit, R)
    by_l, by_r = at(occluder, L)[:, 0], at(occluder, R)[:, 0]
    stop_l, stop_r = at(stopper, L)[:, 0], at(stopper, R)[:, 0]
    through = (by_l != NO_HIT) & (by_r != NO_HIT) & ((stop_l == NO_HIT) | (stop_r == NO_HIT))
    return (at(lit, L) != at(lit, R)) | (through & ((by_l != by_r) | (stop_l != stop_r)))


class Shadows:
    """The shadow edges of :class:`Boundary` (a mixin of Boundary)."""

    @staticmethod
    def blockers(occluder, stopper, index, L, R):
        """What may block light ``index`` (per pair: the index in ``occluder`` and
        ``stopper``, a light's or a light's at a bounce) at the edge between L and R (their
        flat positions, see :func:`flat`): (shape, prim) per pair (numpy; NO_HIT: nothing),
        the occluder at L, at R, the stopper at L, at R."""
        at_l, at_r = picked(occluder, index, L), picked(occluder, index, R)
        if stopper is occluder:  # (no glass: the first blocker stops the light)
            return [at_l, at_r, at_l, at_r]
        return [at_l, at_r, picked(stopper, index, L), picked(stopper, index, R)]

    @staticmethod
    def first_blocker(blockers):
        """(shape, prim) per pair of what blocks the light at L, else at R (NO_HIT: at
        neither: the terminator or a spot's cone): the unlit sample's occluder, of a shadow
        pair whose light lights one sample only."""
        at_l, at_r = blockers[:2]
        return np.where((at_l[:, 0] != NO_HIT)[:, None], at_l, at_r)

    def stopper_of(self, shadow, blocked):
        """Where the light stops along the shadow rays ``shadow`` (Dr.Jit, not evaluated)
        blocked where ``blocked``: (shape, prim) of the first surface crossed that lets no
        light through (kt <= 0), or of the crossing past max_shadow_crossings, at which the
        renderer counts the light as blocked; NO_HIT where the light gets through. The
        renderer's own walk (``Tracer.crossings``) finds it."""
        with dr.suspend_grad():
            return self.tracer.crossings(self.scene, self.terms.surfaces, shadow, blocked,
                                         stop=True).stopper

    def shadow_crossing(self, table, ray, si, light, blockers, which, g, choices, name):
        """g of the shadow pairs ``which`` (numpy) of light ``light`` (per pair) at the hits
        ``si`` of the stacked rays ``ray``: the inside function, on the shadow rays, of the
        first of ``blockers`` (:meth:`blockers`: the occluders and stoppers at L and R)
        whose sign differs between L and R (the unlit sample's occluder if none does);
        where the unlit sample has no blocker, it faces away from the light (the
        terminator: N.L) or lies outside a spot's cone (cos a, where its sign differs
        between L and R). ``choices``: see g_at (theirs: under ``name`` and the light)."""
        lanes = dr.width(si.p)
        lifted = lifted_point(table, si, si.is_valid(), self.tracer.offset_scale)
        first = self.first_blocker(blockers)
        unblocked = jit_array(mi.Bool, stacked(first[:, 0] == NO_HIT, lanes))
        # the other candidates: where the light is blocked at both samples (shadow_differs),
        # the blockers that are not the first
        both = which & (blockers[0][:, 0] != NO_HIT) & (blockers[1][:, 0] != NO_HIT)
        others = [b for b in blockers if np.any(both & (b[:, 0] != NO_HIT)
                                                 & (b[:, 0] != first[:, 0]))]
        candidates = [first] + [np.where((both & (b[:, 0] != NO_HIT))[:, None], b, first)
                                for b in others]
        for j, source in enumerate(self.lights):
            mask = which & (light == j)
            if not mask.any():
                continue
            wi, _, _ = source.illuminate(si.p)
            # (from where the renderer's shadow rays start: a ray epsilon off the surface)
            shadow = self.tracer.shadow_ray(si, wi, lifted)
            facing = dr.dot(self.tracer.facing_normal(si, ray), wi)
            made = choices.get((name, "shadow", j))
            facing, crosses = cone_crossing(source, wi, facing, made, len(which), lanes)
            if made is None:  # (each candidate's face and edge where the pair's segment of
                # shadow rays leaves the blocking mesh: Visibility.outline; which one's
                # function changes sign between L and R)
                outlines = [self.outline(table, shadow, Faces(table, b[:, 0], b[:, 1]))[1:]
                            for b in candidates]
                chosen = None
                if len(candidates) > 1:
                    with dr.suspend_grad():
                        ends = at_l_and_r(shadow, len(which))
                        g_l, g_r = ([self.inside(table, rays, self._faces(table, b, walked),
                                                 edge) for b, (edge, walked)
                                     in zip(candidates, outlines)] for rays in ends)
                        chosen = dr.zeros(mi.UInt32, len(which))  # (none: the first)
                        for c in reversed(range(len(candidates))):
                            chosen = dr.select(signs_differ(g_l[c], g_r[c]), c, chosen)
                # (evaluated now: a later call reads them, not their graph; g_at evaluates
                # the Dr.Jit arrays of choices, not those in lists)
                dr.eval(chosen, [v for outline in outlines for v in outline if v is not None])
                made = (crosses, outlines, chosen)
            choices[(name, "shadow", j)] = (crosses,) + made[1:]
            _, outlines, chosen = made
            gs = [self.inside(table, shadow, self._faces(table, b, walked, lanes),
                              on_lanes(edge, lanes))
                  for b, (edge, walked) in zip(candidates, outlines)]
            pick = gs[0]
            if chosen is not None:
                chosen = on_lanes(chosen, lanes)
                for c in range(1, len(gs)):
                    pick = dr.select(chosen == c, gs[c], pick)
            g = dr.select(jit_array(mi.Bool, stacked(mask, lanes)),
                          dr.select(unblocked, facing, pick), g)
        return g

    @staticmethod
    def _faces(table, blocker, walked, lanes=None):
        """The :class:`Faces` of ``blocker`` ((shape, prim) per pair), their primitives those
        ``walked`` to the mesh's outline where not None (Visibility.outline); per pair, or
        on the stacked rays' ``lanes``."""
        if lanes is None:
            faces = Faces(table, blocker[:, 0], blocker[:, 1])
            return faces if walked is None else faces.with_prim(walked)
        faces = Faces(table, stacked(blocker[:, 0], lanes), stacked(blocker[:, 1], lanes))
        return faces if walked is None else faces.with_prim(on_lanes(walked, lanes))
