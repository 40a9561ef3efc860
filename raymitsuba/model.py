"""The scene model: what a .RAY file means, as typed, immutable values.

The parser (:mod:`raymitsuba.format.parser`) is the only producer of these values and
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
* Source positions (``line``, ``column``) are 1-based. ``Material.column``,
  ``Light.column`` and ``Scene.background_at`` locate the command word, so that
  fitted numbers can be written back (a MIT 6.837 line may hold several commands).
* The camera's ``fov`` is the angle the file gives, about the axis it names
  (``fov_axis``: "y", vertical, in COMP 575; "x", horizontal, in MIT 6.837). The
  vertical angle the renderer needs depends on the image's aspect, so it is
  computed when the image size is known, by :meth:`Camera.vertical_fov` -- the one
  place that convention is decided.
* A MIT 6.837 triangle mesh block is held in bulk (:class:`TriangleMesh`, one per
  run of faces under one surface), not as one object per face.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, fields
from typing import Callable, Optional, Tuple

Vec3 = Tuple[float, float, float]
Matrix4 = Tuple[Tuple[float, float, float, float], ...]

#: The image size, decided here once: a side left unset is the MIT 6.837 ``viewport``'s,
#: else DEFAULT_IMAGE_SIZE (:meth:`Scene.image_size`); no side is larger than MAX_IMAGE_SIZE
#: (the viewport's bound in the parser, the options' range).
DEFAULT_IMAGE_SIZE = 512
MAX_IMAGE_SIZE = 16384

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
    fov: float = 45.0  # field of view, degrees, 0 < fov < 180, about fov_axis
    line: Optional[int] = None  # line of the last camera command, None if all defaults
    fov_axis: str = "y"  # "y": fov is vertical (COMP 575); "x": horizontal (MIT 6.837)

    def vertical_fov(self, width: int, height: int) -> float:
        """The vertical field of view in degrees of a ``width`` x ``height`` image:
        tan(v/2) = tan(fov/2) * height / width for a horizontal fov."""
        if self.fov_axis == "y":
            return self.fov
        half = math.tan(math.radians(self.fov) / 2.0) * height / width
        return math.degrees(2.0 * math.atan(half))


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
    index: int = 0  # 0 is the default material; the first `material` (MIT 6.837: `surface`) line is 1
    line: Optional[int] = None
    column: Optional[int] = None  # of the command word (`material` or `surface`)

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
    column: Optional[int] = None  # of the `light` word


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
class TriangleMesh:
    """Triangles of one MIT 6.837 mesh block under one surface, in world space.

    ``vertices`` is the block's whole vertex list (shared by the block's meshes);
    ``faces`` are (i, j, k) indices into it, a face's front side being
    (p_j - p_i) x (p_k - p_i). Faces of more than three vertices are already fanned.
    """

    vertices: Tuple[Vec3, ...]
    faces: Tuple[Tuple[int, int, int], ...]
    material: int  # index into Scene.materials
    line: int  # line of the run's first face
    block_line: int  # line of the block's `triangles`


@dataclass(frozen=True, slots=True)
class Scene:
    file: str  # the name used in diagnostics ("<string>" for text)
    camera: Camera = field(default_factory=Camera)
    background: Vec3 = (0.0, 0.0, 0.0)
    materials: Tuple[Material, ...] = (Material(),)
    objects: Tuple[SceneObject, ...] = ()
    lights: Tuple[Light, ...] = ()
    warnings: Tuple[Diagnostic, ...] = ()
    dialect: str = "comp575"  # "comp575" or "mit6837"
    meshes: Tuple[TriangleMesh, ...] = ()
    viewport: Optional[Tuple[int, int]] = None  # (width, height): MIT 6.837 `viewport`
    background_at: Optional[Tuple[int, int]] = None  # (line, column) of the last `background`

    @property
    def triangle_count(self) -> int:
        """Triangles of the mesh blocks."""
        return sum(len(m.faces) for m in self.meshes)

    def image_size(self, width: Optional[int] = None, height: Optional[int] = None):
        """(width, height) of the image: each given size, else the viewport's, else 512."""
        default = self.viewport or (DEFAULT_IMAGE_SIZE, DEFAULT_IMAGE_SIZE)
        return (int(width) if width else default[0], int(height) if height else default[1])


def maker(cls: type) -> Callable[..., object]:
    """A function building a ``cls`` from every one of its fields, positionally, in field order.

    For the parser's bulk path (a large scene builds hundreds of thousands of records): a
    frozen dataclass's ``__init__`` sets each field through ``object.__setattr__``, by name;
    this sets the slots directly, about twice as fast. The instance is the one ``__init__``
    makes (same slots, same values: equal, same hash); no default is filled in and nothing is
    checked, so it is only for the model's classes, which have no ``__post_init__``.
    """
    names = [f.name for f in fields(cls)]
    if "__post_init__" in vars(cls) or "__slots__" not in vars(cls):
        raise TypeError(f"maker() needs a slotted dataclass without __post_init__, not {cls}")
    scope = {"_new": object.__new__, "_cls": cls}
    scope.update({f"_set_{n}": vars(cls)[n].__set__ for n in names})
    body = "".join(f"    _set_{n}(o, {n})\n" for n in names)
    exec(f"def make({', '.join(names)}):\n    o = _new(_cls)\n{body}    return o\n", scope)
    make = scope["make"]
    make.__doc__ = f"A {cls.__name__} of every field, positionally (see model.maker)."
    return make
