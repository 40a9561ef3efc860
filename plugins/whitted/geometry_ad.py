"""Derivatives with respect to the geometry and the camera: how the parameter keys that move
shapes (``sphere1.center``, ``translate2.offset``, ``triangle1.v0``, ...) and the camera
(``camera.eye``, ``.lookat``, ``.up``, ``.fov``) reach the rays and the hits.

The integrator's tables hold the geometry as Mitsuba has it (``hits.HitTable``: the
spheres' centres and radii, the meshes' vertex positions; the sensor's rays): detached,
and exactly the numbers Embree traces. A :class:`GeometryAD` (set on the tracer,
``Tracer.geometry_ad``, by whoever owns the keys: ``raymitsuba.parameters``) attaches
the derivative of each key to them, as the linear map the key's change makes:

    g_attached = replace_grad(g, g + J (k - detach(k)))

with ``k`` the key's value (its gradient enabled), ``g`` the table's entries the key moves
and ``J = dg/dk`` (host numbers, computed by the key's owner). Its *value* is the table's,
bit for bit (the primal image does not change), its derivative ``J dk``. With the hits
re-intersected differentiably against the attached geometry (``HitTable.intersect``), the
hit distance, point, normal and shading follow the shapes: the *interior* derivative of
the image (what changes continuously at a fixed pixel sample). Edges that move (a
silhouette crossing a sample) are not part of it.

The camera (:class:`CameraAD`): each camera ray keeps Mitsuba's sensor's value; its
derivative is that of the ray built in Dr.Jit from the attached eye, look-at point, up
vector and field of view through the same point of the image plane:

    q = (d . x0, d . y0, 1) / (d . z0)          (d: the sensor's ray; x0, y0, z0: its frame)
    d(theta) = normalize(s (q_x x + q_y y) + z),  s = tan(fov / 2) / tan(fov0 / 2)
    o(theta) = eye

where (x, y, z) is Mitsuba's look-at frame (z = normalize(lookat - eye), x = normalize(up x
z), y = z x x) of the attached values, (x0, y0, z0) the same of the values at which the
sensor was built. s is the same ratio whether the fov is vertical (COMP 575) or horizontal
(MIT 6.837): at a fixed aspect both tangents scale alike.

**Cost.** A key is one lane; the rays and the table's rows it moves are many. In reverse
mode each of the key's components receives a sum over the lanes, one reduction (one
kernel) each; without care each such kernel would also compute, again, the whole lazy
derivative of the image with respect to the rays and the table, Embree's traversals
included (six times for a 3-vector key and a moving sphere). The attached rays and table
therefore pass through a :func:`joint`: an identity whose derivative, as it passes, is
scheduled for evaluation (``dr.schedule``), so the first reduction evaluates the
derivative with respect to every ray and row once, in one kernel, and the reductions read
it (a gradient step of ``translate2.offset`` and ``camera.eye`` at 256 x 192, k = 4: the
chunks' backward kernels 147 ms -> 25 ms). The camera's rays do the same before their
normalization, and their image-plane coordinates q are computed once, with the rays: each
component of the frame's sum then reads two arrays instead of making the rays again (the
reductions' kernels from 140-220 operations to 7).
"""

import copy

import drjit as dr
import mitsuba as mi
import numpy as np

from .arrays import jit_array


def key_delta(value):
    """``k - detach(k)`` per component of a key's value (a list of one-lane Floats): zero,
    with the key's derivative."""
    components = [value] if isinstance(value, mi.Float) else [value.x, value.y, value.z]
    return [c - dr.detach(c) for c in components]


def linear(jacobian, deltas):
    """sum_i J[:, i] delta_i as a Float of len(J) lanes (jacobian: float64 (n, m))."""
    out = None
    for i, delta in enumerate(deltas):
        column = jacobian[:, i]
        if not np.any(column):
            continue
        term = jit_array(mi.Float, column.astype(np.float32)) * delta
        out = term if out is None else out + term
    return out


class _Joint(dr.CustomOp):
    """The identity; its derivative is scheduled for evaluation as it passes (see the
    module docstring, "Cost")."""

    def eval(self, value):
        return value

    def forward(self):
        grad = self.grad_in("value")
        dr.schedule(grad)
        self.set_grad_out(grad)

    def backward(self):
        grad = self.grad_out()
        dr.schedule(grad)
        self.set_grad_in("value", grad)

    def name(self):
        return "joint"


def joint(value):
    """``value`` (a PyTree of Dr.Jit arrays), its derivative scheduled as it passes: the
    same value, bit for bit."""
    return dr.custom(_Joint, value) if dr.grad_enabled(value) else value


def look_at_frame(eye, lookat, up):
    """Mitsuba's look-at frame (x, y, z) of Dr.Jit or numpy vectors."""
    z = dr.normalize(lookat - eye)
    x = dr.normalize(dr.cross(up, z))
    return x, dr.cross(z, x), z


