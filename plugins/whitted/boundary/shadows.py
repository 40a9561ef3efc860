"""Shadow edges of point, spot and directional lights, and the terminator (the package
docstring, "Pairs"): what blocks a light at the unlit sample (:meth:`Shadows.blocker`) and
g of a shadow pair (:meth:`Shadows.shadow_crossing`): the blocker's inside function on the
shadow rays (``visibility.py``'s), or, where the unlit sample has no blocker, N.L (the
terminator: it has no code of its own but this) or a spot's cos a (``spot.py``). The same
function serves the shadow edges seen along the specular chain (``chain.py``)."""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..lift import lifted_point
from .lattice import NO_HIT, picked
from .spot import cone_crossing
from .terms import on_lanes, stacked
from .visibility import Faces


class Shadows:
    """The shadow edges of :class:`Boundary` (a mixin of Boundary)."""

    @staticmethod
    def blocker(lit, occluder, index, L, R):
        """(shape, prim) per pair (numpy) of what blocks light ``index`` (per pair: the first
        index of ``lit`` and ``occluder``) at the unlit one of L and R (their flat positions,
        see :func:`flat`; NO_HIT: nothing)."""
        blocked_l = ~picked(lit, index, L)
        return np.where(blocked_l[:, None], picked(occluder, index, L),
                        picked(occluder, index, R))

    def shadow_crossing(self, table, ray, si, light, blocker, which, g, choices, name):
        """g of the shadow pairs ``which`` (numpy) of light ``light`` (per pair) at the hits
        ``si`` of the stacked rays ``ray``: the blocking primitive's inside function on the
        shadow rays; where the unlit sample has no blocker, it faces away from the light
        (the terminator: N.L) or lies outside a spot's cone (cos a, where its sign differs
        between L and R). ``choices``: see g_at (theirs: under ``name`` and the light)."""
        lanes = dr.width(si.p)
        lifted = lifted_point(table, si, si.is_valid(), self.tracer.offset_scale)
        unblocked = jit_array(mi.Bool, stacked(blocker[:, 0] == NO_HIT, lanes))
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
            if made is None:  # (the blocker's face and edge where the pair's segment of
                # shadow rays leaves the blocking mesh: Visibility.outline)
                faces = Faces(table, blocker[:, 0], blocker[:, 1])
                _, edge, walked = self.outline(table, shadow, faces)
                made = (crosses, edge, walked)
            choices[(name, "shadow", j)] = (crosses,) + made[1:]
            _, edge, prim = made
            blocking = Faces(table, stacked(blocker[:, 0], lanes), stacked(blocker[:, 1], lanes))
            if prim is not None:  # (followed to the mesh's outline)
                blocking = blocking.with_prim(on_lanes(prim, lanes))
            gs = self.inside(table, shadow, blocking, on_lanes(edge, lanes))
            g = dr.select(jit_array(mi.Bool, stacked(mask, lanes)),
                          dr.select(unblocked, facing, gs), g)
        return g
