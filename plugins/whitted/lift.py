"""The terminator lift of the Whitted integrator: where shadow rays leave a smooth-shaded mesh.

Where the shading normal faces a light but the flat facet that was hit does not, a
shadow ray leaving the facet would run through the mesh's own far side and shadow a
point that the contract says is lit (a convex object never shadows itself). Such a
ray starts instead from the hit point lifted off its facet onto the smooth surface
that the vertex normals describe (Hanika, "Hacking the shadow terminator", Ray
Tracing Gems II, 2021): the barycentric average of its projections onto the tangent
planes of the corners it lies below, then a ray epsilon out along the shading normal.

The hit face's corners and vertex normals are looked up by shape id and primitive in
the scene's geometry table (``hits.py``): the lift's kernel does not depend on how
many meshes the scene has. It is not differentiable (the lifted point only moves the
start of a detached shadow ray).
"""

import drjit as dr
import mitsuba as mi

from .hits import SMOOTH


def lifted_point(table, si, active, offset_scale=1.0):
    """The start of the shadow rays of each hit near a terminator (None: the scene has no
    smooth mesh). ``table``: the scene's HitTable; ``offset_scale``: the ray epsilon's factor
    (see ``Tracer.spawn_ray``)."""
    if not table.has_smooth:
        return None
    shape_id = dr.reinterpret_array(mi.UInt32, si.shape)
    active = active & (shape_id < table.size)
    kind = dr.gather(mi.UInt32, table.kind, shape_id, active)
    mask = active & ((kind & SMOOTH) != 0)
    row = dr.gather(mi.UInt32, table.first, shape_id, mask)
    vertex, corners = table.corners(row, si.prim_index, mask)
    normals = [dr.gather(mi.Normal3f, table.normals, v, mask) for v in vertex]
    e1, e2, q = corners[1] - corners[0], corners[2] - corners[0], si.p - corners[0]
    d11, d12, d22 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
    q1, q2 = dr.dot(q, e1), dr.dot(q, e2)
    inv = dr.rcp(d11 * d22 - d12 * d12)
    w1, w2 = (d22 * q1 - d12 * q2) * inv, (d11 * q2 - d12 * q1) * inv
    p = mi.Point3f(si.p)
    for w, corner, n in zip((1.0 - w1 - w2, w1, w2), corners, normals):
        p -= w * dr.minimum(dr.dot(si.p - corner, n), 0.0) * n
    lifted = dr.select(mask, p, si.p)
    return lifted + (1.0 + dr.max(dr.abs(lifted))) * (mi.math.RayEpsilon * offset_scale) \
        * si.sh_frame.n
