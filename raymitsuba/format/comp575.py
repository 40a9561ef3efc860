"""The COMP 575 dialect: one command per line, a transform stack, textures, checkerboards.

:class:`Comp575Parser` reads the decoded lines of a file one at a time (one command
per line, see :mod:`raymitsuba.format.lexer`) and builds a
:class:`~raymitsuba.model.Scene`. The commands' operands come from
:data:`raymitsuba.format.commands.COMP575_COMMANDS`; the commands shared with the MIT 6.837
dialect (camera, background, lights, materials) are handled by
:class:`~raymitsuba.format.builder.SceneBuilder`.

Work is linear in the size of the input: one pass over the lines, plain tuples, no
per-line NumPy. Columns of tokens are only computed when a diagnostic needs them.

The transform stack is kept as a list of *composites*: ``stack[k]`` is the
object-to-world matrix ``Tk @ ... @ T1`` of the first k transforms (``stack[0]`` is
the identity and is never popped), so a push is one matrix product, a pop is a list
pop, and an object simply takes ``stack[-1]``.
"""

from __future__ import annotations

import math
from typing import Dict, List, Optional, Tuple

from raymitsuba.format import commands as C
from raymitsuba.format.builder import SceneBuilder
from raymitsuba.format.diagnostics import did_you_mean
from raymitsuba.format.geometry import (apply, cross, magnitude_if_usable, rotated, scaled,
                                 translated)
from raymitsuba.format.lexer import COMP575, before_comment, line_tokens, spans
from raymitsuba.model import (IDENTITY, Camera, Matrix4, ObjectKind, Scene, SceneObject,
                              Texture, Vec3)
from raymitsuba.format.textures import TextureFiles

#: Below this, entries of a matrix times coordinates can never overflow a double.
_SAFE_MAGNITUDE = 1e150
_XYZ = ("x", "y", "z")
_OBJECT_KINDS = {kind.value: kind for kind in ObjectKind}
_CANONICAL = {name.lower(): name for name in C.COMMAND_NAMES[COMP575]}


