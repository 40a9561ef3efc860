"""The surface interactions of the Whitted integrator, by lookup in one table of the scene's
geometry instead of Mitsuba's per-shape dispatch.

``scene.ray_intersect`` computes the surface interaction through a virtual call over
*every* shape of the scene, which Dr.Jit traces once per shape each time: a cost that
grows with the number of shapes, at every call. Here a hit is found by
``scene.ray_intersect_preliminary`` (the ray tracer only: distance, shape, primitive,
barycentrics) and the fields the integrator reads -- ``t``, ``p``, the geometric normal
``n``, the shading normal ``sh_frame.n``, ``uv``, ``shape``, ``prim_index`` -- are
computed from tables indexed by the shape's registry id:

* meshes: every mesh's faces (offset to the concatenated vertices), positions, vertex
  normals (smooth meshes) and texture coordinates, concatenated on the host, with each
  mesh's first face; computed as Mitsuba's meshes do, operation for operation (the
  point and the interpolated attributes at the ray tracer's barycentrics, the
  normalized face normal; texture coordinates = the barycentrics on a mesh without
  any): the same bits;
* Mitsuba's analytic spheres, and the sphere set's (``raymitsuba.geometry.sphere_set``: one
  ``ellipsoids`` shape, its sphere k in row first + k): centre, radius and world-to-object
  transform (the point
  on the ray at the hit distance, the normal from the centre, uv = (phi / 2pi, theta / pi)
  of the object-space point, as Mitsuba's sphere does; uv may differ from Mitsuba's in
  the last bits).

Derivatives follow the ray and, where a parameter key moves them, the shapes (a copy of the
table whose centres, radii and positions carry the keys' derivatives: ``geometry_ad.py``):
where the ray or the geometry carries gradients the hit distance is re-intersected differentiably
(ray-plane on the hit face, ray-sphere) and the barycentrics follow the point, with
``dr.replace_grad`` keeping the ray tracer's values. The kernels do not depend on the
number of shapes; the table is rebuilt only when the shapes' buffers change (it keeps
them, so their Dr.Jit ids cannot be reused meanwhile). A scene with any other kind of
shape uses ``scene.ray_intersect`` (``supported`` is False; its meshes are still in the
table, for the lift).
"""

import drjit as dr
import mitsuba as mi
import numpy as np

from raymitsuba.geometry import sphere_set, topology

from .arrays import jit_array
from .protocol import MeshTopology, SurfaceSet, UnboundedPlane

# bits of a shape's kind (0: not in the table); PLANE: a flat mesh that stands for an unbounded
# plane (protocol.UnboundedPlane)
MESH, SMOOTH, TEXCOORDS, SPHERE, PLANE = 1, 2, 4, 8, 16
NO_NEIGHBOUR = 0xFFFFFFFF  # (HitTable.neighbours: no face across an edge; topology.NONE as uint32)


# Shape ids read by shape_ids, by the Dr.Jit index of the scene's array of shapes (which
# names it while that array lives: each entry keeps its array), the latest few
_IDS_READ = {}
IDS_KEPT = 8


def shape_ids(scene):
    """The registry ids of the scene's shapes (one vectorized read), in ``scene.shapes()``
    order: they name the shapes while the scene lives. A scene's shapes do not change:
    they are read once (a read waits for every kernel queued, so that the adjoint pass's
    next chunk would otherwise wait for the last one's kernel before building its own)."""
    if not scene.shapes():
        return np.zeros(0, np.uint32)
    shapes = scene.shapes_dr()
    read = _IDS_READ.get(shapes.index)
    if read is None:
        read = _IDS_READ[shapes.index] = \
            (shapes, dr.reinterpret_array(mi.UInt32, shapes).numpy())
        while len(_IDS_READ) > IDS_KEPT:
            del _IDS_READ[next(iter(_IDS_READ))]
    return read[1]


def sphere_key(shape):
    bbox = shape.bbox()
    return tuple(bbox.min) + tuple(bbox.max)


class _Properties(mi.TraversalCallback):
    """A shape's own properties by name, (value, its C++ type), without recursing into its
    children: ``mi.traverse`` builds a SceneParameters (hashing the JIT ids of each value
    read), a cost per shape that reading the properties directly does not have."""

    def __init__(self):
        mi.TraversalCallback.__init__(self)
        self.values = {}

    def put(self, name, value, flags, cpptype=None):
        self.values[name] = (value, cpptype)


