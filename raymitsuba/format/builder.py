"""The state both dialects' parsers thread through a file, and the commands they share.

:class:`SceneBuilder` holds the scene being built (camera, background, materials,
lights, objects, meshes), the diagnostics, and the handlers whose meaning is the
same in both dialects: the camera vectors, ``fov``, ``background``, ``light``, the
material checks. A dialect's parser (:mod:`raymitsuba.format.comp575`,
:mod:`raymitsuba.format.mit6837`) subclasses it, feeds it one command at a time and says
where the command's tokens are:

* ``self._toks``: the command's tokens as written (``_toks[0]`` the command word);
* ``self._cmd``: the command's canonical spelling;
* :meth:`_where` / :meth:`_where_end`: (line, column, line text) of token ``i`` /
  of the point just past the last token, for diagnostics.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import operator
from typing import Dict, List, Optional, Sequence, Tuple

from raymitsuba.format import commands as C
from raymitsuba.format.diagnostics import Diagnostics, fmt
from raymitsuba.format.geometry import cross, unit
from raymitsuba.model import (Camera, Light, LightKind, Material, SceneObject, Severity,
                              TriangleMesh, Vec3, maker)

#: A parallel test threshold for unit vectors: |u x d| below this counts as parallel.
_PARALLEL_EPS = 1e-12
_RGB = ("r", "g", "b")
_LIGHT_WORDS = {kind.value: kind for kind in LightKind}
#: Material operands for which a negative value draws a warning (n and eta are checked
#: as errors instead).
_WARN_NEGATIVE_MATERIAL = frozenset({"r", "g", "b", "ka", "kd", "ks", "kr", "kt"})


def number_problem(token: str) -> Optional[str]:
    """None if ``token`` is a finite float literal; otherwise a suffix explaining why not."""
    try:
        value = float(token)
    except ValueError:
        return ""
    if not token.isascii():
        return " (numbers are written in ASCII digits)"
    if math.isfinite(value):
        return None
    bare = token.lstrip("+-").lower()
    if bare.startswith(("nan", "inf")):
        return " (nan and infinity are not allowed)"
    return " (too large for a double)"


def either(words: Sequence[str]) -> str:
    """``a, b or c``."""
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " or " + words[-1]


_KINDS = {d: {k.value: k for k in kinds} for d, kinds in C.LIGHT_KINDS.items()}
_KIND_LISTS = {d: either(list(kinds)) for d, kinds in _KINDS.items()}


def _material_plan(command: C.Command):
    """(token positions of the color, (token position, operand) of each other operand)."""
    return (command.positions("color"),
            tuple((k, o) for k, o in enumerate(command.operands, 1) if o.field != "color"))


#: The plan of each dialect's material command, computed once.
_MATERIAL_PLANS = {C.MATERIAL_COMMAND[d]: _material_plan(C.command_table(d)[C.MATERIAL_COMMAND[d]])
                   for d in C.DIALECTS}

#: The most distinct lines whose reading a bulk path remembers: a bound on the memory a file
#: of distinct lines takes.
KNOWN_LINES = 1 << 13

#: Material and SceneObject built from all their fields, positionally (the bulk path's).
make_material = maker(Material)
make_object = maker(SceneObject)


def _fast_material_plan(command: C.Command):
    """What :meth:`SceneBuilder._material_known` reads from the table: (a getter of the color's
    values, a getter of Material's seven scalar fields' values in its field order, the index
    of the ior operand in that order, whether the file holds its reciprocal)."""
    by_field = {o.field: k for k, o in enumerate(command.operands)}
    scalars = Material.FIELDS[1:]
    assert len(scalars) == 7 and tuple(f.name for f in dataclasses.fields(Material)) == (
        Material.FIELDS + ("index", "line", "column")), "the fast material path needs updating"
    color = tuple(k - 1 for k in command.positions("color"))
    ior = command.operand_for("ior")[0]
    return (operator.itemgetter(*color), operator.itemgetter(*(by_field[f] for f in scalars)),
            scalars.index("ior"), ior.reciprocal)


FAST_MATERIAL_PLANS = {C.MATERIAL_COMMAND[d]: _fast_material_plan(
    C.command_table(d)[C.MATERIAL_COMMAND[d]]) for d in C.DIALECTS}


class SceneBuilder:
    """One pass over one input in one dialect (see the module docstring)."""

    dialect = ""  # set by subclasses
    table: Dict[str, C.Command] = {}

    def __init__(self, file: str, camera: Camera):
        self.file = file
        self.diag = Diagnostics(file)
        # camera: value and (line, column, text) of each camera command given
        self.default_camera = camera
        self.camera = {"eye": camera.eye, "lookat": camera.lookat, "up": camera.up,
                       "fov": camera.fov}
        self.camera_at: Dict[str, Tuple[int, int, str]] = {}
        self.background: Vec3 = (0.0, 0.0, 0.0)
        self.background_at: Optional[Tuple[int, int]] = None
        self.materials: List[Material] = [Material()]
        self.objects: List[SceneObject] = []
        self.meshes: List[TriangleMesh] = []
        self.lights: List[Light] = []
        self.first_object_at: Optional[Tuple[int, int, str]] = None  # for the no-light warning
        # the bulk paths' material lines: (fields, column) by line text (_material_known)
        self.material_lines: Dict[str, tuple] = {}
        self._names = {name: command.names for name, command in self.table.items()}
        self._toks: List[str] = []
        self._cmd = ""
        self._ascii = True  # every token of the current command is ASCII

    # ---- where tokens are (the dialect's parser says) -----------------------------

    def _where(self, index: int) -> Tuple[int, int, str]:
        raise NotImplementedError

    def _where_end(self) -> Tuple[int, int, str]:
        raise NotImplementedError

    # ---- diagnostics -------------------------------------------------------------

    def _error_tok(self, index: int, message: str) -> None:
        self.diag.error(*self._where(index)[:2], message, self._where(index)[2])

    def _warning_tok(self, index: int, message: str) -> None:
        ln, column, text = self._where(index)
        self.diag.warning(ln, column, message, text)

    def _error_end(self, message: str) -> None:
        ln, column, text = self._where_end()
        self.diag.error(ln, column, message, text)

    # ---- operands ----------------------------------------------------------------

    def _count_ok(self, names: Sequence[str], start: int = 1, what: Optional[str] = None) -> bool:
        """Check that exactly ``len(names)`` operands follow token ``start - 1``."""
        found = len(self._toks) - start
        if found == len(names):
            return True
        what = what or f"`{self._cmd}`"
        if not names:
            message = f"{what} takes no operands, found {found}"
        else:
            plural = "operand" if len(names) == 1 else "operands"
            message = f"{what} takes {len(names)} {plural} ({' '.join(names)}), found {found}"
        if found > len(names):
            self._error_tok(start + len(names), message)
        else:
            self._error_end(message)
        return False

    def _floats(self, names: Sequence[str], start: int = 1,
                what: Optional[str] = None) -> Optional[Tuple[float, ...]]:
        """Tokens ``start ...`` as finite floats named ``names``; None (reported) if any is not."""
        toks = self._toks[start:start + len(names)]
        try:
            values = tuple(map(float, toks))
        except ValueError:
            values = None
        else:
            total = sum(values)  # finite proves every value finite (an overflow only costs time)
            if total - total == 0.0 and (self._ascii or all(map(str.isascii, toks))):
                return values
        what = what or f"`{self._cmd}`"
        ok = True
        for i, (tok, name) in enumerate(zip(toks, names), start):
            problem = number_problem(tok)
            if problem is not None:
                self._error_tok(i, f"expected a number for `{name}` of {what}, "
                                   f"found `{tok}`{problem}")
                ok = False
        return values if ok else None

    def _operands(self) -> Optional[Tuple[float, ...]]:
        """All operands of a fixed-operand command, checked; None (reported) on error."""
        names = self._names[self._cmd]
        toks = self._toks
        if len(toks) != len(names) + 1:
            self._count_ok(names)
            return None
        try:  # the common case, inlined: every operand a finite ASCII float literal
            values = tuple(map(float, toks[1:]))
            total = sum(values)
            if total - total == 0.0 and self._ascii:
                return values
        except ValueError:
            pass
        return self._floats(names)

    def _warn_negative(self, names: Sequence[str], values: Sequence[float], start: int,
                       what: str, only: Optional[frozenset] = None) -> None:
        if min(values) >= 0:  # the common case, at C speed
            return
        for i, (name, value) in enumerate(zip(names, values)):
            if value < 0 and (only is None or name in only):
                self._warning_tok(start + i, f"negative `{name}` ({fmt(value)}) in {what}")

    # ---- camera and background ---------------------------------------------------

    def _note_camera(self, name: str) -> None:
        earlier = self.camera_at.get(name)
        if earlier is not None:
            self._warning_tok(0, f"`{name}` given again; this value replaces the one "
                                 f"on line {earlier[0]} (the last one wins)")
        self.camera_at[name] = self._where(0)

    def _camera_vector(self) -> None:
        name = self._cmd
        values = self._operands()
        if values is not None:
            self._note_camera(name)
            self.camera[name] = values

    def _fov(self) -> None:
        values = self._operands()
        if values is None:
            return
        (fov,) = values
        if not 0.0 < fov < 180.0:
            self._error_tok(1, f"`fov` must be strictly between 0 and 180 degrees, found {fmt(fov)}")
        self._note_camera("fov")
        self.camera["fov"] = fov

    def _background(self) -> None:
        values = self._operands()
        if values is None:
            return
        if self.background_at is not None:
            self._warning_tok(0, f"`background` given again; this value replaces the "
                                 f"one on line {self.background_at[0]} (the last one wins)")
        self._warn_negative(_RGB, values, 1, "`background`")
        self.background = values  # type: ignore[assignment]
        self.background_at = self._where(0)[:2]

    def _check_camera(self) -> Camera:
        """Whole-camera checks, reported at the last camera line involved."""
        eye, lookat, up = self.camera["eye"], self.camera["lookat"], self.camera["up"]
        at = self.camera_at

        def report(involved, message):
            lines = [at[n] for n in involved if n in at]
            ln, column, text = max(lines) if lines else (1, 1, "")
            self.diag.error(ln, column, message, text)

        if eye == lookat:
            report(("eye", "lookat"), f"the camera's `eye` and `lookat` are the same point "
                                      f"{fmt(eye)}, so it has no view direction")
        elif up == (0.0, 0.0, 0.0):
            report(("up",), "the camera's `up` is the zero vector")
        else:
            view = tuple(b - a for a, b in zip(eye, lookat))
            if not all(map(math.isfinite, view)):
                view = tuple(b / 2 - a / 2 for a, b in zip(eye, lookat))
            side = cross(unit(view), unit(up))  # type: ignore[arg-type]
            if math.sqrt(sum(c * c for c in side)) < _PARALLEL_EPS:
                report(("eye", "lookat", "up"),
                       f"the camera's `up` {fmt(up)} is parallel to its view direction "
                       f"{fmt(view)} (from `eye` to `lookat`)")
        line = max((ln for ln, _, _ in at.values()), default=None)
        return Camera(eye=eye, lookat=lookat, up=up, fov=self.camera["fov"], line=line,
                      fov_axis=self.default_camera.fov_axis)

    # ---- objects -----------------------------------------------------------------

    def _note_object(self) -> None:
        if self.first_object_at is None:
            self.first_object_at = self._where(0)

    # ---- lights ------------------------------------------------------------------

    def _light(self) -> None:
        toks = self._toks
        kinds = _KINDS[self.dialect]
        kind_list = _KIND_LISTS[self.dialect]
        # Where is the kind? The first token after `light` that is not a number.
        kind_at = 4
        if len(toks) < 5 or toks[4].lower() not in _LIGHT_WORDS:
            kind_at = next((i for i in range(1, len(toks))
                            if number_problem(toks[i]) is not None), None)
        if kind_at is not None and kind_at != 4 and toks[kind_at].lower() in _LIGHT_WORDS:
            self._error_tok(kind_at, f"`light` takes 3 color operands (r g b) before the kind "
                                     f"`{toks[kind_at]}`, found {kind_at - 1}")
            return
        if len(toks) < 5:
            self._error_end(f"`light` takes a color r g b and then a kind "
                            f"({kind_list}), found {len(toks) - 1} operands")
            return
        word = toks[4].lower()
        kind = kinds.get(word)
        color = self._floats(_RGB, 1, what="`light`")
        if kind is None:
            if word in _LIGHT_WORDS:
                self._error_tok(4, f"`{toks[4]}` lights are not part of the "
                                   f"{C.DIALECT_NAMES[self.dialect]} format; expected {kind_list}")
                return
            guess = difflib.get_close_matches(word, list(kinds), n=1, cutoff=0.5)
            hint = f"; did you mean `{guess[0]}`?" if guess else f"; expected {kind_list}"
            self._error_tok(4, f"unknown light kind `{toks[4]}`{hint}")
            return
        operands = C.LIGHT_OPERANDS[kind]
        names = tuple(o.name for o in operands)
        what = f"`light ... {kind.value}`"
        if not self._count_ok(names, start=C.LIGHT_KIND_START, what=what):
            return
        values = self._floats(names, start=C.LIGHT_KIND_START, what=what)
        if color is None or values is None:
            return
        self._warn_negative(_RGB, color, 1, "a light's color")
        position = direction = shape = None
        if kind is LightKind.POINT:
            position = values
        elif kind is LightKind.DIRECTIONAL:
            direction = values
            if direction == (0.0, 0.0, 0.0):
                self._error_tok(5, "a directional light's direction (x y z) "
                                   "must not be the zero vector")
        elif kind is LightKind.SPOT:
            position, direction, shape = values[0:3], values[3:6], values[6]
            if direction == (0.0, 0.0, 0.0):
                self._error_tok(8, "a spotlight's axis (x' y' z') must not be the zero vector")
            if shape < 0:
                self._error_tok(11, f"a spotlight's shape coefficient `s` must be "
                                    f">= 0, found {fmt(shape)}")
        ln, column, _ = self._where(0)
        self.lights.append(Light(kind=kind, color=color, index=len(self.lights) + 1,  # type: ignore[arg-type]
                                 line=ln, position=position, direction=direction,
                                 shape=shape, column=column))

    # ---- materials ---------------------------------------------------------------

    def _material(self) -> None:
        """``material`` (COMP 575) or ``surface`` (MIT 6.837): the table says which operand
        is which, and whether the file holds eta or its reciprocal."""
        values = self._operands()
        if values is None:
            return
        command = self.table[self._cmd]
        self._warn_negative(command.names, values, 1, f"`{self._cmd}`",
                            only=_WARN_NEGATIVE_MATERIAL)
        fields: Dict[str, object] = {}
        color_at, scalars = _MATERIAL_PLANS[self._cmd]
        for k, operand in scalars:
            value = values[k - 1]
            if operand.field == "phong_coeff" and value < 0:
                self._error_tok(k, f"the Phong coefficient `{operand.name}` must be >= 0, "
                                   f"found {fmt(value)}")
            elif operand.field == "ior" and value <= 0:
                what = "the ratio of indices of refraction" if operand.reciprocal \
                    else "the index of refraction"
                self._error_tok(k, f"{what} `{operand.name}` must be > 0, found {fmt(value)}")
                value = 1.0
            elif operand.reciprocal and not math.isfinite(operand.value(value)):
                self._error_tok(k, f"`{operand.name}` {fmt(value)} is too small: its reciprocal "
                                   f"is beyond the floating-point range")
                value = 1.0
            fields[operand.field] = operand.value(value)  # type: ignore[index]
        color = tuple(values[k - 1] for k in color_at)
        ln, column, _ = self._where(0)
        self.materials.append(Material(color, index=len(self.materials),  # type: ignore[arg-type]
                                       line=ln, column=column, **fields))  # type: ignore[arg-type]

    def _material_known(self, command: str, line: str, values: Tuple[float, ...]):
        """What the bulk paths need of the material line ``line`` of ``command`` (``material``
        or ``surface``; every operand a finite ASCII float, ``values``): (Material's fields
        but its index, line and column, in field order; the command's column), as
        :meth:`_material` would make them, when none of its checks can report anything (no
        operand negative, the ior operand > 0 and the parameter it gives finite); otherwise
        None (the caller runs :meth:`_material`, which reports). Remembered by the line's
        text, for :data:`KNOWN_LINES` lines: a generated scene repeats its materials."""
        if min(values) < 0.0:  # a warning (negative color or mix) or an error (n, eta)
            return None
        color_of, scalars_of, ior_at, reciprocal = FAST_MATERIAL_PLANS[command]
        scalars = scalars_of(values)
        ior = scalars[ior_at]
        if not ior > 0.0:
            return None
        if reciprocal:
            ior = 1.0 / ior
            if ior - ior != 0.0:  # its reciprocal overflows
                return None
            scalars = scalars[:ior_at] + (ior,) + scalars[ior_at + 1:]
        known = (color_of(values),) + scalars, len(line) - len(line.lstrip(" \t")) + 1
        if len(self.material_lines) < KNOWN_LINES:
            self.material_lines[line] = known
        return known

    # ---- the end -----------------------------------------------------------------

    def _finish_checks(self) -> Camera:
        """The whole-scene checks; the camera."""
        camera = self._check_camera()
        if (self.objects or self.meshes) and not self.lights and self.first_object_at:
            ln, column, text = self.first_object_at
            self.diag.add(Severity.WARNING, ln, column,
                          "the scene has objects but no light: it renders black except for "
                          "the background", text)
        return camera