class Comp575Parser(SceneBuilder):
    """One pass over the lines of one COMP 575 input.

    Handlers read the current line from ``self._ln`` (number), ``self._line`` (text),
    ``self._toks`` (tokens before any comment) and ``self._cmd`` (canonical name).
    """

    dialect = COMP575
    table = C.COMP575_COMMANDS

    def __init__(self, file: str, base_dir: Optional[str]):
        super().__init__(file, Camera())
        self.textures = TextureFiles(base_dir)
        self.texture: Optional[Texture] = None
        self.checker: Optional[float] = None
        self.stack: List[Matrix4] = [IDENTITY]  # composites, see the module docstring
        self.stack_magnitude: List[float] = [1.0]  # largest |entry| of each composite
        self.suggestions: Dict[str, str] = {}
        self.corners: Dict[Vec3, Vec3] = {}  # each distinct triangle corner, once (see _triangle)
        self._ln = 0
        self._line = ""
        handlers = {
            "eye": self._camera_vector, "lookat": self._camera_vector, "up": self._camera_vector,
            "fov": self._fov, "background": self._background,
            "sphere": self._primitive, "plane": self._primitive,
            "cylinder": self._primitive, "cone": self._primitive, "triangle": self._triangle,
            "light": self._light,
            "translate": self._translate, "scale": self._scale,
            "rotatex": self._rotate, "rotatey": self._rotate, "rotatez": self._rotate,
            "reset": self._reset, "pop": self._pop,
            "material": self._material, "texture": self._texture,
            "checkerboard": self._checkerboard,
        }
        self._handlers = {key: (_CANONICAL[key], fn) for key, fn in handlers.items()}

    # ---- driving -----------------------------------------------------------------

    def run(self, lines: List[str]) -> Scene:
        """The scene of the decoded ``lines`` (see :func:`raymitsuba.format.lexer.decode`)."""
        handlers = self._handlers
        for ln, line in enumerate(lines, 1):
            # lexer.line_tokens(line), inlined: this loop runs once per line of the input
            ascii_ = line.isascii()
            toks = line.split() if ascii_ else line_tokens(line)
            if not toks:
                continue
            if "#" in line:
                toks = before_comment(toks)
                if not toks:
                    continue
            self._ln, self._line, self._toks, self._ascii = ln, line, toks, ascii_
            entry = handlers.get(toks[0].lower())
            if entry is None:
                self._unknown_command()
            else:
                self._cmd, handler = entry
                handler()
        return self._finish()

    def _where(self, index: int) -> Tuple[int, int, str]:
        line = self._line
        if index == 0:  # the command is the line's first token
            return self._ln, len(line) - len(line.lstrip(" \t")) + 1, line
        return self._ln, spans(line)[index][0] + 1, line

    def _where_end(self) -> Tuple[int, int, str]:
        return self._ln, spans(self._line)[len(self._toks) - 1][1] + 1, self._line

    # ---- objects -----------------------------------------------------------------

    def _add(self, kind: ObjectKind, vertices=None) -> None:
        if self.first_object_at is None:
            self._note_object()
        material = len(self.materials) - 1
        checker = self.checker if kind is ObjectKind.PLANE else None
        # Positional: this runs once per object, and keyword arguments cost a third more.
        self.objects.append(SceneObject(kind, self.stack[-1], material, self._ln, self.texture,
                                        checker, vertices))

    def _primitive(self) -> None:
        if len(self._toks) != 1:
            self._count_ok(())  # reported; the object is still added, nothing depends on it
        self._add(_OBJECT_KINDS[self._cmd])

    def _triangle(self) -> None:
        values = self._operands()
        if values is None:
            return
        p0, p1, p2 = values[0:3], values[3:6], values[6:9]
        # A mesh's corners repeat: keep one tuple per distinct corner (a third of the memory
        # of a large mesh's model), equal values (0.0 and -0.0 are equal: a zero may change sign).
        corner = self.corners.setdefault
        p0, p1, p2 = corner(p0, p0), corner(p1, p1), corner(p2, p2)
        e1 = (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2])
        e2 = (p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2])
        n = cross(e1, e2)
        if n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0:
            self._warning_tok(0, "zero-area triangle: its corners are collinear "
                                 "(it will not be visible)")
        # Only a transform (not the identity at the bottom) can carry corners out of range.
        if (len(self.stack) > 1
                and max(map(abs, values)) * self.stack_magnitude[-1] > _SAFE_MAGNITUDE ** 2):
            corners = [apply(self.stack[-1], p) for p in (p0, p1, p2)]  # type: ignore[arg-type]
            if not all(math.isfinite(c) for p in corners for c in p):
                self._error_tok(0, "the current transform carries this triangle "
                                   "beyond the floating-point range")
        self._add(ObjectKind.TRIANGLE, vertices=(p0, p1, p2))

    # ---- the transform stack -----------------------------------------------------

    def _push(self, composite: Optional[Matrix4]) -> None:
        """Push the new ``composite`` (``T @ current``). None, after an error in the line,
        pushes a no-op so that later `pop` lines still match their pushes."""
        magnitude = None if composite is None else magnitude_if_usable(composite)
        if magnitude is None:
            if composite is not None:
                self._error_tok(0, f"`{self._cmd}` makes the transform overflow or "
                                   f"become singular in floating point")
            composite, magnitude = self.stack[-1], self.stack_magnitude[-1]
        self.stack.append(composite)
        self.stack_magnitude.append(magnitude)

    def _translate(self) -> None:
        values = self._operands()
        self._push(None if values is None else translated(self.stack[-1], *values))

    def _scale(self) -> None:
        values = self._operands()
        if values is not None and 0.0 in values:
            for i, v in enumerate(values):
                if v == 0.0:
                    self._error_tok(1 + i, f"`scale` factor `{_XYZ[i]}` is zero; "
                                           f"a scale must be invertible")
            values = None
        self._push(None if values is None else scaled(self.stack[-1], *values))

    def _rotate(self) -> None:
        values = self._operands()
        axis = self._cmd[-1].lower()
        self._push(None if values is None else rotated(self.stack[-1], axis, values[0]))

    def _reset(self) -> None:
        if len(self._toks) != 1:
            self._count_ok(())
        del self.stack[1:], self.stack_magnitude[1:]

    def _pop(self) -> None:
        if len(self._toks) != 1:
            self._count_ok(())
        if len(self.stack) == 1:
            self._error_tok(0, "`pop` on an empty transform stack "
                               "(nothing has been pushed since the start or `reset`)")
            return
        self.stack.pop()
        self.stack_magnitude.pop()

    # ---- texture, checkerboard ---------------------------------------------------

    def _checkerboard(self) -> None:
        values = self._operands()
        if values is not None:
            self.checker = values[0] if values[0] > 0 else None

    def _texture(self) -> None:
        parsed = self._filename()
        if parsed is None:
            self.texture = None
            return
        name, column, quoted = parsed
        if not quoted and name.lower() == "none":
            self.texture = None
            return
        loaded = self.textures.load(name)
        if isinstance(loaded, Texture):
            self.texture = loaded
        else:
            self.diag.error(self._ln, column, loaded, self._line)
            self.texture = None

    def _filename(self) -> Optional[Tuple[str, int, bool]]:
        """(filename, its 1-based column, was it quoted) of the current line; None if bad."""
        line = self._line
        start = line.find(self._toks[0]) + len(self._toks[0])
        rest = line[start:]
        body = rest.lstrip(" \t")
        column = start + (len(rest) - len(body)) + 1
        if body.startswith('"'):
            close = body.find('"', 1)
            if close < 0:
                self.diag.error(self._ln, column,
                                "unterminated quoted filename: the closing `\"` is missing", line)
                return None
            after = body[close + 1:].lstrip(" \t")
            if after and not after.startswith("#"):
                self.diag.error(self._ln, column + len(body) - len(after),
                                f"unexpected text `{after.split()[0]}` after the quoted filename",
                                line)
                return None
            name = body[1:close]
            if not name:
                self.diag.error(self._ln, column, "the quoted filename is empty", line)
                return None
            return name, column, True
        words = self._toks[1:]
        if not words:
            self._error_end("`texture` takes a filename (or `none`), found nothing")
            return None
        last = spans(line)[len(self._toks) - 1][1]
        return line[column - 1:last], column, False

    # ---- unknown commands --------------------------------------------------------

    def _unknown_command(self) -> None:
        word = self._toks[0]
        key = word.lower()
        hint = self.suggestions.get(key)
        if hint is None:
            guess = did_you_mean(key, C.COMMAND_NAMES[COMP575])
            hint = (f"; did you mean `{guess}`?" if guess
                    else "; the commands are " + ", ".join(C.COMMAND_NAMES[COMP575]))
            self.suggestions[key] = hint
        self._error_tok(0, f"unknown command `{word}`{hint}")

    # ---- the end -----------------------------------------------------------------

    def _finish(self) -> Scene:
        camera = self._finish_checks()
        warnings = self.diag.result()
        return Scene(file=self.file, camera=camera, background=self.background,
                     materials=tuple(self.materials), objects=tuple(self.objects),
                     lights=tuple(self.lights), warnings=warnings, dialect=COMP575,
                     background_at=self.background_at)
