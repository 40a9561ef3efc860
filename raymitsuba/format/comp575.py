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
from itertools import compress, count
from operator import and_, eq, itemgetter, not_
from typing import Dict, List, Optional, Tuple

from raymitsuba.format import bulk
from raymitsuba.format import commands as C
from raymitsuba.format.builder import KNOWN_LINES, SceneBuilder, make_material, make_object
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

#: The token count of each fixed-operand command's line, from the table (lower case keys).
_NTOKS_GET = {name.lower(): 1 + len(command.operands)
              for name, command in C.COMP575_COMMANDS.items()}.get
#: The bulk path's object commands carried out in place (planes carry the checker state and
#: go to their handler).
_SOLIDS = frozenset({"sphere", "cylinder", "cone"})
_TRANSFORMS = frozenset({"scale", "rotatex", "rotatey", "rotatez"})
_HEAD = itemgetter(0)
#: What :func:`_read_lines` makes of a line without tokens, and of a line that is not simple.
#: (Shaped as a simple line's reading, with a command word no line has: the hot loop of
#: :meth:`Comp575Parser._carry_out` tells them apart only after the hot commands.)
_BLANK = ("(blank)", None, None)
_EXACT = ("(exact)", None, None)


def _read_lines(texts: List[str]) -> list:
    """How the bulk path reads each line of ``texts``: :data:`_BLANK` (no tokens),
    (command word in lower case, tokens, operands as floats) for a *simple* line, else
    :data:`_EXACT`.

    A line is simple when it is ASCII (``str.split`` then splits on exactly spaces and tabs,
    as the exact path), its command word is a fixed-operand command's, its token count that
    command's (:data:`raymitsuba.format.commands.COMP575_COMMANDS`), and every operand a
    finite float literal, read to the bits ``float`` reads
    (:func:`raymitsuba.format.bulk.operands`). A ``#`` comment never passes: ``#`` is in no
    command word and no number.

    The work is done for all the lines at once, in C loops (``map`` of ``str.split``, of
    ``str.lower``, :func:`~raymitsuba.format.bulk.operands`); only a bad number sends the
    lines through a loop of their own, which finds it. (Numbers too large to sum also do:
    the sum proves them finite.)
    """
    split = list(map(str.split, texts))
    words = list(filter(None, split))
    keys = list(map(str.lower, map(_HEAD, words)))
    simple = list(map(eq, map(len, words), map(_NTOKS_GET, keys)))
    if not all(map(str.isascii, texts)):
        ascii_ = compress(map(str.isascii, texts), split)
        simple = list(map(and_, simple, ascii_))
    values = bulk.operands(list(compress(words, simple)))
    if values is not None and len(words) == len(texts) and all(simple):
        return list(zip(keys, words, values))  # the common case: every line simple
    if values is None:  # a bad number: each line's own reading (None: it holds one)
        values = list(map(bulk.finite_operands, compress(words, simple)))
    read = zip(compress(keys, simple), compress(words, simple), values)
    read = (None if r[2] is None else r for r in read)
    simple_of = iter(simple)
    out = []
    for toks, text in zip(split, texts):
        if not toks:  # (str.split splits on Unicode spaces too; the exact path does not)
            out.append(_BLANK if text.isascii() else _EXACT)
        elif next(simple_of):
            out.append(next(read) or _EXACT)
        else:
            out.append(_EXACT)
    return out