class CameraAD:
    """The camera's keys: ``values`` {field: Dr.Jit value} for the fields that are keys (eye,
    lookat, up: Point3f; fov: Float, degrees as written), ``start`` {field: numpy value} of
    all four at which the sensor was built (eye, lookat, up, fov as written)."""

    def __init__(self, values, start):
        self.values, self.start = values, start

    def attached(self):
        return any(dr.grad_enabled(v) for v in self.values.values())

    def rays(self, ray):
        """``ray`` (the sensor's camera rays) with the camera's derivative attached."""
        if not self.attached():
            return ray
        # (opaque: data, not constants of the kernels, which a fit would compile at each step)
        start = {k: mi.Vector3f(*(dr.opaque(mi.Float, float(v)) for v in self.start[k]))
                 for k in ("eye", "lookat", "up")}
        x0, y0, z0 = look_at_frame(start["eye"], start["lookat"], start["up"])
        d = ray.d
        q = mi.Vector2f(dr.dot(d, x0), dr.dot(d, y0)) / dr.dot(d, z0)
        dr.schedule(q)  # (read by the camera keys' sums: computed once, with the rays)
        vec = {k: mi.Vector3f(self.values[k]) if k in self.values else mi.Vector3f(start[k])
               for k in ("eye", "lookat", "up")}
        x, y, z = look_at_frame(vec["eye"], vec["lookat"], vec["up"])
        s = mi.Float(1.0)
        if "fov" in self.values:
            half = dr.deg2rad(self.values["fov"]) * 0.5
            s = dr.tan(half) / dr.opaque(mi.Float, float(np.tan(np.radians(self.start["fov"])
                                                                * 0.5)))
        direction = dr.normalize(joint(s * (q.x * x + q.y * y) + z))
        out = mi.Ray3f(ray)
        out.o, out.d = joint((dr.replace_grad(ray.o, mi.Point3f(vec["eye"])),
                              dr.replace_grad(ray.d, direction)))
        return out


class GeometryAD:
    """The keys that move shapes and the camera (see the module docstring).

    ``spheres``: {shape id: [(key value, J_center (3, m), J_radius (1, m), J_frame (9, m))]}
    (J_frame: of the linear part of its world-to-object transform, column by column: what
    turns its texture coordinates);
    ``meshes``: {shape id: [(key value, J_positions (3 V, m), J_normals (3 V, m) or None)]}
    (V the mesh's vertices; J_normals: a smooth mesh's vertex normals, None for a flat one);
    ``camera``: a CameraAD or None."""

    def __init__(self, spheres=None, meshes=None, camera=None):
        self.spheres = spheres or {}
        self.meshes = meshes or {}
        self.camera = camera

    def moves(self):
        """Whether some key of the geometry or of the camera has its gradient enabled."""
        return self.attached() or self.camera_moves()

    def attached(self):
        """Whether some key of the geometry has its gradient enabled."""
        return bool(self.moving_shapes())

    def moving_shapes(self):
        """The names (``Shape.id()``) of the shapes that some key with its gradient enabled
        moves."""
        return {name for shapes in (self.spheres, self.meshes)
                for name, entries in shapes.items()
                if any(dr.grad_enabled(v) for v, *_ in entries)}

    def camera_moves(self):
        """Whether some key of the camera has its gradient enabled."""
        return self.camera is not None and self.camera.attached()

    def camera_rays(self, ray):
        return ray if self.camera is None else self.camera.rays(ray)

    def table(self, table):
        """``table`` (a HitTable), or a copy whose geometry carries the keys' derivatives."""
        if not self.attached():
            return table
        rows = table.rows_by_name
        out = copy.copy(table)
        out.moving = True
        if self.spheres and table.has_spheres:
            count = dr.width(table.radius)
            center, radius = dr.zeros(mi.Point3f, count), dr.zeros(mi.Float, count)
            uv = table.to_object is not None  # (the frame is read for uv, see HitTable)
            frame = dr.zeros(mi.Float, dr.width(table.to_object)) if uv else None
            for name, entries in self.spheres.items():
                row = mi.UInt32(rows[name])
                for value, j_center, j_radius, j_frame in entries:
                    deltas = key_delta(value)
                    c = [linear(j_center[i:i + 1], deltas) for i in range(3)]
                    if any(t is not None for t in c):
                        c = mi.Point3f(*[mi.Float(0.0) if t is None else t for t in c])
                        dr.scatter_add(center, c, row)
                    r = linear(j_radius, deltas)
                    if r is not None:
                        dr.scatter_add(radius, r, row)
                    turned = linear(j_frame, deltas) if uv else None
                    if turned is not None:  # the row's first three columns (4 x 3 a row)
                        dr.scatter_add(frame, turned, dr.arange(mi.UInt32, 9) + 12 * rows[name])
            attached = (dr.replace_grad(table.center, table.center + center),
                        dr.replace_grad(table.radius, table.radius + radius))
            if uv:
                attached += (dr.replace_grad(table.to_object, table.to_object + frame),)
            out.center, out.radius, *to_object = joint(attached)
            out.to_object = to_object[0] if uv else table.to_object
        if self.meshes and table.has_meshes:
            offset = dr.zeros(mi.Float, dr.width(table.positions))
            turned = dr.zeros(mi.Float, dr.width(table.normals)) if table.has_smooth else None
            for name, entries in self.meshes.items():
                first = rows[name]
                for value, j_positions, j_normals in entries:
                    deltas = key_delta(value)
                    index = dr.arange(mi.UInt32, len(j_positions)) + 3 * first
                    moved = linear(j_positions, deltas)
                    if moved is not None:
                        dr.scatter_add(offset, moved, index)
                    normals = None if j_normals is None else linear(j_normals, deltas)
                    if normals is not None and turned is not None:
                        dr.scatter_add(turned, normals, index)
            out.positions = joint(dr.replace_grad(table.positions, table.positions + offset))
            if turned is not None:
                out.normals = joint(dr.replace_grad(table.normals, table.normals + turned))
        return out
