"""The geometry and camera keys as scene parameters: ``loaded.params["translate1.offset"]``.

The keys (:class:`~raymitsuba.format.commands.ParamKey`: ``camera.eye``, ``sphere2.radius``,
``translate1.offset``, ``triangle1.v0``, ``v7.position``, ...) are entries of
``loaded.params`` (Mitsuba's SceneParameters) like the material keys: read a value, set it,
``dr.enable_grad`` it, then ``params.update()``. Their node is a :class:`GeometryKeys`:

* **Values.** A key's value is a Dr.Jit value (Point3f for 3-vectors, Float for angles,
  radii and the fov), initially the numbers written in the file.
* **Moving the geometry** (``params.update()`` after a value changed): the file's text is
  rewritten with the keys' values (every digit), parsed again and translated again on the
  host (``translate.shape_geometry``: a transform key moves every object under it on the
  stack, as the parser composes them); each shape that changed is updated in Mitsuba (an
  analytic sphere's ``to_world``, a mesh's ``vertex_positions``; the camera's ``to_world``
  and field of view) and Mitsuba rebuilds Embree's acceleration structure; the integrator's
  tables follow (they are rebuilt when the shapes' buffers or the spheres' boxes change).
  How an object is represented never changes: the shapes are translated under the loaded
  camera, and the tessellated objects (cylinders, cones, spheres under non-uniform
  scales) keep the segment counts they were loaded with (``Options.segments``), so their
  meshes' vertices and normals move with the keys. A key that would move a plane (whose
  rings are laid out under the camera) or a sphere of the sphere set, or change what kind
  of shape stands for an object (an analytic sphere scaled unevenly), is refused
  (:class:`~raymitsuba.format.writeback.ParameterError`) before anything is changed.
* **Derivatives** (a key whose gradient is enabled): the Jacobian of every shape's geometry
  with respect to the key (analytic spheres: centre and radius; meshes: positions, and a
  tessellation's vertex normals) by
  central differences of the same host translation (exact for the keys on which the
  geometry depends affinely -- translations, scales, vertices, sphere centres and radii --,
  O(h^2) for rotation angles, h = 1e-2 degree; others h = 1e-2 max(1, |value|)), handed to the integrator as a
  ``geometry_ad.GeometryAD`` (which says how they reach the rays and the hits). Rebuilt at
  every update (a rotation's Jacobian, or a translation's under a rotation, depends on the
  other keys' values), but for the keys on which the geometry depends linearly (LINEAR:
  offsets, vertices, MIT 6.837 centres and radii), whose Jacobian depends on the rotations'
  and scales' values alone: theirs is kept while those stay (each costs two translations of
  the whole scene per component: a fit of a translate on a large scene would pay them at
  every step).

Not a parameter: ``checkerboard{n}.size`` (it moves checker lines only: an image whose
derivative is all in moving edges). A key that would move a fixed shape (see above) is in
``params`` but refused with the reason (:meth:`GeometryKeys.check`) when it changes or its
gradient is enabled.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Dict, Optional

import numpy as np

from raymitsuba.format.commands import ParamKey
from raymitsuba.format.keys import geometry_places
from raymitsuba.format.parser import parse_text
from raymitsuba.format.writeback import ParameterError, rewrite_scene, source_lines
from raymitsuba.translate import camera_geometry, shape_geometry, tessellation_segments

CAMERA_FIELDS = ("eye", "lookat", "up", "fov")
# the keys' fields on which the geometry depends linearly, with the rotations' and scales'
# values fixed (see the module docstring)
LINEAR = ("offset", "v0", "v1", "v2", "center", "radius", "position")
TURNING = ("angle", "factors")  # the fields their Jacobians depend on: rotations and scales
ANGLE_STEP = 1e-2  # degrees: the central difference of a rotation angle's Jacobian
STEP = 1e-2  # the central difference of the other keys, times max(1, |value|): exact for
# the affine ones whatever the step (float32 mesh positions: ~1e-5 relative)


class GeometryKeys:
    """The node of the geometry and camera keys in ``loaded.params`` (see the module
    docstring). ``data``: the .RAY text of ``loaded.model``."""

    def __init__(self, loaded, data):
        from raymitsuba.backend import mitsuba

        mi = mitsuba()
        self.loaded, self.data = loaded, data
        self.model = loaded.model
        # The tessellated objects keep their meshes' segment counts as loaded (their vertices
        # move with the keys; a mesh of other counts would be another shape)
        self.options = dataclasses.replace(
            loaded.options, segments=tessellation_segments(self.model, loaded.options))
        self.places = geometry_places(source_lines(data), self.model.dialect)
        self.written = {key: place.values for key, place in self.places.items()}  # as in the file
        self.shapes = shape_geometry(self.model, self.options)  # as Mitsuba has them now
        self.camera = camera_geometry(self.model, self.options)
        self._refusals: Dict[str, Optional[str]] = {}  # key -> why it cannot move (None: it can)
        self.values = {}  # key -> its Dr.Jit value
        self.state = {}  # the keys whose values differ from the file's, as the geometry has them
        for key in self.places:
            if ParamKey.parse(key).owner == "checkerboard":
                continue  # (see the module docstring)
            written = self.written[key]
            self.values[key] = mi.Point3f(*written) if len(written) == 3 else mi.Float(written[0])
        self._mitsuba = None  # the shapes' and the sensor's own parameters (mi.traverse)
        # key -> (the TURNING keys' values, its Jacobian at them), of the LINEAR keys
        self._linear_jacobians = {}

    @property
    def mitsuba(self):
        if self._mitsuba is None:
            from raymitsuba.backend import mitsuba

            self._mitsuba = mitsuba().traverse(self.loaded.scene)
        return self._mitsuba

    def check(self, key: str) -> None:
        """Raise ParameterError if ``key`` is not a parameter that can move (found once, by
        translating the scene with the key changed)."""
        if key not in self._refusals:
            self._refusals[key] = self._refusal(key)
        if self._refusals[key] is not None:
            place = self.places.get(key)
            at = "" if place is None else f"{self.model.file}:{place.line}:{place.column}: "
            raise ParameterError(f"{at}`{key}` cannot be a parameter: {self._refusals[key]}")

    # -- which keys -----------------------------------------------------------------------------
    def _refusal(self, key: str) -> Optional[str]:
        parsed = ParamKey.parse(key)
        if parsed.owner == "camera":
            return None
        if parsed.owner == "checkerboard" or key not in self.values:
            return ("the checker size moves checker lines only (an image that is piecewise "
                    "constant in it): no derivative without boundary terms")
        try:
            moved = self._moved(self._perturbed({key: self._shifted(key, 1.0)}))
        except ParameterError as e:
            return str(e)
        if not moved:
            return "it moves no object of the scene"
        return None

    def _shifted(self, key, step):
        written = self.written[key]
        return tuple(v + step for v in written) if len(written) > 1 else written[0] + step

    def _perturbed(self, values):
        """The shapes and camera of the model with ``values`` ({key: value}) written in."""
        data = rewrite_scene(self.data, self.model, values, exact=True)
        model = parse_text(data, self.model.dialect)
        # The shapes are translated under the loaded camera: the plane's rings and the
        # tessellations' segment counts follow the camera, and stay as loaded.
        shapes = shape_geometry(dataclasses.replace(model, camera=self.model.camera),
                                self.options)
        return shapes, camera_geometry(model, self.options)

    def _moved(self, geometry):
        """{shape id: its new geometry} of the shapes that differ from the current ones
        (ParameterError if one of them may not move)."""
        shapes, _ = geometry
        if shapes.keys() != self.shapes.keys():
            raise ParameterError("it changes which shapes stand for the objects")
        moved = {}
        for name, new in shapes.items():
            old = self.shapes[name]
            if old[0] != new[0]:
                raise ParameterError(f"it changes how `{name}` is represented")
            if old[0] == "fixed":
                if old != new and old[1] == "ellipsoids":
                    raise ParameterError(
                        f"it moves a sphere of `{name}`, the sphere set (a scene's many opaque "
                        "spheres as one shape, which does not move; load the scene with "
                        "--sphere-set 0 (sphere_set=0) to fit them)")
                if old != new:
                    raise ParameterError(f"it moves {_object(name)}, and a plane cannot move "
                                         "(its rings are laid out under the camera, as far as "
                                         "the horizon)")
                continue
            if old[0] == "sphere" and np.any(old[3] != new[3]):
                moved[name] = new
            elif old[0] == "mesh" and any(len(a) != len(b) or np.any(a != b)
                                          for a, b in zip(old[1:], new[1:])):
                if any(len(a) != len(b) for a, b in zip(old[1:], new[1:])):
                    raise ParameterError(f"it changes the mesh `{name}`")
                moved[name] = new
        return moved

    def register(self, params) -> None:
        """Add the keys to ``params`` (a SceneParameters), this object as their node."""
        params.hierarchy[self] = (None, 0)
        for key, value in self.values.items():
            params.properties[key] = (value, None, self, 0)

    # -- SceneParameters' node interface ------------------------------------------------------------
    def parameters_changed(self, keys=None) -> None:
        """Move the geometry to the keys' values; attach their derivatives (module docstring)."""
        import drjit as dr

        for value in self.values.values():  # data, not constants of the kernels: a fit
            dr.make_opaque(value)  # compiles them once, not at every step
        current = {key: _host(value) for key, value in self.values.items()}
        # (as float32, the precision the values are held in: a key set to its own value is
        # unchanged)
        changed = {key: v for key, v in current.items()
                   if not np.array_equal(np.float32(v), np.float32(_as_value(self.written[key])))}
        attached = [key for key, value in self.values.items() if dr.grad_enabled(value)]
        for key in set(changed) | set(attached):
            self.check(key)
        if changed != self.state:
            shapes, camera = self._perturbed(changed)
            moved = self._moved((shapes, camera))
            self._apply(moved, camera)
            self.shapes, self.camera = shapes, camera
        self.state = changed
        self.loaded.integrator.tracer.geometry_ad = self._geometry_ad(attached, changed) \
            if attached else None

    def _apply(self, moved, camera):
        """Set the moved shapes and the camera in Mitsuba, and let it update."""
        from raymitsuba.backend import mitsuba
        from raymitsuba.plugins.whitted.arrays import jit_array

        mi = mitsuba()
        params = self.mitsuba
        for name, new in moved.items():
            if new[0] == "sphere":
                params[f"{name}.to_world"] = _opaque(mi.Transform4f(mi.ScalarTransform4f(new[3])))
            else:
                params[f"{name}.vertex_positions"] = jit_array(mi.Float, new[1])
                if len(new) > 2:  # a tessellation's vertex normals
                    params[f"{name}.vertex_normals"] = jit_array(mi.Float, new[2])
        if any(not np.array_equal(a, b) for a, b in zip(camera[:3], self.camera[:3])) \
                or camera[3] != self.camera[3]:
            eye, lookat, up, fov = camera
            params["sensor.to_world"] = _opaque(mi.Transform4f().look_at(
                origin=mi.ScalarPoint3f(*eye), target=mi.ScalarPoint3f(*lookat),
                up=mi.ScalarVector3f(*up)))
            width, height = self.options.width, self.options.height
            params["sensor.x_fov"] = _opaque(mi.Float(float(np.degrees(
                2.0 * np.arctan(np.tan(np.radians(fov) / 2.0) * width / height)))))
        params.update()

    # -- derivatives ---------------------------------------------------------------------------------
    def _geometry_ad(self, attached, changed):
        from raymitsuba.plugins.whitted.geometry_ad import CameraAD, GeometryAD

        spheres, meshes, camera_values = {}, {}, {}
        for key in attached:
            parsed = ParamKey.parse(key)
            if parsed.owner == "camera":
                camera_values[parsed.field] = self.values[key]
                continue
            for name, (kind, jacobian) in self._jacobian(key, changed).items():
                if kind == "sphere":
                    spheres.setdefault(name, []).append((self.values[key], jacobian[:3],
                                                         jacobian[3:4], jacobian[4:]))
                else:  # (a tessellation's rows: its positions', then its normals')
                    count = len(self.shapes[name][1])
                    meshes.setdefault(name, []).append((self.values[key], jacobian[:count],
                                                        jacobian[count:] if len(jacobian) > count
                                                        else None))
        camera = None
        if camera_values:
            eye, lookat, up, _ = self.camera
            written_fov = self.model.camera.fov
            if "camera.fov" in self.values:
                written_fov = _host(self.values["camera.fov"])
            camera = CameraAD(camera_values, {"eye": eye, "lookat": lookat, "up": up,
                                              "fov": written_fov})
        return GeometryAD(spheres, meshes, camera)

    def _jacobian(self, key, changed):
        """{shape id: (kind, d geometry / d key (n, m) float64)} of the shapes the key moves,
        at the current values ``changed`` (central differences, see the module docstring; a
        LINEAR key's kept while the rotations' and scales' values stay).

        A component whose change alone would change how a shape is represented (one factor of
        a scale over an analytic sphere: the sphere would become an ellipsoid) is
        differentiated along the uniform direction (1, ..., 1) instead, each component taking
        1/m of it: the representation never changes, so a sphere only scales uniformly."""
        if ParamKey.parse(key).field in LINEAR:  # (see the module docstring)
            others = tuple(sorted((k, _as_tuple(v)) for k, v in changed.items()
                                  if ParamKey.parse(k).field in TURNING))
            kept = self._linear_jacobians.get(key)
            if kept is None or kept[0] != others:
                kept = (others, self._computed_jacobian(key, changed))
                self._linear_jacobians[key] = kept
            return kept[1]
        return self._computed_jacobian(key, changed)

    def _computed_jacobian(self, key, changed):
        value = _as_tuple(changed.get(key, _as_value(self.written[key])))
        h = ANGLE_STEP if ParamKey.parse(key).field == "angle" else \
            STEP * max(1.0, max(abs(v) for v in value))
        if ParamKey.parse(key).field == "factors":  # (a scale keeps its signs)
            h = min(h, 0.25 * min(abs(v) for v in value))
        m = len(value)
        directions = [np.eye(m)[i] for i in range(m)]
        try:
            columns = [self._derivative(key, changed, value, u, h) for u in directions]
        except KeyError:  # a shape changed representation (see the docstring)
            uniform = self._derivative(key, changed, value, np.ones(m), h)
            columns = [{name: d / m for name, d in uniform.items()} for _ in range(m)]
        out = {}
        for i, column in enumerate(columns):
            for name, d in column.items():
                out.setdefault(name, (self.shapes[name][0], np.zeros((len(d), m))))
                out[name][1][:, i] = d
        return out

    def _derivative(self, key, changed, value, u, h):
        """{shape id: d geometry / dt} of the moving shapes, for the key's value + t u
        (KeyError: a shape changes representation)."""
        sides = []
        for sign in (1.0, -1.0):
            shifted = tuple(float(v) for v in np.asarray(value) + sign * h * u)
            shapes, _ = self._perturbed(changed | {key: _as_value(shifted)})
            sides.append(shapes)
        out = {}
        for name, old in self.shapes.items():
            if old[0] == "fixed":
                continue
            plus, minus = sides[0][name], sides[1][name]
            if plus[0] != old[0] or minus[0] != old[0]:
                raise KeyError(name)
            d = (_flat(plus) - _flat(minus)) / (2.0 * h)
            if np.any(d):
                out[name] = d
        return out

