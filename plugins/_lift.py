"""The terminator lift of the Whitted integrator: where shadow rays leave a smooth-shaded mesh.

Where the shading normal faces a light but the flat facet that was hit does not, a
shadow ray leaving the facet would run through the mesh's own far side and shadow a
point that the contract says is lit (a convex object never shadows itself). Such a
ray starts instead from the hit point lifted off its facet onto the smooth surface
that the vertex normals describe (Hanika, "Hacking the shadow terminator", Ray
Tracing Gems II, 2021): the barycentric average of its projections onto the tangent
planes of the corners it lies below, then a ray epsilon out along the shading normal.

**One table for all smooth meshes.** The faces, positions and normals of every mesh
of the scene that has vertex normals are concatenated on the host into one table
(face indices offset to the concatenated vertices), with, by shape registry id, the
index of each mesh's first face (``NO_MESH`` for the other shapes). The lift is then
a lookup by ``si.shape`` and ``si.prim_index``: its kernel does not depend on how
many meshes the scene has. The table is rebuilt only when the meshes' buffers
change (it keeps them, so their Dr.Jit ids cannot be reused meanwhile); it is not
differentiable (the lifted point only moves the start of a detached shadow ray).
"""

import drjit as dr
import mitsuba as mi
import numpy as np

NO_MESH = 0xFFFFFFFF  # first face of a shape that is not a smooth mesh


class SmoothMeshes:
    """The concatenated table of a scene's smooth meshes (see the module docstring);
    ``update(scene)`` before each render, then ``lifted_point``."""

    def __init__(self):
        self.key = None  # the buffers the table was built from
        self.empty = True

    def update(self, scene):
        meshes = [shape for shape in scene.shapes() if shape.is_mesh() and shape.has_vertex_normals()]
        buffers = [(mesh.faces_buffer(), mesh.vertex_positions_buffer(),
                    mesh.vertex_normals_buffer()) for mesh in meshes]
        key = [(dr.reinterpret_array(mi.UInt32, mi.ShapePtr(mesh))[0],
                *(buffer.index for buffer in bufs)) for mesh, bufs in zip(meshes, buffers)]
        if key == self.key:
            return self
        self.key, self.buffers = key, buffers  # kept: see the module docstring
        self.empty = not meshes
        if self.empty:
            return self
        ids = np.array([k[0] for k in key], np.int64)
        first_face = np.full(ids.max() + 1, NO_MESH, np.uint32)
        faces, positions, normals = [], [], []
        face_count = vertex_count = 0
        for shape_id, (face_buf, position_buf, normal_buf) in zip(ids, buffers):
            first_face[shape_id] = face_count
            mesh_faces = face_buf.numpy().astype(np.int64)
            faces.append(mesh_faces + vertex_count)
            positions.append(position_buf.numpy())
            normals.append(normal_buf.numpy())
            face_count += len(mesh_faces) // 3
            vertex_count += len(positions[-1]) // 3
        self.first_face = mi.UInt32(first_face)
        self.faces = mi.UInt32(np.concatenate(faces).astype(np.uint32))
        self.positions = mi.Float(np.concatenate(positions))
        self.normals = mi.Float(np.concatenate(normals))
        return self

    def lifted_point(self, si, active):
        """The start of the shadow rays of each hit near a terminator (None: no smooth mesh)."""
        if self.empty:
            return None
        shape_id = dr.reinterpret_array(mi.UInt32, si.shape)
        active = active & (shape_id < dr.width(self.first_face))
        first = dr.gather(mi.UInt32, self.first_face, shape_id, active)
        mask = active & (first != NO_MESH)
        face = (first + si.prim_index) * 3
        vertex = [dr.gather(mi.UInt32, self.faces, face + k, mask) for k in range(3)]
        corners = [dr.gather(mi.Point3f, self.positions, v, mask) for v in vertex]
        normals = [dr.gather(mi.Normal3f, self.normals, v, mask) for v in vertex]
        e1, e2, q = corners[1] - corners[0], corners[2] - corners[0], si.p - corners[0]
        d11, d12, d22 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
        q1, q2 = dr.dot(q, e1), dr.dot(q, e2)
        inv = dr.rcp(d11 * d22 - d12 * d12)
        w1, w2 = (d22 * q1 - d12 * q2) * inv, (d11 * q2 - d12 * q1) * inv
        p = mi.Point3f(si.p)
        for w, corner, n in zip((1.0 - w1 - w2, w1, w2), corners, normals):
            p -= w * dr.minimum(dr.dot(si.p - corner, n), 0.0) * n
        lifted = dr.select(mask, p, si.p)
        return lifted + (1.0 + dr.max(dr.abs(lifted))) * mi.math.RayEpsilon * si.sh_frame.n