def shape_property(shape, name):
    """``mi.traverse(shape)[name]``, read directly (see _Properties)."""
    properties = _Properties()
    shape.traverse(properties)
    value, cpptype = properties.values[name]
    return value if cpptype is None else mi.get_property(value, cpptype, shape)


def traversed_values(obj):
    """The values ``obj`` (a plugin) puts in ``mi.traverse``, its own (see _Properties)."""
    properties = _Properties()
    obj.traverse(properties)
    return [value for value, _ in properties.values.values()]


def sphere_rows(to_world, uv=True):
    """What the table keeps of a sphere of to-world transform ``to_world``, host values of
    its one-lane entries read one by one (no kernel each; only the entries used): (the
    translation column, the first column of the linear part -- its length is the radius --,
    the columns of Mitsuba's own world-to-object matrix as 4 x 3 nested lists or None
    without ``uv``). The world-to-object matrix is the
    transpose of ``inverse_transpose``: its column j holds the first three entries of row
    j of the latter."""
    m = to_world.matrix
    rows = m[0], m[1], m[2]
    center = [row[3][0] for row in rows]
    axis = [row[0][0] for row in rows]
    if not uv:
        return center, axis, None
    it = to_world.inverse_transpose
    return center, axis, [[row[i][0] for i in range(3)] for row in (it[j] for j in range(4))]


NO_SHAPE = 0xFFFFFFFF  # the shape id of no hit (a shape's id is smaller)


def preliminary(t, uv, shape, prim):
    """A PreliminaryIntersection3f of these fields, as the ray tracer gives them (``shape``:
    a UInt32 id, NO_SHAPE: no hit, a null shape)."""
    pi = dr.zeros(mi.PreliminaryIntersection3f, dr.width(t))
    valid = shape != NO_SHAPE
    pi.t, pi.prim_uv, pi.prim_index, pi.valid = t, uv, prim, valid
    pi.shape = dr.reinterpret_array(mi.ShapePtr, dr.select(valid, shape, 0))
    return pi


def barycentrics(corners, p):
    """(b1, b2) of the point ``p`` in the plane of the triangle ``corners`` (p0, p1, p2): p =
    p0 + b1 (p1 - p0) + b2 (p2 - p0), by least squares (exact on the plane)."""
    p0, p1, p2 = corners
    e1, e2, rel = p1 - p0, p2 - p0, p - p0
    a11, a12, a22 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
    r1, r2 = dr.dot(e1, rel), dr.dot(e2, rel)
    inv = dr.rcp(a11 * a22 - a12 * a12)
    return (a22 * r1 - a12 * r2) * inv, (a11 * r2 - a12 * r1) * inv


class SphereRows:
    """The sphere rows of a HitTable under construction, in order: Mitsuba's spheres one by
    one (:func:`sphere_rows`: host values, made arrays a run at a time), a sphere set's in
    bulk (its ellipsoids too); ``arrays()`` gives them as float32 (centres (n, 3), radii
    (n,), world-to-object columns (n, 4, 3) or None, which rows are ellipsoids (n,) bool).
    The world-to-object columns are kept with ``uv`` or where a row is an ellipsoid (its
    hits are solved in object space); a Mitsuba sphere's are then read only with ``uv``
    (zeros otherwise: not used)."""

    def __init__(self, uv):
        self.uv, self.count = uv, 0
        self.blocks = []  # (centres, radii, world-to-object columns, ellipsoids), in row order
        self.run = []  # the latest Mitsuba spheres' sphere_rows, not yet a block

    def add(self, center, axis, to_object):
        self.run.append((center, axis, to_object))
        self.count += 1

    def add_set(self, data):
        self.close_run()
        center, radius, to_object, ellipsoid = sphere_set.unpack(data)
        self.blocks.append((center, radius, np.transpose(to_object, (0, 2, 1)), ellipsoid))
        self.count += len(radius)

    def close_run(self):
        if self.run:
            center, axis, to_object = zip(*self.run)
            count = len(center)
            self.blocks.append((np.array(center, np.float64),
                                np.linalg.norm(np.array(axis, np.float32).astype(np.float64),
                                               axis=1),
                                np.array(to_object, np.float32) if self.uv
                                else np.zeros((count, 4, 3), np.float32),
                                np.zeros(count, bool)))
            self.run = []

    def arrays(self):
        self.close_run()
        center, radius, to_object, ellipsoid = zip(*self.blocks)
        ellipsoid = np.concatenate(ellipsoid)
        keep = self.uv or ellipsoid.any()
        return (np.concatenate(center).astype(np.float32),
                np.concatenate(radius).astype(np.float32),
                np.concatenate(to_object).astype(np.float32) if keep else None, ellipsoid)


