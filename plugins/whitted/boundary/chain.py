"""The specular chain (the package docstring): the path that follows, from the surface
seen, the refracted ray where kt > 0 (the reflected one under total internal reflection),
else the reflected ray where kr > 0, as deep as the tree goes (the render's ``max_depth``
bounces), at most CHAIN_DEPTH (:func:`chain_depth`). Its next ray
(:meth:`Chain.chain_step`), its keys per bounce (:meth:`Chain.chain_keys`), how far the
chains reach, and g of a pair whose edge is seen along it (:meth:`Chain.chain_crossing`):
each ray's chain replayed with derivatives to the bounce, then the visibility, checker or
shadow function there, or the refraction margin where total internal reflection switches
(``tir.py``)."""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..tree import reflect, refract
from .lattice import (CHAIN_CHECKER, CHAIN_SHADOW, CHAIN_TIR, CHAIN_VISIBILITY, NO_HIT, STOP,
                      _host_keys, picked)
from .terms import _evaluated, stacked

# The most bounces of the specular chain followed past the first hit, whatever the tree's depth:
# each takes 33 bytes a sample and 9 a light, 17 with glass (samples.py), and a chain between two mirrors
# goes on to the last bounce
CHAIN_DEPTH = 8


def chain_depth(max_depth):
    """The bounces of the specular chain followed past the first hit for a tree of
    ``max_depth`` bounces: every bounce the tree traces (bounce d of the chain is the tree's
    generation d + 1), at most CHAIN_DEPTH. An edge seen past them has no term. Four bounces
    were followed until 2026-12-07, whatever the depth: the horizon seen through a glass ball
    that is seen through a glass cone by total internal reflection (random scene 22, five
    bounces) had none, and its scale's derivative was off by 46 % of the finite difference's
    sum at k = 32 (11 % with five)."""
    return min(max_depth, CHAIN_DEPTH)


def _merge(mask, si, other):
    """The fields the boundary terms read (uv, shape, prim_index, t, p, n and the shading
    normal) of ``si`` where ``mask``, else of ``other``."""
    out = dr.zeros(mi.SurfaceInteraction3f, dr.width(mask))
    out.p, out.n = dr.select(mask, si.p, other.p), dr.select(mask, si.n, other.n)
    out.sh_frame = mi.Frame3f(dr.select(mask, si.sh_frame.n, other.sh_frame.n))
    out.uv = dr.select(mask, si.uv, other.uv)
    out.shape = dr.select(mask, si.shape, other.shape)
    out.prim_index = dr.select(mask, si.prim_index, other.prim_index)
    out.t = dr.select(mask, si.t, other.t)
    return out