def _opaque(value):
    """``value`` made data rather than a constant of the kernels (a fit that moves the camera
    or a sphere would otherwise compile its kernels again at every step)."""
    import drjit as dr

    dr.make_opaque(value)
    return value


def _object(name: str) -> str:
    """The object a shape id names, for a message: ``the plane of line 6`` for ``plane_6``
    (``translate.ShapeNames``: ``{kind}_{line}``, ``{kind}_{line}_{n}``), else the id."""
    match = re.fullmatch(r"([a-z]+)_(\d+)(?:_\d+)?", name)
    return f"the {match[1]} of line {match[2]}" if match else f"`{name}`"


def _flat(geometry):
    """A shape's geometry as one float64 vector (sphere: centre, radius, then the linear part
    of its world-to-object transform column by column, which its texture coordinates read;
    mesh: positions, then a tessellation's vertex normals)."""
    if geometry[0] == "sphere":
        to_object = np.linalg.inv(geometry[3][:3, :3])
        return np.concatenate([geometry[1], [geometry[2]], to_object.T.ravel()]).astype(np.float64)
    return np.concatenate(geometry[1:]).astype(np.float64)


def _host(value):
    """A key's Dr.Jit value as a float or a tuple of floats."""
    array = np.array(value.numpy(), dtype=np.float64).ravel()
    return float(array[0]) if array.size == 1 else tuple(float(v) for v in array)


def _as_value(written):
    return written[0] if len(written) == 1 else tuple(written)


def _as_tuple(value):
    return value if isinstance(value, tuple) else (value,)
