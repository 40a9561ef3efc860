"""The commands of both .RAY dialects, as one table each, and the parameter keys.

Every fact about a command is written here once: its canonical spelling, its
operands' names (as error messages show them) and, for the operands that hold a
fittable parameter, which parameter each one feeds and in which component. The
parser reads its operand counts and names from here, ``fit`` finds the tokens to
rewrite from here, ``check``'s summary and the format reference name the dialects
from here.

Token positions: operand ``k`` of a command (0-based) is token ``k + 1`` of the
command (token 0 is the command word). A light is ``light r g b KIND ...``: its
color is tokens 1-3, its kind token 4, the kind's operands tokens 5 on
(:data:`LIGHT_KIND_START`).

Parameter keys name one fittable value of a scene: ``mat{i}.{field}`` (materials
numbered in file order, ``mat0`` the default), ``light{j}.{field}`` (lights from 1)
and ``background.color``. :class:`ParamKey` is their one parser.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Dict, Optional, Tuple

from raymitsuba.format.lexer import COMP575, MIT6837
from raymitsuba.model import LightKind

DIALECTS = (COMP575, MIT6837)
DIALECT_NAMES = {COMP575: "COMP 575", MIT6837: "MIT 6.837"}


@dataclass(frozen=True)
class Operand:
    """One numeric operand: its name in messages and the parameter it feeds, if any."""

    name: str
    field: Optional[str] = None  # the model/parameter field ("color", "ior", ...)
    component: int = 0  # component of a vector field
    reciprocal: bool = False  # the file holds 1 / the parameter (MIT 6.837's `index`)

    def value(self, written: float) -> float:
        """The parameter value of the number ``written`` in the file."""
        return 1.0 / written if self.reciprocal else written

    def written(self, value: float) -> float:
        """The number to write in the file for the parameter value ``value``."""
        return 1.0 / value if self.reciprocal else value


@dataclass(frozen=True)
class Command:
    """A command with a fixed list of numeric operands (``light`` and ``texture`` aside)."""

    name: str  # canonical spelling
    operands: Tuple[Operand, ...] = ()
    meaning: str = ""
    names: Tuple[str, ...] = field(init=False, repr=False, compare=False)  # operand names

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(o.name for o in self.operands))

    def positions(self, field: str) -> Tuple[int, ...]:
        """Token positions of the operands that feed ``field``, in component order."""
        return tuple(k + 1 for k, o in enumerate(self.operands) if o.field == field)

    def operand_for(self, field: str) -> Tuple[Operand, ...]:
        return tuple(o for o in self.operands if o.field == field)


def _plain(*names: str) -> Tuple[Operand, ...]:
    return tuple(Operand(n) for n in names)


def _vector(field: str, *names: str) -> Tuple[Operand, ...]:
    return tuple(Operand(n, field, i) for i, n in enumerate(names))


_XYZ = ("x", "y", "z")
_RGB = ("r", "g", "b")
_COLOR = _vector("color", *_RGB)
_PHONG = (Operand("ka", "ambient_mix"), Operand("kd", "diffuse_mix"),
          Operand("ks", "specular_mix"))


def _table(*commands: Command) -> Dict[str, Command]:
    return {c.name: c for c in commands}


_EYE = _vector("eye", *_XYZ)
_LOOKAT = _vector("lookat", *_XYZ)
_UP = _vector("up", *_XYZ)
_CAMERA_575 = (
    Command("eye", _EYE, "position of the eye (default 0 0 5)"),
    Command("lookat", _LOOKAT, "a point the eye looks at (default 0 0 0)"),
    Command("up", _UP, "up direction (default 0 1 0)"),
    Command("fov", (Operand("theta", "fov"),), "vertical field of view in degrees (default 45)"),
)
_BACKGROUND = Command("background", _COLOR, "color of rays that hit nothing (default black)")

#: The COMP 575 dialect.
COMP575_COMMANDS: Dict[str, Command] = _table(
    *_CAMERA_575, _BACKGROUND,
    Command("sphere", (), "unit sphere at the origin"),
    Command("plane", (), "the plane y = 0"),
    Command("cylinder", (), "closed cylinder, axis y, radius 1, height 1"),
    Command("cone", (), "closed cone, axis y, base radius 1, height 1"),
    Command("triangle", _vector("v0", "x0", "y0", "z0") + _vector("v1", "x1", "y1", "z1")
            + _vector("v2", "x2", "y2", "z2"), "triangle with these corners"),
    Command("translate", _vector("offset", *_XYZ), "push a translation"),
    Command("scale", _vector("factors", *_XYZ), "push a scale"),
    Command("rotateX", (Operand("theta", "angle"),), "push a rotation about x, degrees"),
    Command("rotateY", (Operand("theta", "angle"),), "push a rotation about y, degrees"),
    Command("rotateZ", (Operand("theta", "angle"),), "push a rotation about z, degrees"),
    Command("reset", (), "empty the transform stack"),
    Command("pop", (), "remove the last transform"),
    Command("material", _COLOR + _PHONG + (
        Operand("n", "phong_coeff"), Operand("kr", "reflectivity"),
        Operand("kt", "refractivity"), Operand("eta", "ior")),
        "material of the objects that follow"),
    Command("checkerboard", (Operand("size", "size"),),
            "checker the planes that follow (<= 0: off)"),
)

#: The MIT 6.837 dialect.
MIT6837_COMMANDS: Dict[str, Command] = _table(
    Command("eye", _EYE, "position of the eye (default 0 0 10)"),
    Command("lookat", _LOOKAT, "a point the eye looks at (default 0 0 0)"),
    Command("up", _UP, "up direction (default 0 1 0)"),
    Command("fov", (Operand("theta", "fov"),), "horizontal field of view in degrees (default 30)"),
    Command("viewport", _plain("width", "height"), "image size in pixels (default 512 512)"),
    _BACKGROUND,
    Command("surface", _COLOR + _PHONG + (
        Operand("ns", "phong_coeff"), Operand("kr", "reflectivity"),
        Operand("kt", "refractivity"), Operand("index", "ior", reciprocal=True)),
        "material of the objects that follow; index = n_outside / n_inside"),
    Command("sphere", _vector("center", "cx", "cy", "cz") + (Operand("r", "radius"),),
            "sphere of centre (cx, cy, cz), radius r"),
    Command("triangles", (), "open a triangle mesh block"),
    Command("v", _vector("position", *_XYZ), "a vertex of the open block, numbered from 0"),
    Command("f", (), "a face: 3 or more vertex indices, fanned from the first"),
    Command("end", (), "close the mesh block"),
)

def command_table(dialect: str) -> Dict[str, Command]:
    """The table of commands of ``dialect``."""
    return MIT6837_COMMANDS if dialect == MIT6837 else COMP575_COMMANDS


#: The material command of each dialect (its operands feed ``mat{i}.*``).
MATERIAL_COMMAND = {COMP575: "material", MIT6837: "surface"}

#: Commands of later programs built on the MIT 6.837 code (not part of its format).
LATER_6837_COMMANDS = ("cube", "torus", "obj", "quads", "q", "rotation", "bumpmap", "texture",
                       "backgroundcubemap", "cylinder")

#: Every command of each dialect, canonical spelling (``light`` and COMP 575's ``texture``
#: have operands of their own shape).
COMMAND_NAMES = {
    COMP575: tuple(COMP575_COMMANDS) + ("light", "texture"),
    MIT6837: tuple(MIT6837_COMMANDS) + ("light",),
}

#: The light kinds each dialect has.
LIGHT_KINDS = {COMP575: tuple(LightKind), MIT6837: (LightKind.AMBIENT, LightKind.POINT,
                                                    LightKind.DIRECTIONAL)}
LIGHT_COLOR: Tuple[Operand, ...] = _COLOR
LIGHT_KIND_START = 5  # token position of a light kind's first operand
LIGHT_OPERANDS: Dict[LightKind, Tuple[Operand, ...]] = {
    LightKind.AMBIENT: (),
    LightKind.POINT: _vector("position", *_XYZ),
    LightKind.DIRECTIONAL: _vector("direction", *_XYZ),
    LightKind.SPOT: _vector("position", *_XYZ) + _vector("direction", "x'", "y'", "z'")
    + (Operand("s", "shape_coefficient"),),
}


def light_positions(kind: LightKind, field: str) -> Tuple[int, ...]:
    """Token positions of the operands of a ``light ... KIND`` line that feed ``field``."""
    if field == "color":
        return (1, 2, 3)
    return tuple(LIGHT_KIND_START + k for k, o in enumerate(LIGHT_OPERANDS[kind])
                 if o.field == field)


def light_fields(kind: LightKind) -> Tuple[str, ...]:
    """The fittable fields of a light of ``kind``, color first."""
    fields = ["color"]
    for o in LIGHT_OPERANDS[kind]:
        if o.field not in fields:
            fields.append(o.field)  # type: ignore[arg-type]
    return tuple(fields)


# -- parameter keys --------------------------------------------------------------------------
#: The commands whose operands are parameters of the geometry or the camera, by dialect: a
#: key ``{command}{n}.{field}`` names the fields of the n-th line of that command (from 1,
#: counted over the whole file), the fields being the operands' ``field`` in the table.
GEOMETRY_COMMANDS = {
    COMP575: ("translate", "scale", "rotateX", "rotateY", "rotateZ", "triangle", "checkerboard"),
    MIT6837: ("sphere", "v"),
}
#: The camera's commands: ``camera.{field}`` names the operands of the last such line (the
#: one in effect).
CAMERA_COMMANDS = ("eye", "lookat", "up", "fov")

_OWNERS = "|".join(sorted({c for cs in GEOMETRY_COMMANDS.values() for c in cs}, key=len,
                          reverse=True))
_KEY = re.compile(rf"(?:(mat|light|{_OWNERS})(\d+)|(background|camera))\.([a-z_0-9]+)")


def geometry_fields(command: str, dialect: str) -> Tuple[str, ...]:
    """The fields of a geometry (or camera) command, in operand order."""
    fields: list = []
    for o in command_table(dialect)[command].operands:
        if o.field is not None and o.field not in fields:
            fields.append(o.field)
    return tuple(fields)


@dataclass(frozen=True)
class ParamKey:
    """A parameter key: ``mat3.color`` is ParamKey("mat", 3, "color").

    The keys, decided here (the translator gives the Mitsuba objects of materials, lights and
    the background these ids, so they are also the keys of ``mi.traverse``): ``mat{i}.{field}``
    with i the material's number in file order (``mat0``: the default material; MIT 6.837
    ``surface`` commands count alike) and field one of ``Material.FIELDS``;
    ``light{j}.{field}`` with j counting ``light`` lines from 1 and field one of
    :func:`light_fields` of its kind (color, position, direction, shape_coefficient);
    ``background.color``.

    The geometry and the camera (:data:`GEOMETRY_COMMANDS`, :data:`CAMERA_COMMANDS`):
    ``camera.eye``, ``camera.lookat``, ``camera.up`` (3-vectors) and ``camera.fov`` (degrees as
    written: COMP 575 vertical, MIT 6.837 horizontal), each of the last line of its command;
    ``{command}{n}.{field}``, n counting that command's lines in the file from 1: COMP 575
    ``translate{n}.offset``, ``scale{n}.factors``, ``rotateX{n}.angle`` (also Y, Z; degrees),
    ``triangle{n}.v0`` / ``.v1`` / ``.v2``, ``checkerboard{n}.size``; MIT 6.837
    ``sphere{n}.center``, ``sphere{n}.radius``, ``v{n}.position`` (n counting ``v`` lines over
    the whole file, across mesh blocks)."""

    owner: str  # "mat", "light", "background", "camera" or a geometry command
    index: Optional[int]  # None for the background and the camera
    field: str

    @classmethod
    def parse(cls, key: str) -> "ParamKey":
        """The key ``key`` parsed; ValueError if it is not of the form above."""
        m = _KEY.fullmatch(key)
        if m is None:
            raise ValueError(f"`{key}` is not a parameter key (mat<i>.<field>, light<j>.<field>, "
                             f"background.color, camera.<field> or <command><n>.<field>)")
        owner, number, single, field = m.groups()
        if single:
            return cls(single, None, field)
        return cls(owner, int(number), field)

    @property
    def is_geometry(self) -> bool:
        """Whether the key names a number of the geometry or of the camera."""
        return self.owner not in ("mat", "light", "background")

    def __str__(self) -> str:
        head = self.owner if self.index is None else f"{self.owner}{self.index}"
        return f"{head}.{self.field}"