class HitTable:
    """The geometry of a scene by shape id (see the module docstring): ``update(scene)``
    before each render, then ``intersect``; the mesh arrays also serve the terminator lift
    (``lift.py``)."""

    def __init__(self):
        # What the table is of (see update)
        self.key = None  # per shape: (registry id, kind, its buffers' JIT ids or the sphere's box)
        self.buffers = None  # per shape: its mesh buffers, the sphere or None (kept: see update)
        self.uv = False  # whether the spheres' texture coordinates are computed (to_object read)
        self.supported = False  # whether every shape is in the table (else Mitsuba's dispatch)
        # By shape id (the scene dict's name): its sphere row or its first vertex
        self.rows_by_name = {}
        self.id_by_name = {}  # its registry id (see build)
        # Whether the geometry carries derivatives (a copy made by geometry_ad.GeometryAD)
        self.moving = False
        # By shape registry id (see build)
        self.kind = None  # UInt32: the bits MESH, SMOOTH, TEXCOORDS, SPHERE, PLANE (0: not in the table)
        self.kind_host = None  # the same, numpy
        self.first = None  # UInt32: the shape's first face (meshes) or row (spheres)
        self.size = None  # UInt32 (opaque): the tables' length, one past the largest id
        # The meshes, concatenated
        self.has_meshes = False  # whether the scene has a mesh in the table
        self.faces = None  # UInt32: three vertex indices per face (into the concatenated vertices)
        self.positions = None  # Float: three per vertex
        self.has_smooth = False  # whether some mesh has vertex normals
        self.normals = None  # Float: three per vertex, if has_smooth (a flat mesh's: zeros)
        self.has_texcoords = False  # whether some mesh has texture coordinates
        self.texcoords = None  # Float: two per vertex, if has_texcoords (others' zeros)
        # The spheres, by row
        self.has_spheres = False  # whether the scene has a sphere
        self.center = None  # Point3f
        self.radius = None  # Float
        self.to_object = None  # Float: the world-to-object columns, 4 x 3 per sphere (None:
        # neither uv nor ellipsoids)
        self.has_ellipsoids = False  # whether some row is an ellipsoid (of a sphere set)
        self.ellipsoid = None  # Bool by row, if has_ellipsoids: its hits solved in object space
        # The meshes' (first face, faces, first vertex, vertices, declared neighbours or
        # None), and their faces' neighbours (see neighbours: made when first read)
        self.mesh_ranges, self.adjacency = [], None

    # -- the table ---------------------------------------------------------------------------
    def update(self, scene, uv=True, ids=None):
        """The table of ``scene`` (rebuilt only if its shapes changed). ``uv``: whether the
        hits' texture coordinates are used (a checkerboard or an image texture); without
        them the spheres' uv are 0 and their world-to-object matrices are not read.
        ``ids``: the shapes' :func:`shape_ids`, if already read."""
        shapes = scene.shapes()
        ids = shape_ids(scene) if ids is None else ids
        key, buffers = [], []
        for shape_id, shape in zip(ids, shapes):
            if shape.is_mesh():
                bufs = (shape.faces_buffer(), shape.vertex_positions_buffer(),
                        shape.vertex_normals_buffer() if shape.has_vertex_normals() else None,
                        shape.vertex_texcoords_buffer() if shape.has_vertex_texcoords() else None)
                buffers.append(bufs)
                key.append((int(shape_id), "mesh") + tuple(-1 if b is None else b.index for b in bufs))
            elif shape.class_name() == "Sphere":
                buffers.append(shape)
                key.append((int(shape_id), "sphere") + sphere_key(shape))
            elif shape.class_name() == "Ellipsoids" and isinstance(shape.bsdf(), SurfaceSet):
                data = shape_property(shape, "data")  # the sphere set (raymitsuba.geometry.sphere_set)
                # (a handle of the table's own: ``data`` is the shape's, which an update
                # points at a new variable, and the key names the variable by its index)
                data = type(data)(data)
                buffers.append(data)
                key.append((int(shape_id), "spheres", data.index))
            else:  # not in the table: its hits need Mitsuba's dispatch
                key.append((int(shape_id), "other"))
                buffers.append(None)
        if key == self.key and (self.uv or not uv):
            return self
        self.key, self.buffers, self.uv = key, buffers, uv  # kept: see the module docstring
        self.supported = bool(key) and all(k[1] != "other" for k in key)
        self.build(ids, key, buffers, shapes)
        return self

    def build(self, ids, key, buffers, shapes):
        size = max(int(max(ids, default=0)) + 1, 2)
        kind = np.zeros(size, np.uint32)
        first = np.zeros(size, np.uint32)  # first face (meshes) or row (spheres)
        faces, positions, normals, texcoords = [], [], [], []
        self.mesh_ranges, self.adjacency = [], None
        spheres = SphereRows(self.uv)
        face_count = vertex_count = 0
        self.rows_by_name = {}
        self.id_by_name = {}
        for k, item, shape in zip(key, buffers, shapes):
            shape_id = k[0]
            if k[1] == "other":
                continue
            self.id_by_name[shape.id()] = shape_id
            self.rows_by_name[shape.id()] = spheres.count if k[1] != "mesh" else vertex_count
            if k[1] == "sphere":
                kind[shape_id], first[shape_id] = SPHERE, spheres.count
                spheres.add(*sphere_rows(shape_property(item, "to_world"), self.uv))
                continue
            if k[1] == "spheres":  # its spheres are rows first + prim_index
                kind[shape_id], first[shape_id] = SPHERE, spheres.count
                spheres.add_set(item.numpy())
                continue
            face_buf, position_buf, normal_buf, texcoord_buf = item
            mesh_faces = face_buf.numpy().astype(np.int64)
            mesh_positions = position_buf.numpy()
            count = len(mesh_positions) // 3
            kind[shape_id] = MESH | (SMOOTH if normal_buf is not None else 0) \
                | (TEXCOORDS if texcoord_buf is not None else 0) \
                | (PLANE if isinstance(shape, UnboundedPlane) and shape.unbounded_plane else 0)
            first[shape_id] = face_count
            faces.append(mesh_faces + vertex_count)
            positions.append(mesh_positions)
            normals.append(normal_buf.numpy() if normal_buf is not None
                           else np.zeros(3 * count, np.float32))
            texcoords.append(texcoord_buf.numpy() if texcoord_buf is not None
                             else np.zeros(2 * count, np.float32))
            self.mesh_ranges.append((face_count, len(mesh_faces) // 3, vertex_count, count,
                                     shape.neighbours if isinstance(shape, MeshTopology)
                                     else None))
            face_count += len(mesh_faces) // 3
            vertex_count += count
        self.kind, self.first = jit_array(mi.UInt32, kind), jit_array(mi.UInt32, first)
        self.kind_host = kind  # (the same, on the host: read without waiting for kernels)
        # The table's length as data, not as a constant of the kernels (it grows with the scene).
        self.size = dr.opaque(mi.UInt32, size)
        self.has_meshes, self.has_spheres = bool(faces), spheres.count > 0

        def upload(parts, dtype, empty):
            return jit_array(mi.Float, np.concatenate(parts).astype(dtype)) if parts else \
                dr.zeros(mi.Float, empty)

        self.faces = jit_array(mi.UInt32, np.concatenate(faces)) if faces else \
            dr.zeros(mi.UInt32, 3)
        self.positions = upload(positions, np.float32, 3)
        self.has_smooth = bool(np.any(kind & SMOOTH))
        self.has_planes = bool(np.any(kind & PLANE))
        self.has_texcoords = bool(np.any(kind & TEXCOORDS))
        # (only the attributes some mesh has: flat or untextured scenes keep no zeros)
        self.normals = upload(normals if self.has_smooth else [], np.float32, 3)
        self.texcoords = upload(texcoords if self.has_texcoords else [], np.float32, 2)
        self.has_ellipsoids = False
        self.center = self.radius = self.to_object = self.ellipsoid = None
        if spheres.count:
            center, radius, to_object, ellipsoid = spheres.arrays()
            self.center = mi.Point3f(*(jit_array(mi.Float, center[:, i])
                                       for i in range(3)))
            self.radius = jit_array(mi.Float, radius)
            # columns of the world-to-object transform (its first three rows), 4 x 3 per sphere
            self.to_object = None if to_object is None else jit_array(mi.Float, to_object)
            self.has_ellipsoids = bool(ellipsoid.any())
            if self.has_ellipsoids:
                self.ellipsoid = jit_array(mi.Bool, ellipsoid)

    # -- the hits ----------------------------------------------------------------------------
    def entries(self, shape_id, valid):
        """(valid, kind, row) of each lane's shape (a UInt32 registry id, where ``valid``):
        the lanes whose shape the table holds, its kind bits and its first row."""
        valid = valid & (shape_id < self.size)
        return (valid, dr.gather(mi.UInt32, self.kind, shape_id, valid),
                dr.gather(mi.UInt32, self.first, shape_id, valid))

    def intersect(self, scene, ray, coherent=False, pi=None):
        """The surface interaction of each ray (``supported`` must be True); ``pi``: the
        rays' closest hits, if already found (else the ray tracer is asked)."""
        if pi is None:
            pi = scene.ray_intersect_preliminary(ray, coherent=coherent)
        shape_id = dr.reinterpret_array(mi.UInt32, pi.shape)
        valid, kind, row = self.entries(shape_id, pi.is_valid())
        attached = self.moving or dr.grad_enabled(ray.o, ray.d)
        si = dr.zeros(mi.SurfaceInteraction3f, dr.width(pi.t))
        t, p, n, shading_n, uv = pi.t, mi.Point3f(0.0), mi.Normal3f(0.0), mi.Normal3f(0.0), \
            mi.Point2f(0.0)
        if self.has_meshes:
            mesh = valid & ((kind & MESH) != 0)
            t_m, p_m, n_m, shading_m, uv_m = self.mesh_hit(pi, ray, kind, row, mesh, attached)
            t = dr.select(mesh, t_m, t)
            p, n = dr.select(mesh, p_m, p), dr.select(mesh, n_m, n)
            shading_n, uv = dr.select(mesh, shading_m, shading_n), dr.select(mesh, uv_m, uv)
        if self.has_spheres:  # (a Mitsuba sphere's one primitive is 0; a set's are its rows)
            sphere = valid & ((kind & SPHERE) != 0)
            t_s, p_s, n_s, uv_s = self.sphere_hit(pi, ray, row + pi.prim_index, sphere, attached)
            t = dr.select(sphere, t_s, t)
            p, n = dr.select(sphere, p_s, p), dr.select(sphere, n_s, n)
            shading_n, uv = dr.select(sphere, n_s, shading_n), dr.select(sphere, uv_s, uv)
        si.t = dr.select(valid, t, dr.inf)
        si.p, si.n, si.uv = p, n, uv
        si.sh_frame = mi.Frame3f(shading_n)
        si.shape = pi.shape
        si.prim_index = pi.prim_index
        si.wi = si.to_local(-ray.d)
        return si

    def known_hits(self, ray, shape, prim, t_near):
        """The hits of ``ray`` on given primitives, solved from the table instead of asked
        of the ray tracer (a PreliminaryIntersection3f for :meth:`intersect`, detached):
        ``shape`` (a UInt32 id, NO_SHAPE: none) and ``prim`` per lane. A mesh face is
        extended to its plane: the hit is where the ray meets that plane, wherever; a
        sphere's is the root nearest ``t_near`` (:meth:`sphere_hit`). None (no hit) where
        the ray meets neither in front of it."""
        with dr.suspend_grad():
            valid, kind, row = self.entries(shape, shape != NO_SHAPE)
            t, uv = mi.Float(t_near), mi.Point2f(0.0)
            if self.has_meshes:
                mesh = valid & ((kind & MESH) != 0)
                _, corners = self.corners(row, prim, mesh)
                p0, p1, p2 = corners
                n = dr.cross(p1 - p0, p2 - p0)
                t_m = dr.dot(n, p0 - ray.o) / dr.dot(n, ray.d)
                t = dr.select(mesh, t_m, t)
                uv = dr.select(mesh, mi.Point2f(*barycentrics(corners, ray(t_m))), uv)
            if self.has_spheres:  # (the line meets the sphere, the far root ahead)
                sphere = valid & ((kind & SPHERE) != 0)
                oc, d, radius = self.sphere_frame(row + prim, ray.o, ray.d, sphere)
                b = dr.dot(oc, d)
                disc = dr.square(b) - dr.squared_norm(d) * (dr.squared_norm(oc)
                                                             - dr.square(radius))
                meets = (disc >= 0) & (dr.sqrt(dr.maximum(disc, 0.0)) > b)
                t = dr.select(sphere & ~meets, dr.nan, t)
            valid &= (t > 0) & (t < dr.inf)
            return preliminary(dr.select(valid, t, dr.inf), uv, dr.select(valid, shape, NO_SHAPE),
                               prim)

    def uv_footprint(self, si, ray, active):
        """(duv_dx, duv_dy, (kx, ky)): each mesh hit's footprint in texture space, as
        ``checkerboard.checker_filtered`` reads it, from where the offset rays of ``ray`` (a
        RayDifferential3f, one footprint away) meet the hit face's plane: an offset ray at
        distance t_k, the main ray at t, k = t / t_k - 1 (the distance falls as 1 / (1 + k s)
        across the footprint, s in footprints), and the derivative of uv, (uv_k - uv) (1 +
        k) (the image of the offset point being uv + duv / (1 + k)). Zero off meshes, and
        where an offset ray meets the plane behind it or not at all (then k is infinite)."""
        shape_id = dr.reinterpret_array(mi.UInt32, si.shape)
        valid = active & (shape_id < self.size)
        kind = dr.gather(mi.UInt32, self.kind, shape_id, valid)
        mesh = valid & ((kind & MESH) != 0)
        if not self.has_meshes:
            return mi.Vector2f(0.0), mi.Vector2f(0.0), (mi.Float(0.0), mi.Float(0.0))
        row = dr.gather(mi.UInt32, self.first, shape_id, mesh)
        vertex, (p0, p1, p2) = self.corners(row, si.prim_index, mesh)
        n = dr.cross(p1 - p0, p2 - p0)
        t = dr.dot(n, p0 - ray.o) / dr.dot(n, ray.d)
        derivatives, distortion = [], []
        for o, d in ((ray.o_x, ray.d_x), (ray.o_y, ray.d_y)):
            t_k = dr.dot(n, p0 - o) / dr.dot(n, d)
            uv = self.texcoords_at(kind, vertex, *barycentrics((p0, p1, p2), o + t_k * d), mesh)
            k = dr.select(t_k > 0, t / t_k - 1.0, dr.inf)
            derivatives.append(dr.select(mesh, mi.Vector2f(uv - si.uv) * (1.0 + k), 0.0))
            distortion.append(dr.select(mesh, k, 0.0))
        return derivatives[0], derivatives[1], tuple(distortion)

    def neighbours(self):
        """A UInt32 of three entries per face (of the concatenated faces): the face of the
        same mesh across each of its edges (edge i: from corner i to corner i + 1 mod 3), as
        that mesh's primitive index; NO_NEIGHBOUR where none (the mesh's border, or more than
        one face). A mesh's own (``protocol.MeshTopology``: a tessellation's faces are grown
        apart), else found where the faces' corners' positions are equal
        (``raymitsuba.geometry.topology``). The topology only: made when first read, and
        kept by the table's copies that carry derivatives."""
        if self.adjacency is None:
            out = np.full((dr.width(self.faces) // 3, 3), NO_NEIGHBOUR, np.uint32)
            if any(declared is None for *_, declared in self.mesh_ranges):
                faces = self.faces.numpy().reshape(-1, 3).astype(np.int64)
                positions = self.positions.numpy().reshape(-1, 3)
            for face0, count, vertex0, vertices, declared in self.mesh_ranges:
                if declared is not None:
                    out[face0:face0 + count] = declared.numpy().reshape(-1, 3)
                    continue
                found = topology.face_neighbours(faces[face0:face0 + count] - vertex0,
                                                 positions[vertex0:vertex0 + vertices])
                out[face0:face0 + count] = found.astype(np.uint32)  # (NONE: NO_NEIGHBOUR)
            self.adjacency = jit_array(mi.UInt32, out.ravel())
        return self.adjacency

    def corners(self, row, prim_index, mesh):
        """(face vertex indices, positions) of each lane's hit face."""
        face = (row + prim_index) * 3
        vertex = [dr.gather(mi.UInt32, self.faces, face + k, mesh) for k in range(3)]
        return vertex, [dr.gather(mi.Point3f, self.positions, v, mesh) for v in vertex]

    def mesh_hit(self, pi, ray, kind, row, mesh, attached):
        vertex, (p0, p1, p2) = self.corners(row, pi.prim_index, mesh)
        b1, b2 = pi.prim_uv.x, pi.prim_uv.y
        e1, e2 = p1 - p0, p2 - p0
        n = mi.Normal3f(dr.normalize(dr.cross(e1, e2)))
        t = pi.t
        if attached:  # the hit follows the ray on the plane of its face
            t_ray = dr.dot(n, p0 - ray.o) / dr.dot(n, ray.d)
            b1_ray, b2_ray = barycentrics((p0, p1, p2), ray(t_ray))
            b1, b2 = dr.replace_grad(b1, b1_ray), dr.replace_grad(b2, b2_ray)
            t = dr.replace_grad(t, t_ray)
        b0 = 1.0 - b1 - b2
        p = dr.fma(p0, b0, dr.fma(p1, b1, p2 * b2))
        shading_n = n
        if self.has_smooth:
            smooth = mesh & ((kind & SMOOTH) != 0)
            n0, n1, n2 = (dr.gather(mi.Vector3f, self.normals, v, smooth) for v in vertex)
            interpolated = dr.fma(n2, b2, dr.fma(n1, b1, n0 * b0))
            interpolated *= dr.rsqrt(dr.squared_norm(interpolated))
            shading_n = dr.select(smooth, mi.Normal3f(interpolated), n)
        return t, p, n, shading_n, self.texcoords_at(kind, vertex, b1, b2, mesh)

    def texcoords_at(self, kind, vertex, b1, b2, mesh):
        """The texture coordinates at barycentrics (b1, b2) of each lane's face (its
        corners' indices ``vertex``): the mesh's interpolated, or (b1, b2) on a mesh
        without any."""
        uv = mi.Point2f(b1, b2)
        if self.has_texcoords:
            textured = mesh & ((kind & TEXCOORDS) != 0)
            uv0, uv1, uv2 = (dr.gather(mi.Point2f, self.texcoords, v, textured) for v in vertex)
            uv = dr.select(textured, dr.fma(uv2, b2, dr.fma(uv1, b1, uv0 * (1.0 - b1 - b2))), uv)
        return uv

    def sphere_frame(self, row, o, d, sphere):
        """(oc, d, r): the ray (o, d) in the frame where the sphere of row ``row`` is centred
        at the origin with radius r -- for a sphere the world's frame shifted by its centre
        (o - c, d, its radius), for an ellipsoid its object space (W o + w, W d, 1; the same
        ray parameter t). ``o``, ``d``: Point3f, Vector3f."""
        center = dr.gather(mi.Point3f, self.center, row, sphere)
        radius = dr.gather(mi.Float, self.radius, row, sphere)
        oc = o - center
        if not self.has_ellipsoids:
            return oc, d, radius
        ellipsoid = sphere & dr.gather(mi.Bool, self.ellipsoid, row, sphere)
        w = self.to_object_columns(row, ellipsoid)
        return (dr.select(ellipsoid, _linear(w, o) + w[3], oc),
                dr.select(ellipsoid, _linear(w, d), d), dr.select(ellipsoid, 1.0, radius))

    def to_object_columns(self, row, active):
        """The four columns of row ``row``'s world-to-object transform (3 x 4)."""
        return [dr.gather(mi.Vector3f, self.to_object, row * 4 + i, active) for i in range(4)]

    def sphere_hit(self, pi, ray, row, sphere, attached):
        """The hit on the sphere of table row ``row``: t is the root of |o + t d - c| = r
        that the ray tracer found (the one nearer its distance), solved here from the
        table's centre and radius, so that every representation of a sphere (Mitsuba's
        ``sphere``, the sphere set's ``ellipsoids``) gives the same bits, attached to the
        ray and the geometry. The operations are those of Mitsuba's sphere (the same bits
        as its ray tracer on most hits, never less accurate): the quadratic solved from the
        point of the ray's line nearest the centre, o + t0 d, with no cancellation far
        from the sphere. An ellipsoid's hit is solved alike in its object space
        (:meth:`sphere_frame`), its normal the inverse transpose of the object-space one."""
        oc, d, radius = self.sphere_frame(row, ray.o, ray.d, sphere)
        a = dr.squared_norm(d)
        t0 = -dr.dot(oc, d) / a
        h = dr.fma(d, t0, oc)
        _, near, far = mi.math.solve_quadratic(a, 2.0 * dr.dot(h, d),
                                               dr.squared_norm(h) - dr.square(radius))
        near, far = near + t0, far + t0
        t = dr.select(dr.abs(near - pi.t) <= dr.abs(far - pi.t), near, far)
        p = ray(t)
        center = dr.gather(mi.Point3f, self.center, row, sphere)
        n, columns = self.sphere_normal(row, p, center, sphere)
        if not self.uv:  # no uv used (see update)
            return t, p, n, mi.Point2f(0.0)
        columns = columns or self.to_object_columns(row, sphere)
        local = dr.fma(columns[2], p.z, dr.fma(columns[1], p.y, dr.fma(columns[0], p.x,
                                                                      columns[3])))
        if attached:  # the texture follows the sphere: local = W (p - c), both attached
            local = dr.replace_grad(local, _linear(columns, p - center))
        theta = dr.safe_acos(local.z)
        phi = dr.atan2(local.y, local.x)
        phi = dr.select(phi < 0.0, phi + 2.0 * dr.pi, phi)
        return t, p, n, mi.Point2f(phi * dr.inv_two_pi, theta * dr.inv_pi)

    def sphere_normal(self, row, p, center, sphere):
        """(The outward unit normal at the point ``p`` of the sphere of row ``row``, centred
        at ``center``: from the centre, or an ellipsoid's W^T W (p - c) for its
        world-to-object transform W; the ellipsoids' columns of W, or None)."""
        n = mi.Normal3f(dr.normalize(p - center))
        if not self.has_ellipsoids:
            return n, None
        ellipsoid = sphere & dr.gather(mi.Bool, self.ellipsoid, row, sphere)
        columns = self.to_object_columns(row, sphere)
        local = _linear(columns, p) + columns[3]
        normal = mi.Vector3f(*(dr.dot(columns[i], local) for i in range(3)))  # W^T local
        return dr.select(ellipsoid, mi.Normal3f(dr.normalize(normal)), n), columns

    def surface_key(self, si, active):
        """UInt32: which part of its shape each lane hit, for its path signature
        (signature.py): on a flat-shaded mesh its face's normal, to 2^-20 (the faces of one
        plane, coplanar, are one surface; a crease between two faces is not), elsewhere
        the primitive (a smooth mesh's face, a sphere set's sphere)."""
        key = mi.UInt32(si.prim_index)
        if not self.has_meshes:
            return key
        valid, kind, _ = self.entries(dr.reinterpret_array(mi.UInt32, si.shape), active)
        flat = valid & ((kind & MESH) != 0) & ((kind & SMOOTH) == 0)
        # (to 2^-20: the normals of coplanar faces differ in their last bits)
        x, y, z = (mi.UInt32(mi.Int32(dr.round(dr.detach(c) * 1048576.0))) for c in si.n)
        normal = (x * 0x9E3779B1) ^ (y * 0x85EBCA77) ^ (z * 0xC2B2AE3D)
        return dr.select(flat, normal, key)

    def normal_at(self, si, p, active):
        """The shading normal of each lane's hit surface (``si``'s shape and primitive) at
        ``p``, a point of the hit's tangent plane near ``si.p`` (ray differentials, see
        differentials.py): a sphere's or ellipsoid's from its centre, a smooth mesh's face's
        vertex normals interpolated at p's barycentrics, a flat face's own (``si.n``)."""
        shape_id = dr.reinterpret_array(mi.UInt32, si.shape)
        valid, kind, row = self.entries(shape_id, active)
        n = mi.Normal3f(si.n)
        if self.has_smooth:
            smooth = valid & ((kind & MESH) != 0) & ((kind & SMOOTH) != 0)
            vertex, corners = self.corners(row, si.prim_index, smooth)
            b1, b2 = barycentrics(corners, p)
            n0, n1, n2 = (dr.gather(mi.Vector3f, self.normals, v, smooth) for v in vertex)
            interpolated = dr.fma(n2, b2, dr.fma(n1, b1, n0 * (1.0 - b1 - b2)))
            n = dr.select(smooth, mi.Normal3f(dr.normalize(interpolated)), n)
        if self.has_spheres:
            sphere = valid & ((kind & SPHERE) != 0)
            sphere_row = row + si.prim_index
            center = dr.gather(mi.Point3f, self.center, sphere_row, sphere)
            n = dr.select(sphere, self.sphere_normal(sphere_row, p, center, sphere)[0], n)
        return n


def _linear(columns, v):
    """The linear part of a 3 x 4 transform (its ``columns``) applied to ``v``."""
    return dr.fma(columns[2], v.z, dr.fma(columns[1], v.y, columns[0] * v.x))
