"""The MIT 6.837 dialect: a free stream of tokens, spheres with operands, mesh blocks.

:class:`Mit6837Parser` reads the token stream of a file (:func:`raymitsuba.format.lexer.stream_6837`:
``#`` and ``/`` comments, operands across line breaks) and builds the same
:class:`~raymitsuba.model.Scene` as the COMP 575 parser:

* a command's operands are the tokens after it up to the next command: a token that
  is a command word of either dialect, or a non-number that starts a line (so a
  misspelt command on its own line is reported as one, not as an operand);
* ``sphere cx cy cz r`` is a unit sphere under the similarity transform
  translate(c) scale(r), so that it renders as Mitsuba's analytic sphere;
* ``surface`` is COMP 575's ``material`` with the last operand n_outside / n_inside
  (eta = 1 / index), :data:`raymitsuba.format.commands.MIT6837_COMMANDS` says so;
* a ``triangles`` ... ``end`` block becomes one :class:`~raymitsuba.model.TriangleMesh`
  per run of faces under one surface; faces are fanned from their first index;
  a fan triangle with a repeated index has no area: it is skipped (the face's others are
  kept, so ``f 1 2 3 1`` is the triangle 1 2 3) and counted in one warning;
* the camera's ``fov`` is horizontal (``Camera.fov_axis == "x"``), default 30, the
  eye defaults to 0 0 10, and ``viewport w h`` is the default image size.

A bulk path carries out the simple ``v``, ``f``, ``sphere`` and ``surface`` lines of a large
file without the token stream, in chunks (:meth:`Mit6837Parser.run`); it gives the same
scene and diagnostics as the stream alone (``fast_path = False``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import compress
from typing import List, Optional, Tuple

from raymitsuba.format import bulk
from raymitsuba.format import commands as C
from raymitsuba.format.builder import SceneBuilder, make_material, make_object, number_problem
from raymitsuba.format.diagnostics import did_you_mean, fmt
from raymitsuba.format.geometry import magnitude_if_usable, similarity
from raymitsuba.format.lexer import COMP575, MIT6837, Token, stream_6837
from raymitsuba.model import (MAX_IMAGE_SIZE, Camera, ObjectKind, Scene, SceneObject,
                              TriangleMesh, Vec3)

#: The MIT 6.837 camera defaults (fov horizontal).
CAMERA = Camera(eye=(0.0, 0.0, 10.0), fov=30.0, fov_axis="x")

_NAMES = C.COMMAND_NAMES[MIT6837]
_CANONICAL = {name.lower(): name for name in _NAMES}
_COMP575_ONLY = {n.lower(): n for n in C.COMMAND_NAMES[COMP575] if n.lower() not in _CANONICAL}
_LATER = {n.lower() for n in C.LATER_6837_COMMANDS}
#: Words that always start a command (never an operand).
_COMMAND_WORDS = frozenset(_CANONICAL) | frozenset(_COMP575_ONLY) | _LATER
_LIGHT_WORDS = frozenset({"ambient", "point", "directional", "spotlight"})
#: The MIT 6.837 command a user of a COMP 575 word probably meant.
_COUNTERPARTS = {"material": "surface", "triangle": "triangles"}
#: What a block may hold (a nested `triangles` has an error of its own).
_BLOCK_COMMANDS = frozenset({"v", "f", "surface", "end", "triangles"})


def _reads_as_float(text: str) -> bool:
    """Whether ``float()`` reads ``text`` (nan and inf included: they are bad operands,
    reported as such, not commands)."""
    try:
        float(text)
    except ValueError:
        return False
    return True


#: The bulk path's commands (their lines carried out in place, see Mit6837Parser.run), and
#: the token count of each line of theirs; ``f`` takes 3 or more indices.
_BULK_TOKENS = {"v": 4, "sphere": 5, "surface": 1 + len(C.MIT6837_COMMANDS["surface"].operands)}
#: A line's reading when it is not simple (see _read_lines).
_OTHER = (None, None, None)


def _read_lines(texts: List[str], after: Optional[str]) -> list:
    """How the bulk path reads each line of ``texts``, the next word after them (lower case)
    being ``after`` (None: none): (command word in lower case, tokens, operands as floats or
    None for ``f``) for a *self-contained simple* line, else :data:`_OTHER`.

    Simple: ASCII, no comment (``#`` or ``/``), a ``v``, ``sphere`` or ``surface`` of its
    token count (:data:`_BULK_TOKENS`) with finite float literals (the bits ``float``
    reads), or an ``f`` of 3 or more operands. Self-contained: the next line with tokens
    starts with a command word (or there is none), so the command takes no operand from
    below. A line's first token ``#`` or ``/`` is no command word: the line before it is
    left to the exact path, which reads the comment.
    """
    split = list(map(str.split, texts))
    # (a line of Unicode spaces: no tokens for str.split, a token for the stream: "")
    firsts = [toks[0].lower() if toks else (None if text.isascii() else "")
              for toks, text in zip(split, texts)]
    ends = []  # the first word of the next line with tokens, for each line
    following = after
    for word in reversed(firsts):
        ends.append(following)
        if word is not None:
            following = word
    ends.reverse()
    simple = [word in _BULK_TOKENS or word == "f" for word in firsts]
    simple = [s and (end is None or end in _COMMAND_WORDS) and "#" not in text
              and "/" not in text and text.isascii()
              and (len(toks) == _BULK_TOKENS[word] if word != "f" else len(toks) >= 4)
              for s, end, text, toks, word in zip(simple, ends, texts, split, firsts)]
    numeric = [s and word != "f" for s, word in zip(simple, firsts)]
    values = iter(bulk.each_operands(list(compress(split, numeric))))
    out = []
    for is_simple, is_numeric, word, toks in zip(simple, numeric, firsts, split):
        if not is_simple:
            out.append(_OTHER)
        elif is_numeric:
            v = next(values)
            out.append(_OTHER if v is None else (word, toks, v))
        else:
            out.append((word, toks, None))
    return out


def _next_word(lines: List[str], start: int) -> Optional[str]:
    """The first word (lower case) of the first line with tokens from index ``start`` on;
    None if there is none."""
    for index in range(start, len(lines)):  # (islice would walk the lines before start)
        toks = lines[index].split(None, 1)
        if toks:
            return toks[0].lower()
    return None


def _fan(indices: List[int]) -> List[Tuple[int, int, int]]:
    """The triangles of a face fanned from its first index: (i, j, k), (i, k, l), …."""
    i0 = indices[0]
    return [(i0, indices[k], indices[k + 1]) for k in range(1, len(indices) - 1)]


@dataclass
class _Block:
    """The open ``triangles`` block."""

    line: int
    column: int
    source: str
    vertices: List[Vec3] = field(default_factory=list)
    faces: List[Tuple[int, int, int]] = field(default_factory=list)
    runs: List[Tuple[int, int, int]] = field(default_factory=list)  # (first face, material, line)


class Mit6837Parser(SceneBuilder):
    """One pass over the token stream of one MIT 6.837 input."""

    dialect = MIT6837
    table = C.MIT6837_COMMANDS

    def __init__(self, file: str):
        super().__init__(file, CAMERA)
        self.lines: List[str] = []
        self.viewport: Optional[Tuple[int, int]] = None
        self.block: Optional[_Block] = None
        self.degenerate = 0
        self.first_degenerate: Optional[Tuple[int, int, str]] = None
        self._cur: List[Token] = []
        cls = type(self)  # functions, called with self: bound methods would make a cycle
        self._handlers = {
            "eye": cls._camera_vector, "lookat": cls._camera_vector, "up": cls._camera_vector,
            "fov": cls._fov, "viewport": cls._viewport, "background": cls._background,
            "light": cls._light, "surface": cls._surface, "sphere": cls._sphere,
            "triangles": cls._triangles, "v": cls._vertex, "f": cls._face, "end": cls._end,
        }

    # ---- driving -----------------------------------------------------------------

    #: Whether :meth:`run` takes the bulk path for simple lines (the tests compare it with the
    #: token stream's path, ``fast_path = False``).
    fast_path = True

    def run(self, lines: List[str]) -> Scene:
        """The scene of the decoded ``lines`` (see :func:`raymitsuba.format.lexer.decode`).

        The bulk path (:attr:`fast_path`): the lines are read in chunks of
        :data:`~raymitsuba.format.bulk.CHUNK` (:func:`_read_lines`); a *self-contained*
        simple line (a ``v``, ``f``, ``sphere`` or ``surface`` line whose command ends on
        it) is carried out by :meth:`_carry_out` where no check could report anything, and
        every other line, in runs, by the token stream's exact path (:meth:`_run_exact`). A
        run of other lines ends just before a simple line, whose first token starts a
        command: no command is cut in two. Both paths give the same scene, the same
        diagnostics.
        """
        self.lines = lines
        if not self.fast_path:
            self._run_exact(0, len(lines))
            return self._finish()
        pending = 0  # the first line (index) not carried out yet
        for start in range(0, len(lines), bulk.CHUNK):
            stop = min(start + bulk.CHUNK, len(lines))
            pending = self._carry_out(start, _read_lines(lines[start:stop],
                                                         _next_word(lines, stop)), pending)
        self._run_exact(pending, len(lines))
        return self._finish()

    def _run_exact(self, start: int, stop: int) -> None:
        """The token stream's path over the lines of index ``start`` .. ``stop`` - 1."""
        if start < stop:
            for command in self._commands(stream_6837(self.lines[start:stop], start + 1)):
                self._dispatch(command)

    def _carry_out(self, start: int, found: list, pending: int) -> int:
        """Carry out the lines of index ``start`` ..., read as ``found`` (:func:`_read_lines`),
        the lines from index ``pending`` on being left so far to the exact path; returns the
        first line left to it after them (a run of such lines goes on into the next chunk).

        Before a simple line, the lines left before it are run (its first token starts a
        command: no command is cut); then the line is carried out here when no check of its
        command could report anything (a ``v`` or ``f`` in an open block, indices defined,
        no degenerate fan triangle; a ``sphere`` outside a block with r > 0 and a usable
        transform; a ``surface`` that :meth:`_material_known` takes; never the first object:
        its position is noted there), else left to the exact path too."""
        objects, materials = self.objects, self.materials
        material_lines_get = self.material_lines.get
        for index, (key, toks, v) in enumerate(found, start):
            if key is None:  # not simple: left to the exact path, with the lines around it
                continue
            if pending < index:
                self._run_exact(pending, index)
                pending = index  # (this line too, unless it is carried out below)
            block = self.block
            if key == "v":
                if block is None:
                    continue
                block.vertices.append(v)
            elif key == "f":
                if block is None:
                    continue
                try:
                    indices = list(map(int, toks[1:]))  # (what int reads, float reads alike)
                except ValueError:
                    continue
                if not (min(indices) >= 0 and max(indices) < len(block.vertices)):
                    continue
                if len(indices) == 3:  # a triangle (_fan of it, at less cost)
                    i, j, k = indices
                    if i == j or j == k or i == k:  # degenerate: counted there
                        continue
                    fan = [(i, j, k)]
                else:
                    fan = _fan(indices)
                    if not all(len(set(t)) == 3 for t in fan):  # degenerate: counted there
                        continue
                first, material, line = block.runs[-1]
                if line == 0:  # the run's first face
                    if self.first_object_at is None:
                        continue
                    block.runs[-1] = (first, material, index + 1)
                block.faces.extend(fan)
            elif key == "sphere":
                if block is not None or self.first_object_at is None:
                    continue
                cx, cy, cz, r = v
                if not 0.0 < r * (r * r) < math.inf:  # r > 0, its transform usable
                    continue
                objects.append(make_object(ObjectKind.SPHERE, similarity((cx, cy, cz), r),
                                           len(materials) - 1, index + 1, None, None, None))
            else:  # surface
                line = self.lines[index]
                known = material_lines_get(line) or self._material_known(key, line, v)
                if known is None:
                    continue
                materials.append(make_material(*known[0], len(materials), index + 1, known[1]))
                if block is not None:
                    self._start_run()
            pending = index + 1
        return pending

    @staticmethod
    def _commands(tokens):
        """The token stream cut into commands (see the module docstring)."""
        current: List[Token] = []
        for tok in tokens:
            if current and (tok.text.lower() in _COMMAND_WORDS or (
                    tok.line != current[-1].line and tok.text.lower() not in _LIGHT_WORDS
                    and not _reads_as_float(tok.text))):
                yield current
                current = []
            current.append(tok)
        if current:
            yield current

    def _dispatch(self, command: List[Token]) -> None:
        self._cur = command
        self._toks = [t.text for t in command]
        self._ascii = all(t.isascii() for t in self._toks)
        word = self._toks[0].lower()
        handler = self._handlers.get(word)
        if handler is None:
            self._not_a_command(word)
            return
        self._cmd = _CANONICAL[word]
        if self.block is not None and word not in _BLOCK_COMMANDS:
            self._error_tok(0, f"`{self._cmd}` inside the `triangles` block of line "
                               f"{self.block.line}; a block holds only `v`, `f` and `surface` "
                               f"lines (close it with `end`)")
        handler(self)

    def _where(self, index: int) -> Tuple[int, int, str]:
        tok = self._cur[index]
        return tok.line, tok.start + 1, self.lines[tok.line - 1]

    def _where_end(self) -> Tuple[int, int, str]:
        tok = self._cur[-1]
        return tok.line, tok.end + 1, self.lines[tok.line - 1]

    def _not_a_command(self, word: str) -> None:
        written = self._toks[0]
        if word in _LATER and (word != "cylinder" or len(self._toks) > 1):
            what = "`cylinder` with operands" if word == "cylinder" else f"`{written}`"
            self._error_tok(0, f"{what} is not part of the MIT 6.837 format (a later program "
                               f"built on its code added it)")
        elif word in _COMP575_ONLY:
            hint = _COUNTERPARTS.get(word)
            self._error_tok(0, f"`{_COMP575_ONLY[word]}` is a COMP 575 command, not part of the "
                               f"MIT 6.837 format" + (f"; did you mean `{hint}`?" if hint else ""))
        elif number_problem(written) is None:
            self._error_tok(0, f"expected a command, found the number `{written}`")
        else:
            guess = did_you_mean(word, _NAMES)
            hint = (f"; did you mean `{guess}`?" if guess
                    else "; the MIT 6.837 commands are " + ", ".join(_NAMES))
            self._error_tok(0, f"unknown command `{written}`{hint}")

    # ---- camera ------------------------------------------------------------------

    def _viewport(self) -> None:
        values = self._operands()
        if values is None:
            return
        for k, (name, value) in enumerate(zip(("width", "height"), values), 1):
            if value != int(value) or not 1 <= value <= MAX_IMAGE_SIZE:
                self._error_tok(k, f"the viewport {name} must be a whole number of pixels from 1 "
                                   f"to {MAX_IMAGE_SIZE}, found {fmt(value)}")
                return
        if self.viewport is not None:
            self._warning_tok(0, "`viewport` given again; this value replaces the earlier one "
                                 "(the last one wins)")
        self.viewport = (int(values[0]), int(values[1]))

    # ---- surfaces and spheres ----------------------------------------------------

    def _surface(self) -> None:
        self._material()
        if self.block is not None:
            self._start_run()

    def _sphere(self) -> None:
        values = self._operands()
        if values is None:
            return
        cx, cy, cz, r = values
        if r <= 0:
            self._error_tok(4, f"a sphere's radius `r` must be > 0, found {fmt(r)}")
            return
        to_world = similarity((cx, cy, cz), r)
        if magnitude_if_usable(to_world) is None:  # as a COMP 575 transform is checked
            self._error_tok(4, f"a sphere's radius `r` of {fmt(r)} makes its transform overflow "
                               f"or become singular in floating point")
            return
        self._note_object()
        self.objects.append(SceneObject(ObjectKind.SPHERE, to_world, len(self.materials) - 1,
                                        self._cur[0].line))

    # ---- mesh blocks -------------------------------------------------------------

    def _triangles(self) -> None:
        self._count_ok(())
        if self.block is not None:
            self._error_tok(0, f"nested `triangles`: the block opened on line {self.block.line} "
                               f"is not closed (close it with `end` first)")
            return
        self.block = _Block(*self._where(0))
        self._start_run()

    def _start_run(self) -> None:
        block = self.block
        assert block is not None
        block.runs.append((len(block.faces), len(self.materials) - 1, 0))

    def _open_block(self) -> Optional[_Block]:
        if self.block is None:
            self._error_tok(0, f"`{self._cmd}` outside a mesh block (open one with `triangles`)")
        return self.block

    def _vertex(self) -> None:
        block = self._open_block()
        values = self._operands()
        if block is not None:
            block.vertices.append(values or (0.0, 0.0, 0.0))  # keeps the numbering after an error

    def _face(self) -> None:
        block = self._open_block()
        if block is None:
            return
        indices = [self._index(k, len(block.vertices)) for k in range(1, len(self._toks))]
        if len(indices) < 3:
            self._error_end(f"a face `f` takes 3 or more vertex indices, found {len(indices)}")
            return
        if None in indices:
            return
        fan = _fan(indices)  # type: ignore[arg-type]
        kept = [t for t in fan if len(set(t)) == 3]
        if len(kept) < len(fan):
            self.degenerate += len(fan) - len(kept)
            if self.first_degenerate is None:
                self.first_degenerate = self._where(0)
        if not kept:
            return
        first, run_material, line = block.runs[-1]
        if line == 0:  # the run's first face
            block.runs[-1] = (first, run_material, self._cur[0].line)
            self._note_object()
        block.faces.extend(kept)

    def _index(self, k: int, count: int) -> Optional[int]:
        """Token ``k`` as a vertex index of a block of ``count`` vertices; None (reported)."""
        tok = self._toks[k]
        problem = number_problem(tok)
        if problem is not None:
            self._error_tok(k, f"expected a vertex index for `f`, found `{tok}`{problem}")
            return None
        value = float(tok)
        if value != int(value):
            self._error_tok(k, f"a vertex index is a whole number, found `{tok}`")
        elif value < 0:
            self._error_tok(k, f"vertex indices start at 0, found `{tok}`")
        elif value >= count:
            defined = "none yet" if count == 0 else f"0 to {count - 1}"
            self._error_tok(k, f"vertex index {int(value)} is not defined in this block "
                               f"(defined so far: {defined})")
        else:
            return int(value)
        return None

    def _end(self) -> None:
        self._count_ok(())
        if self.block is None:
            self._error_tok(0, "`end` without an open `triangles` block")
            return
        self._close_block()

    def _close_block(self) -> None:
        block = self.block
        assert block is not None
        self.block = None
        vertices = tuple(block.vertices)
        ends = [first for first, _, _ in block.runs[1:]] + [len(block.faces)]
        for (first, material, line), stop in zip(block.runs, ends):
            if stop > first:
                self.meshes.append(TriangleMesh(vertices, tuple(block.faces[first:stop]),
                                                material, line, block.line))

    # ---- the end -----------------------------------------------------------------

    def _finish(self) -> Scene:
        if self.block is not None:
            self.diag.error(self.block.line, self.block.column,
                            "this `triangles` block is never closed with `end`", self.block.source)
            self._close_block()
        if self.degenerate:
            ln, column, text = self.first_degenerate  # type: ignore[misc]
            triangles = "triangle was" if self.degenerate == 1 else "triangles were"
            self.diag.warning(ln, column, f"{self.degenerate} degenerate fan {triangles} skipped "
                                          f"(a repeated vertex index); this is the first", text)
        camera = self._finish_checks()
        warnings = self.diag.result()
        return Scene(file=self.file, camera=camera, background=self.background,
                     materials=tuple(self.materials), objects=tuple(self.objects),
                     lights=tuple(self.lights), warnings=warnings, dialect=MIT6837,
                     meshes=tuple(self.meshes), viewport=self.viewport,
                     background_at=self.background_at)
