"""``raylight``: one .RAY light, evaluated by the Whitted integrator.

Lights live in world space and are never transformed. A light of color I
contributes at a surface point p (see the format reference):

* ``ambient``: I everywhere, unshadowed (the integrator multiplies it by ka C);
* ``point``: I from ``position``, **no distance falloff**;
* ``directional``: I from the direction ``-direction`` (``direction`` is the
  direction the light *travels*), from infinitely far away;
* ``spotlight``: I (cos a)^s from ``position`` where cos a > 0 and 0 elsewhere,
  a being the angle between ``direction`` (the axis of maximum brightness) and
  the direction from the light to p.

The integrator asks :meth:`Light.illuminate` for the unit direction from p
toward the light, the distance to it (infinite for a directional light) and the
intensity arriving; it then traces the shadow ray itself. This is not a
radiometric emitter: Mitsuba's own integrators cannot use it.

Parameters (exposed by ``mi.traverse``; all differentiable):

* ``kind`` (string, not a parameter): ambient | point | directional | spotlight
* ``color`` (Color3f): I
* ``position`` (Point3f): point and spotlight
* ``direction`` (Vector3f): directional and spotlight; need not be unit length
* ``shape_coefficient`` (float, >= 0): the spotlight's exponent s
* ``index`` (int, not a parameter): the light's number in file order, the j of its key
  ``light{j}``; it keeps equal lights distinct (see ``rayphong``'s ``index``)
"""

import drjit as dr
import mitsuba as mi

from raymitsuba.model import LightKind

KINDS = tuple(kind.value for kind in LightKind)  # ambient, point, directional, spotlight
PARAMETERS = ("color", "position", "direction", "shape_coefficient")


class Light(mi.Emitter):
    def __init__(self, props):
        super().__init__(props)
        self.kind = props.get("kind", "point")
        self.index = int(props.get("index", 0))
        if self.kind not in KINDS:
            raise ValueError(f"raylight: unknown kind {self.kind!r}")
        self.color = mi.Color3f(props.get("color", mi.ScalarColor3f(1.0)))
        if self.kind in ("point", "spotlight"):
            self.position = mi.Point3f(props.get("position", mi.ScalarPoint3f(0.0)))
        if self.kind in ("directional", "spotlight"):
            self.direction = mi.Vector3f(props.get("direction", mi.ScalarVector3f(0, 0, -1)))
        if self.kind == "spotlight":
            self.shape_coefficient = mi.Float(props.get("shape_coefficient", 1.0))
        self.m_flags = mi.EmitterFlags.Empty if self.is_ambient else mi.EmitterFlags.DeltaPosition
        self.parameters_changed([])

    @property
    def is_ambient(self):
        return self.kind == "ambient"

    def illuminate(self, p):
        """(wi, dist, intensity): unit world direction p -> light, distance, arriving color."""
        if self.kind == "directional":
            wi = -dr.normalize(self.direction)
            return wi, mi.Float(dr.inf), mi.Color3f(self.color)
        to_light = self.position - p
        dist = dr.norm(to_light)
        wi = to_light / dist
        if self.kind == "point":
            return wi, dist, mi.Color3f(self.color)
        cos_a = dr.dot(dr.normalize(self.direction), -wi)
        falloff = dr.power(dr.maximum(cos_a, 1e-30), self.shape_coefficient)
        return wi, dist, self.color * dr.select(cos_a > 0, falloff, 0.0)

    def traverse(self, callback):
        for name in PARAMETERS:
            if hasattr(self, name):
                callback.put(name, getattr(self, name), mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys):
        # Opaque: a new value must not become a new constant in the kernels (see phong.py).
        dr.make_opaque(*(getattr(self, name) for name in PARAMETERS if hasattr(self, name)))

    def to_string(self):
        return f"Light[kind={self.kind}, color={self.color}]"