class Chain:
    """The specular chain of :class:`Boundary` (a mixin of Boundary)."""

    def chain_keys(self, ray, alive, tir, normals=True):
        """The keys of the specular chain (numpy lists, a bounce each: ``chain_shape``, ...,
        ``chain_tir``) from its first rays ``ray``, where ``alive`` (the first hits with a
        next ray), ``tir``: where that ray is a total internal reflection. Each bounce's keys
        are one evaluation. ``normals``: with ``chain_normal``, the face's normal, three
        planes a bounce (the lattice's, for its creases; not for rays whose shapes and
        lights only are read)."""
        scene, table = self.scene, self.terms.geometry
        out = {"chain_" + name: [] for name in ("shape", "prim", "t", "cell", "tir", "lit",
                                                 "occluder", "stopper")}
        if normals:
            out["chain_normal"] = []
        for _ in range(self.chain_depth):
            if not dr.any(alive):  # (the chain's keys past its end: as the lattice starts)
                break
            si_k = self.tracer.intersect(scene, table, ray, coherent=False)
            found = alive & si_k.is_valid()
            keys_k = self.hit_keys(si_k, ray, found)
            keys_k["shape"] = dr.select(found, keys_k["shape"],
                                        dr.select(alive, mi.UInt32(NO_HIT), mi.UInt32(STOP)))
            at_tir = alive & tir  # (total internal reflection at the bounce that led here)
            alive = found & keys_k["go"]
            ray, tir = keys_k["next"], keys_k["tir"]
            dr.eval(keys_k, si_k.n if normals else [], at_tir, alive)
            # (lit, occluder and stopper: lists, one per light)
            for name, value in _host_keys(keys_k).items():
                out["chain_" + name] += value if isinstance(value, list) else [value]
            if normals:
                out["chain_normal"] += [c.numpy() for c in si_k.n]  # (its x, y, z planes)
            out["chain_tir"].append(at_tir.numpy())
        return out

    def chain_step(self, terms, si, ray):
        """The next ray of the *specular chain* from the hit ``si`` of ``ray``: the refracted
        ray where the surface has kt > 0 (the reflected one under total internal reflection),
        else the reflected ray where kr > 0; (ray, whether there is one, TIR mask). Attached
        when ``si`` and ``ray`` are (eta, the geometry, the camera)."""
        surfaces = terms.surfaces
        hit = si.is_valid()
        slot = surfaces.slot(si.shape, si.prim_index, hit)
        kr = surfaces.get("reflectivity", slot, hit)
        kt = surfaces.get("refractivity", slot, hit)
        eta = surfaces.get("ior", slot, hit)
        v, n = -ray.d, self.tracer.facing_normal(si, ray)
        entering = dr.dot(si.n, ray.d) < 0
        refracted, tir = refract(v, n, dr.select(entering, dr.rcp(eta), eta))
        through = hit & (kt > 0) & ~tir
        back = hit & ~through & ((kr > 0) | (kt > 0))
        d = dr.select(through, refracted, reflect(v, n))
        return self.tracer.spawn_ray(si, d), through | back, hit & (kt > 0) & tir

    def chain_bounces(self):
        """How many bounces of the specular chain some chain reaches: those before the first
        that none does (0: no mirror, no glass)."""
        reached = [not np.all(shape == STOP) for shape in self.chain_shape]
        return (reached + [False]).index(False)  # (every bounce reached: chain_depth)

    def chain_crossing(self, table, terms, ray, si, ends, kind, depth, g, light, line,
                       choices):
        """g of the pairs whose edge is seen along the specular chain, at bounce ``depth``:
        each ray's chain replayed, attached, then the visibility, checker or shadow function
        there (``light``: per pair, the light of a shadow), or (total internal reflection
        switching) the refraction margin at the surface it leaves (the stacked rays
        ``ray``, hitting ``si``)."""
        lanes = dr.width(ray.d)
        bounce = stacked(depth, lanes)
        final_ray, final_si, margin = ray, si, mi.Float(0.0)
        for d in range(int(depth.max()) + 1):
            last = jit_array(mi.Bool, bounce == d)  # (the lanes whose chain ends here)
            margin = dr.select(last, self.refraction_margin(terms, si, ray), margin)
            ray, _, _ = self.chain_step(terms, si, ray)
            dr.eval(ray)
            si = _evaluated(self.tracer.intersect(self.scene, table, ray, coherent=False))
            final_ray = mi.Ray3f(dr.select(last, ray.o, final_ray.o),
                                 dr.select(last, ray.d, final_ray.d))
            final_si = _merge(last, si, final_si)
        d = np.maximum(depth, 0)
        L, R = ends.l, ends.r
        left = tuple(picked(a, d, L) for a in (self.chain_shape, self.chain_prim, self.chain_t))
        right = tuple(picked(a, d, R) for a in (self.chain_shape, self.chain_prim, self.chain_t))
        if (kind == CHAIN_VISIBILITY).any():  # (none, as where only a light moves: skipped)
            vis = self.visibility(table, final_ray, left, right, choices, "chain")
            g = dr.select(jit_array(mi.Bool, stacked(kind == CHAIN_VISIBILITY, lanes)), vis, g)
        g = dr.select(jit_array(mi.Bool, stacked(kind == CHAIN_TIR, lanes)), margin, g)
        if (kind == CHAIN_CHECKER).any():
            g = self.checker_crossing(terms, final_si, *line, kind == CHAIN_CHECKER, g,
                                      choices, "chain")
        if (kind == CHAIN_SHADOW).any():
            index = d * len(self.lights) + light
            blockers = self.blockers(self.chain_occluder, self.chain_stopper, index, L, R)
            g = self.shadow_crossing(table, final_ray, final_si, light, blockers,
                                     kind == CHAIN_SHADOW, g, choices, "chain")
        return g
