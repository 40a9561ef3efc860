"""Ray differentials through specular bounces: a sample's footprint carried from the camera
through mirror reflection and refraction (Igehy, "Tracing Ray Differentials", 1999).

Anti-aliasing's camera rays carry their samples' footprints as ``mi.RayDifferential3f``:
the offset rays (``o_x``, ``d_x``) and (``o_y``, ``d_y``) through the sample's neighbours
one footprint away (``camera.sample``). A checkerboard seen directly is averaged over the
footprint those rays span where they meet it (``hits.uv_footprint``,
``checkerboard.checker_filtered``). Seen in a mirror or through glass it was point
sampled: a curved mirror shrinks a board into detail finer than a pixel, which no
affordable grid of samples resolves (issue 31: the mirror balls of
``scenes/aa_showcase.ray`` were most of its refinement's cost).

Here each child of a hit gets offset rays of its own, to first order those of the offset
rays' own bounce:

* the offset ray meets the hit's tangent plane (through ``si.p``, normal ``si.n``) at
  ``p_x``: the hit point moved by the footprint, ``dP/dx`` (Igehy's transfer);
* the shading normal there, ``n_x``, is the surface's own: its curvature turns the child's
  direction (a sphere's normal from its centre, a smooth mesh's interpolated from its
  vertices; a flat face's is ``si.n`` everywhere: a plane mirror keeps the footprint's
  spread), flipped to the side the main ray's normal faces;
* the child's offset ray leaves ``p_x`` (moved off the surface as the child's origin is)
  along the mirror or the refracted direction of the offset ray about ``n_x``, with the
  main ray's relative index of refraction.

The offset rays are detached: the footprint is a filter's width, and its derivative (with
respect to an index of refraction, say) is not computed. Where the offset ray misses the
tangent plane (parallel to it), the child's offset ray is the child itself: no footprint,
the board point sampled there.
"""

import drjit as dr
import mitsuba as mi


def tangent_point(si, o, d):
    """Where the ray (o, d) meets the plane of the hit ``si`` (through si.p, normal si.n),
    and whether it does (not parallel to it)."""
    t = dr.dot(si.n, si.p - o) / dr.dot(si.n, d)
    met = dr.isfinite(t)
    return dr.select(met, dr.fma(d, t, o), si.p), met


def offset_children(ray, si, n, eta_ratio, children, normal_at, active, reflect, refract):
    """The reflected and refracted ``children`` (Ray3f, from ``Tracer.spawn_ray``) of the
    hits ``si`` of ``ray`` (a RayDifferential3f) as RayDifferential3f carrying their
    footprints (see the module docstring). ``n``: the shading normal facing the ray;
    ``eta_ratio``: eta_i / eta_t of each lane; ``normal_at(si, p, active)``: the surface's
    shading normal at points ``p`` of its tangent plane (``hits.HitTable.normal_at``);
    ``reflect``, ``refract``: the tree's own laws of reflection and refraction."""
    offsets = {}
    with dr.suspend_grad():
        si, n, eta_ratio = dr.detach(si), dr.detach(n), dr.detach(eta_ratio)
        flip = dr.dot(si.sh_frame.n, n) < 0  # n faces the ray: the offset normals alike
        for axis in ("x", "y"):
            o, d = dr.detach(getattr(ray, "o_" + axis)), dr.detach(getattr(ray, "d_" + axis))
            p, met = tangent_point(si, o, d)
            n_offset = normal_at(si, p, active & met)
            n_offset = dr.select(flip, -n_offset, n_offset)
            v = -dr.normalize(d)
            d_t, _ = refract(v, n_offset, eta_ratio)
            offsets[axis] = p, met, (reflect(v, n_offset), d_t)
    out = []
    for k, child in enumerate(children):
        child_d = mi.RayDifferential3f(child)
        lift = dr.detach(child.o) - si.p  # the child's origin off the surface
        for axis, (p, met, directions) in offsets.items():
            setattr(child_d, "o_" + axis, dr.select(met, p + lift, dr.detach(child.o)))
            setattr(child_d, "d_" + axis, dr.select(met, directions[k], dr.detach(child.d)))
        child_d.has_differentials = True
        out.append(child_d)
    return tuple(out)
