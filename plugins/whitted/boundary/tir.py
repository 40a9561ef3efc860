"""Total internal reflection switching on or off along the specular chain (the package
docstring, "Pairs"): g of such a pair is the refraction margin at the surface the chain
leaves (:meth:`Tir.refraction_margin`); the chain's keys flag each bounce that is a total
internal reflection and the chain replays it (``chain.py``)."""

import drjit as dr


class Tir:
    """Total internal reflection's edges of :class:`Boundary` (a mixin of Boundary)."""

    def refraction_margin(self, terms, si, ray):
        """1 - sin^2 of the refracted angle at the hit ``si`` of ``ray``, 1 - (eta_i /
        eta_t)^2 (1 - cos^2 theta_i): > 0 where the ray refracts, <= 0 under total internal
        reflection (as ``tree.refract`` decides it). Attached as ``si`` and ``ray`` are."""
        hit = si.is_valid()
        slot = terms.surfaces.slot(si.shape, si.prim_index, hit)
        eta = terms.surfaces.get("ior", slot, hit)
        v, n = -ray.d, self.tracer.facing_normal(si, ray)
        ratio = dr.select(dr.dot(si.n, ray.d) < 0, dr.rcp(eta), eta)
        return 1.0 - dr.square(ratio) * (1.0 - dr.square(dr.dot(n, v)))