def _transform(key: str, composite: Matrix4, v: Tuple[float, ...]):
    """(the composite, its magnitude) after the transform line ``key`` (scale or rotate,
    operands ``v``) on ``composite``; None when the handler must report (a zero scale, an
    unusable composite)."""
    if key == "scale":
        if 0.0 in v:
            return None
        pushed = scaled(composite, *v)
    else:
        pushed = rotated(composite, key[-1], v[0])
    magnitude = magnitude_if_usable(pushed)
    return None if magnitude is None else (pushed, magnitude)


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
        # the largest |entry| of each composite; None until asked for (see _magnitude)
        self.stack_magnitude: List[Optional[float]] = [1.0]
        self.suggestions: Dict[str, str] = {}
        self.corners: Dict[Vec3, Vec3] = {}  # each distinct triangle corner, once (see _triangle)
        self._ln = 0
        self._line = ""
        self._known: Dict[str, object] = {}  # the bulk path's readings, by line text
        self._from_identity: Dict[str, Tuple[Matrix4, float]] = {}  # transform lines' composites
        # the handlers as functions of the class, called with self: a table of bound methods
        # would make the parser a cycle, its scene kept until a full collection
        cls = type(self)
        handlers = {
            "eye": cls._camera_vector, "lookat": cls._camera_vector, "up": cls._camera_vector,
            "fov": cls._fov, "background": cls._background,
            "sphere": cls._primitive, "plane": cls._primitive,
            "cylinder": cls._primitive, "cone": cls._primitive, "triangle": cls._triangle,
            "light": cls._light,
            "translate": cls._translate, "scale": cls._scale,
            "rotatex": cls._rotate, "rotatey": cls._rotate, "rotatez": cls._rotate,
            "reset": cls._reset, "pop": cls._pop,
            "material": cls._material, "texture": cls._texture,
            "checkerboard": cls._checkerboard,
        }
        self._handlers = {key: (_CANONICAL[key], fn) for key, fn in handlers.items()}

    # ---- driving -----------------------------------------------------------------

    #: Whether :meth:`run` takes the bulk path for runs of simple lines (the tests compare it
    #: with the line-by-line path, ``fast_path = False``).
    fast_path = True

    def run(self, lines: List[str]) -> Scene:
        """The scene of the decoded ``lines`` (see :func:`raymitsuba.format.lexer.decode`).

        The bulk path (:attr:`fast_path`): the lines are read in chunks of
        :data:`~raymitsuba.format.bulk.CHUNK`; a chunk's distinct lines not seen before are
        read at once (:func:`_read_lines`), each line's reading is remembered by its text
        (:attr:`_known`, a generated scene repeats its ``pop``, ``sphere`` and ``scale``
        lines), and :meth:`_carry_out` carries the chunk out. A line that is not *simple*
        goes to :meth:`_run_line`, the exact path, and so does a simple line of a command
        whose checks could report something. Both paths give the same scene, the same
        diagnostics.
        """
        if not self.fast_path:
            for ln, line in enumerate(lines, 1):
                self._run_line(ln, line)
            return self._finish()
        known = self._known
        for start in range(0, len(lines), bulk.CHUNK):
            chunk = lines[start:start + bulk.CHUNK]
            found = list(map(known.get, chunk))
            if not all(found):  # a reading is never falsy: None is a line not seen before
                fresh = list(dict.fromkeys(compress(chunk, map(not_, found))))
                read = dict(zip(fresh, _read_lines(fresh)))
                if len(known) < KNOWN_LINES:
                    known.update(read)
                found = list(map(read.get, chunk, found))
            self._carry_out(lines, start + 1, found)
        return self._finish()

    def _run_line(self, ln: int, line: str) -> None:
        """The exact path: line ``ln`` (text ``line``), whatever it holds."""
        # lexer.line_tokens(line), inlined: this runs once per line the bulk path leaves
        ascii_ = line.isascii()
        toks = line.split() if ascii_ else line_tokens(line)
        if not toks:
            return
        if "#" in line:
            toks = before_comment(toks)
            if not toks:
                return
        self._ln, self._line, self._toks, self._ascii = ln, line, toks, ascii_
        entry = self._handlers.get(toks[0].lower())
        if entry is None:
            self._unknown_command()
        else:
            self._cmd, handler = entry
            handler(self)

    def _carry_out(self, lines: List[str], first: int, found: list) -> None:
        """Carry out lines ``first ...``, read as ``found`` (:func:`_read_lines`).

        A simple line of the hot commands (objects, transforms, ``pop``, ``material``) is
        carried out here when no check of the command could report anything (no `pop` on an
        empty stack, no zero scale, no transform that overflows or turns singular, no
        negative material value, no first object: its position is noted); any other simple
        line goes to its command's handler with its tokens (the handler reads them again),
        any other line to :meth:`_run_line`.
        """
        handlers = self._handlers
        stack, magnitudes = self.stack, self.stack_magnitude
        objects, materials = self.objects, self.materials
        append = objects.append
        from_identity = self._from_identity
        material_lines_get = self.material_lines.get
        for ln, (key, toks, v) in zip(count(first), found):
            # the hot commands, when they cannot report anything; else their handler
            if key == "pop":
                if len(stack) > 1:
                    del stack[-1], magnitudes[-1]
                    continue
            elif key in _SOLIDS:
                if self.first_object_at is not None:
                    append(make_object(_OBJECT_KINDS[key], stack[-1], len(materials) - 1, ln,
                                       self.texture, None, None))
                    continue
            elif key == "translate":
                # the linear part is unchanged, so is its determinant: only the translation
                # can turn the composite unusable (magnitude_if_usable, shortened)
                r0, r1, r2, last = stack[-1]
                x, y, z = r0[3] + v[0], r1[3] + v[1], r2[3] + v[2]
                total = x + y + z
                if total - total == 0.0:
                    r0, r1, r2 = (r0[0], r0[1], r0[2], x), (r1[0], r1[1], r1[2], y), \
                        (r2[0], r2[1], r2[2], z)
                    stack.append((r0, r1, r2, last))
                    magnitudes.append(None)  # only a triangle asks for it: _magnitude()
                    continue
            elif key == "scale" and len(stack) > 1:
                # scaled() then magnitude_if_usable(), inlined (the same products, the same
                # determinant); the magnitude is left to _magnitude(), as a translation's
                x, y, z = v
                r0, r1, r2, last = stack[-1]
                r0 = (r0[0] * x, r0[1] * x, r0[2] * x, r0[3] * x)
                r1 = (r1[0] * y, r1[1] * y, r1[2] * y, r1[3] * y)
                r2 = (r2[0] * z, r2[1] * z, r2[2] * z, r2[3] * z)
                total = sum(r0) + sum(r1) + sum(r2)
                if x != 0.0 and y != 0.0 and z != 0.0 and total - total == 0.0:
                    (a, b, c, _), (d, e, f, _), (g, h, i, _) = r0, r1, r2
                    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
                    if det != 0.0 and det - det == 0.0:
                        stack.append((r0, r1, r2, last))
                        magnitudes.append(None)
                        continue
            elif key in _TRANSFORMS:
                if len(stack) == 1:  # the same line on the identity: the same composite
                    line = lines[ln - 1]
                    pushed = from_identity.get(line)
                    if pushed is None:
                        pushed = _transform(key, IDENTITY, v)
                        if pushed is not None and len(from_identity) < KNOWN_LINES:
                            from_identity[line] = pushed
                else:
                    pushed = _transform(key, stack[-1], v)
                if pushed is not None:
                    stack.append(pushed[0])
                    magnitudes.append(pushed[1])
                    continue
            elif key == "material":
                line = lines[ln - 1]
                known = material_lines_get(line) or self._material_known(key, line, v)
                if known is not None:
                    materials.append(make_material(*known[0], len(materials), ln, known[1]))
                    continue
            elif key == "triangle":
                if self.first_object_at is not None and self._triangle_fast(v, ln):
                    continue
            elif toks is None:  # _BLANK or _EXACT
                if key == "(exact)":
                    self._run_line(ln, lines[ln - 1])
                continue
            self._ln, self._line, self._toks, self._ascii = ln, lines[ln - 1], toks, True
            self._cmd, handler = handlers[key]
            handler(self)

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

    def _magnitude(self) -> float:
        """The largest |entry| of the current composite (the bulk path's translations leave
        it to be computed here, when a triangle needs it)."""
        magnitude = self.stack_magnitude[-1]
        if magnitude is None:
            r0, r1, r2, _ = self.stack[-1]
            magnitude = self.stack_magnitude[-1] = max(map(abs, r0 + r1 + r2))
        return magnitude

    def _triangle_fast(self, values: Tuple[float, ...], ln: int) -> bool:
        """The bulk path's `triangle` (operands ``values``, finite) at line ``ln``, appended as
        :meth:`_triangle` would, and True, when it can report nothing (corners not collinear,
        no transform that could carry them out of range); else False, nothing done but the
        corners' interning (which :meth:`_triangle` repeats alike)."""
        corner = self.corners.setdefault
        p0, p1, p2 = values[0:3], values[3:6], values[6:9]
        p0, p1, p2 = corner(p0, p0), corner(p1, p1), corner(p2, p2)
        e1 = (p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2])
        e2 = (p2[0] - p0[0], p2[1] - p0[1], p2[2] - p0[2])
        n = cross(e1, e2)
        if n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0:
            return False
        if (len(self.stack) > 1
                and max(map(abs, values)) * self._magnitude() > _SAFE_MAGNITUDE ** 2):
            return False
        self.objects.append(make_object(ObjectKind.TRIANGLE, self.stack[-1],
                                        len(self.materials) - 1, ln, self.texture, None,
                                        (p0, p1, p2)))
        return True

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
                and max(map(abs, values)) * self._magnitude() > _SAFE_MAGNITUDE ** 2):
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
