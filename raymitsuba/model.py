"""The scene model: what a .RAY file means, as typed, immutable values.

The parser (:mod:`raymitsuba.parser`) is the only producer of these values and
the single source of truth for every decision the format leaves to it
(defaults, the transform-stack order, which texture and checker state an
object carries). Later stages -- the translator, the checker's summary, the
fitting tools -- read this model and never parse the .RAY text again (writing
fitted numbers back edits the lines the model names, with the parser's own
lexical rules).

Every class is a frozen dataclass with ``__slots__``: immutable, compared and
hashed by value, and small (a large scene holds hundreds of thousands of them).

Conventions, decided here once:

* All vectors are tuples of Python floats. Points and directions of lights
  and of the camera are in **world space**; they are never transformed.
* ``SceneObject.to_world`` is the 4x4 object-to-world matrix, **row-major**, acting
  on column vectors: ``p_world = M @ (x, y, z, 1)``. With transforms
  T1 ... Tn on the stack (T1 the oldest) it is ``Tn @ ... @ T2 @ T1``
  ("earlier stack statements are applied first").
* ``Light.direction`` is the direction the light *travels* (from the light
  into the scene) for directional lights, and the axis of maximum brightness
  for spotlights. Neither is normalised here: the user's numbers are kept.
* Materials are numbered in file order; ``Scene.materials[0]`` is the default
  material in force before the first ``material`` line, so the first
  ``material`` line is number 1. Lights are numbered from 1 in file order.
* Source positions (``line``) are 1-based.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Optional, Tuple

Vec3 = Tuple[float, float, float]
Matrix4 = Tuple[Tuple[float, float, float, float], ...]

IDENTITY: Matrix4 = (
    (1.0, 0.0, 0.0, 0.0),
    (0.0, 1.0, 0.0, 0.0),
    (0.0, 0.0, 1.0, 0.0),
    (0.0, 0.0, 0.0, 1.0),
)


class Severity(str, enum.Enum):
    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True, slots=True)
class Diagnostic:
    """One problem found in the input, located at FILE:LINE:COLUMN (1-based)."""

    severity: Severity
    file: str
    line: int
    column: int
    message: str
    source_line: str = ""  # the offending line's text, without its line end

    def format(self) -> str:
        """``FILE:LINE:COLUMN: error: message``, the line quoted, a caret under the column."""
        head = f"{self.file}:{self.line}:{self.column}: {self.severity.value}: {self.message}"
        if not self.source_line:
            return head
        text = self.source_line.expandtabs(1)
        caret = " " * (max(self.column, 1) - 1) + "^"
        return f"{head}\n    {text}\n    {caret}"

    def __str__(self) -> str:
        return self.format()


class RayError(Exception):
    """The input is not a valid .RAY scene. Carries every error found (at least one)."""

    def __init__(self, diagnostics):
        self.diagnostics: Tuple[Diagnostic, ...] = tuple(diagnostics)
        super().__init__("\n".join(d.format() for d in self.diagnostics))

    @property
    def errors(self) -> Tuple[Diagnostic, ...]:
        return tuple(d for d in self.diagnostics if d.severity is Severity.ERROR)


@dataclass(frozen=True, slots=True)
class Camera:
    eye: Vec3 = (0.0, 0.0, 5.0)
    lookat: Vec3 = (0.0, 0.0, 0.0)
    up: Vec3 = (0.0, 1.0, 0.0)
    fov: float = 45.0  # vertical field of view, degrees, 0 < fov < 180
    line: Optional[int] = None  # line of the last camera command, None if all defaults


@dataclass(frozen=True, slots=True)
class Material:
    """``material r g b ka kd ks n kr kt eta``; see the format reference."""

    color: Vec3 = (1.0, 1.0, 1.0)
    ambient_mix: float = 1.0
    diffuse_mix: float = 1.0
    specular_mix: float = 0.0
    phong_coeff: float = 1.0
    reflectivity: float = 0.0
    refractivity: float = 0.0
    ior: float = 1.0
    index: int = 0  # 0 is the default material; the first `material` line is 1
    line: Optional[int] = None

    FIELDS = ("color", "ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
              "reflectivity", "refractivity", "ior")


class LightKind(str, enum.Enum):
    AMBIENT = "ambient"
    POINT = "point"
    DIRECTIONAL = "directional"
    SPOT = "spotlight"


@dataclass(frozen=True, slots=True)
class Light:
    kind: LightKind
    color: Vec3
    index: int  # 1-based, counting `light` lines in file order
    line: int
    position: Optional[Vec3] = None  # point and spotlight
    direction: Optional[Vec3] = None  # directional: direction of travel; spotlight: axis
    shape: Optional[float] = None  # spotlight exponent s >= 0


class ObjectKind(str, enum.Enum):
    SPHERE = "sphere"
    PLANE = "plane"
    CYLINDER = "cylinder"
    CONE = "cone"
    TRIANGLE = "triangle"


@dataclass(frozen=True, slots=True)
class Texture:
    """An image texture named by a `texture` line, checked readable at parse time."""

    path: str  # absolute path
    format: str  # detected from the file's contents: "exr", "png", "jpeg", "hdr", "pfm", "ppm", "bmp", "tga"


@dataclass(frozen=True, slots=True)
class SceneObject:
    kind: ObjectKind
    to_world: Matrix4
    material: int  # index into Scene.materials
    line: int
    texture: Optional[Texture] = None
    checker: Optional[float] = None  # checker square size; planes only; None when off
    vertices: Optional[Tuple[Vec3, Vec3, Vec3]] = None  # triangle corners, object space


@dataclass(frozen=True, slots=True)
class Scene:
    file: str  # the name used in diagnostics ("<string>" for text)
    camera: Camera = field(default_factory=Camera)
    background: Vec3 = (0.0, 0.0, 0.0)
    materials: Tuple[Material, ...] = (Material(),)
    objects: Tuple[SceneObject, ...] = ()
    lights: Tuple[Light, ...] = ()
    warnings: Tuple[Diagnostic, ...] = ()
