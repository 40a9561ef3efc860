"""The .RAY parser: text in, an immutable :class:`~raymitsuba.model.Scene` out.

Public entry points:

* :func:`parse_file` -- read a .RAY file;
* :func:`parse_text` -- parse a string (or bytes) already in memory;
* :func:`parse` -- either of the two, guessed from the argument;
* :data:`LINE_END` and :func:`token_spans` -- the lexical rules, for tools that edit
  .RAY text in place (``raymitsuba.fit`` writes fitted numbers back with them).

Every rule of the format is decided here and written down in ``docs/format.md``;
this module implements that page and nothing else. The contract with callers:

* The result is a :class:`Scene`, or a :class:`RayError` is raised carrying
  **every** error of the input (the parser carries on after a bad line) and the
  warnings. Nothing else escapes, whatever the input.
* Work is linear in the size of the input: one pass over the lines, plain
  tuples, no per-line NumPy, no quadratic bookkeeping. Columns of tokens are
  only computed when a diagnostic needs them.

Conventions, decided once:

* Lines are 1-based; columns are 1-based *characters* of the decoded line (a
  tab counts as one column). A diagnostic about a token points at its first
  character; one about a missing operand points just past the end of the
  line's last token (comments excluded).
* The transform stack is kept as a list of *composites*: ``stack[k]`` is the
  object-to-world matrix ``Tk @ ... @ T1`` of the first k transforms
  (``stack[0]`` is the identity and is never popped), so a push is one matrix
  product, a pop is a list pop, and an object simply takes ``stack[-1]`` (see
  :mod:`raymitsuba.model` for the matrix layout).
"""

from __future__ import annotations

import contextlib
import difflib
import functools
import gc
import math
import os
import re
import stat
from typing import Dict, Iterator, List, Optional, Sequence, Tuple, Union

from raymitsuba.model import (IDENTITY, Camera, Diagnostic, Light, LightKind, Material,
                              Matrix4, ObjectKind, RayError, Scene, SceneObject, Severity,
                              Texture, Vec3)

__all__ = ["parse", "parse_file", "parse_text", "token_spans", "COMMANDS", "LINE_END",
           "OPERANDS", "TEXTURE_FORMATS"]

PathOrText = Union[str, bytes, "os.PathLike[str]"]

# --------------------------------------------------------------------------------------
# The vocabulary
# --------------------------------------------------------------------------------------

#: Operand names of every command with a fixed list of numeric operands, keyed by the
#: canonical spelling (the one used in messages). ``light`` and ``texture`` are special.
_XYZ = ("x", "y", "z")
_RGB = ("r", "g", "b")
OPERANDS: Dict[str, Tuple[str, ...]] = {
    "eye": _XYZ, "lookat": _XYZ, "up": _XYZ, "fov": ("theta",),
    "background": _RGB,
    "sphere": (), "plane": (), "cylinder": (), "cone": (),
    "triangle": ("x0", "y0", "z0", "x1", "y1", "z1", "x2", "y2", "z2"),
    "translate": _XYZ, "scale": _XYZ,
    "rotateX": ("theta",), "rotateY": ("theta",), "rotateZ": ("theta",),
    "reset": (), "pop": (),
    "material": ("r", "g", "b", "ka", "kd", "ks", "n", "kr", "kt", "eta"),
    "checkerboard": ("size",),
}
#: Every command, canonical spelling. Keywords are matched case-insensitively.
COMMANDS: Tuple[str, ...] = tuple(OPERANDS) + ("light", "texture")
_CANONICAL = {name.lower(): name for name in COMMANDS}

#: Operands of each light kind after ``light r g b KIND``.
_LIGHT_OPERANDS: Dict[LightKind, Tuple[str, ...]] = {
    LightKind.AMBIENT: (),
    LightKind.POINT: _XYZ,
    LightKind.DIRECTIONAL: _XYZ,
    LightKind.SPOT: ("x", "y", "z", "x'", "y'", "z'", "s"),
}
_LIGHT_KINDS = {kind.value: kind for kind in LightKind}
_LIGHT_WHAT = {kind: f"`light ... {kind.value}`" for kind in LightKind}  # as named in messages
_LIGHT_KIND_LIST = "ambient, point, directional or spotlight"

_OBJECT_KINDS = {kind.value: kind for kind in ObjectKind}
#: Material operands for which a negative value draws a warning (n and eta are checked
#: as errors instead).
_WARN_NEGATIVE_MATERIAL = frozenset({"r", "g", "b", "ka", "kd", "ks", "kr", "kt"})

#: What a texture file may contain, as named in messages.
TEXTURE_FORMATS = ("EXR", "HDR (Radiance RGBE)", "PFM", "PNG", "JPEG",
                   "PPM/PGM/PBM (netpbm P1-P6)", "BMP", "TGA (by its .tga extension)")
_TEXTURE_MAGIC = (  # (prefix, format); first match wins
    (b"\x76\x2f\x31\x01", "exr"),
    (b"\x89PNG\r\n\x1a\n", "png"),
    (b"\xff\xd8\xff", "jpeg"),
    (b"#?RADIANCE", "hdr"),
    (b"#?RGBE", "hdr"),
    (b"BM", "bmp"),
)
_TGA_HEADER_SIZE = 18
_TGA_IMAGE_TYPES = frozenset({1, 2, 3, 9, 10, 11})

#: Characters that may not appear anywhere in a scene: C0/C1 control characters other
#: than tab (line ends are consumed by the line splitting), DEL, and lone surrogates
#: (which only a Python ``str`` can carry; they are not Unicode text).
_FORBIDDEN = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\ud800-\udfff]")
_TOKEN = re.compile(r"[^ \t]+")
#: What ends a line. (The parser itself splits with str.replace, which is faster.)
LINE_END = re.compile(r"\r\n|\r|\n")

#: A parallel test threshold for unit vectors: |u x d| below this counts as parallel.
_PARALLEL_EPS = 1e-12
#: Below this, entries of a matrix times coordinates can never overflow a double.
_SAFE_MAGNITUDE = 1e150

# --------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------


def parse_file(path: "Union[str, bytes, os.PathLike[str]]") -> Scene:
    """Parse the .RAY file at ``path``.

    Relative texture paths resolve against the file's directory. A file that
    cannot be read (missing, a directory, no permission, a device) is reported
    as a :class:`RayError` at line 1, column 1.
    """
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"parse_file() takes a path, not {type(path).__name__}")
    shown = _display_name(path)
    try:
        path = os.fsdecode(path)
        data = _read_scene_bytes(path)
        base_dir = os.path.dirname(os.path.abspath(path))
    except (OSError, ValueError) as exc:
        raise RayError([Diagnostic(Severity.ERROR, shown, 1, 1,
                                   f"cannot read the scene file: {_os_reason(exc)}")]) from None
    return _Parser(shown, base_dir).run(data)


def parse_text(text: Union[str, bytes], file: str = "<string>",
               base_dir: Optional[str] = None) -> Scene:
    """Parse .RAY source held in memory.

    ``file`` is the name shown in diagnostics and stored in ``Scene.file``;
    relative texture paths resolve against ``base_dir`` (default: the current
    directory at parse time). ``bytes`` are decoded as UTF-8 exactly like a file.
    """
    if not isinstance(text, (str, bytes, bytearray, memoryview)):
        raise TypeError(f"parse_text() takes str or bytes, not {type(text).__name__}")
    return _Parser(file, base_dir).run(text)


def parse(path_or_text: PathOrText) -> Scene:
    """Parse a .RAY file or .RAY text, whichever ``path_or_text`` is.

    An ``os.PathLike`` is a path. A ``str`` is a path when it names an existing
    file, or when it is a single line ending in ``.ray`` (any case) -- then a
    missing file is reported as such; any other ``str``, and ``bytes``, are text.
    """
    if isinstance(path_or_text, os.PathLike):
        return parse_file(path_or_text)
    if not isinstance(path_or_text, (str, bytes, bytearray, memoryview)):
        raise TypeError(f"parse() takes a path, str or bytes, not {type(path_or_text).__name__}")
    if isinstance(path_or_text, str) and _looks_like_path(path_or_text):
        return parse_file(path_or_text)
    return parse_text(path_or_text)


def _looks_like_path(text: str) -> bool:
    if "\n" in text or "\r" in text:
        return False
    if text.lower().endswith(".ray"):
        return True
    try:
        return os.path.exists(text)
    except (OSError, ValueError):
        return False


# --------------------------------------------------------------------------------------
# Reading files
# --------------------------------------------------------------------------------------


def _display_name(path) -> str:
    try:
        return os.fsdecode(path)
    except (TypeError, ValueError):  # pragma: no cover - fsdecode of str/bytes/PathLike
        return repr(path)


def _os_reason(exc: BaseException) -> str:
    if isinstance(exc, OSError) and exc.strerror:
        return exc.strerror
    return str(exc) or type(exc).__name__


def _read_scene_bytes(path) -> bytes:
    """The file's bytes; only regular files and pipes (never devices that never end)."""
    with open(path, "rb") as f:
        mode = os.fstat(f.fileno()).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(21, "Is a directory")
        if not (stat.S_ISREG(mode) or stat.S_ISFIFO(mode)):
            raise OSError(0, "not a regular file")
        return f.read()


def _detect_texture_format(path: str) -> Optional[str]:
    """The image format of the file at ``path``, from its first bytes; None if unknown.

    Raises OSError when the file cannot be opened or read, or is not a regular file.
    """
    st = os.stat(path)
    if stat.S_ISDIR(st.st_mode):
        raise IsADirectoryError(21, "Is a directory")
    if not stat.S_ISREG(st.st_mode):
        raise OSError(0, "not a regular file")
    with open(path, "rb") as f:
        head = f.read(32)
    for magic, fmt in _TEXTURE_MAGIC:
        if head.startswith(magic):
            return fmt
    if len(head) >= 3 and head[0:1] == b"P" and head[2:3] in b" \t\r\n":
        if head[1:2] in b"Ff":
            return "pfm"
        if head[1:2] in b"123456":
            return "ppm"
    if (path.lower().endswith(".tga") and len(head) >= _TGA_HEADER_SIZE
            and head[1] in (0, 1) and head[2] in _TGA_IMAGE_TYPES):
        return "tga"
    return None


# --------------------------------------------------------------------------------------
# Lines and tokens
# --------------------------------------------------------------------------------------


@contextlib.contextmanager
def _no_cyclic_gc():
    """Pause the cyclic garbage collector while a parse builds its (acyclic) objects.

    A large scene allocates millions of tuples; each allocation burst would
    otherwise trigger collections that re-scan everything built so far.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def _split_lines(data: bytes) -> List[bytes]:
    return data.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")


def _tokens(line: str) -> List[str]:
    """The tokens of ``line`` before any trailing comment (spaces and tabs separate)."""
    # For ASCII text without control characters str.split() splits on exactly
    # spaces and tabs; otherwise Unicode spaces must stay inside tokens.
    toks = line.split() if line.isascii() else [t for t in line.replace("\t", " ").split(" ") if t]
    return _before_comment(toks) if "#" in line else toks


def _before_comment(toks: List[str]) -> List[str]:
    """``toks`` up to the first token that starts with ``#`` (a comment), if any."""
    for i, tok in enumerate(toks):
        if tok[0] == "#":
            return toks[:i]
    return toks


def _spans(line: str) -> List[Tuple[int, int]]:
    """0-based [start, end) character spans of the tokens of ``line``, as :func:`_tokens`."""
    return [m.span() for m in _TOKEN.finditer(line)]


def token_spans(line: str) -> List[Tuple[int, int]]:
    """0-based [start, end) character spans of the tokens of one line (without its line end)
    before any trailing comment, as the parser reads them: the command, then its operands."""
    return _spans(line)[:len(_tokens(line))]


# --------------------------------------------------------------------------------------
# Small vector and matrix helpers (plain tuples: a 4x4 row-major affine matrix)
# --------------------------------------------------------------------------------------


# Each push multiplies the new transform T onto the *left* of the current composite
# M (T is applied last). The products are written out per kind of T: cheaper than a
# general 4x4 product, and exact where T is (a translation adds, a scale multiplies).

def _translated(m: Matrix4, x: float, y: float, z: float) -> Matrix4:
    """``translation(x, y, z) @ m``."""
    r0, r1, r2, last = m
    return ((r0[0], r0[1], r0[2], r0[3] + x), (r1[0], r1[1], r1[2], r1[3] + y),
            (r2[0], r2[1], r2[2], r2[3] + z), last)


def _scaled(m: Matrix4, x: float, y: float, z: float) -> Matrix4:
    """``scaling(x, y, z) @ m``."""
    r0, r1, r2, last = m
    return ((r0[0] * x, r0[1] * x, r0[2] * x, r0[3] * x),
            (r1[0] * y, r1[1] * y, r1[2] * y, r1[3] * y),
            (r2[0] * z, r2[1] * z, r2[2] * z, r2[3] * z), last)


_QUARTER_TURNS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))  # (cos, sin) of k * 90


@functools.lru_cache(maxsize=256)  # scenes repeat their angles
def _cos_sin_degrees(theta: float) -> Tuple[float, float]:
    """cos and sin of ``theta`` degrees; exact for whole multiples of 90 degrees."""
    theta = math.fmod(theta, 360.0)
    if theta % 90.0 == 0.0:
        return _QUARTER_TURNS[int(theta // 90.0) % 4]
    rad = math.radians(theta)
    return math.cos(rad), math.sin(rad)


def _rotated(m: Matrix4, axis: str, theta: float) -> Matrix4:
    """``rotation(axis, theta) @ m``: right-handed, ``theta`` in degrees, ``axis`` x, y or z.

    The rotation matrices are Rx = [[1,0,0],[0,c,-s],[0,s,c]],
    Ry = [[c,0,s],[0,1,0],[-s,0,c]] and Rz = [[c,-s,0],[s,c,0],[0,0,1]].
    """
    c, s = _cos_sin_degrees(theta)
    r0, r1, r2, last = m
    if axis == "x":
        return (r0, _mix(c, r1, -s, r2), _mix(s, r1, c, r2), last)
    if axis == "y":
        return (_mix(c, r0, s, r2), r1, _mix(-s, r0, c, r2), last)
    return (_mix(c, r0, -s, r1), _mix(s, r0, c, r1), r2, last)


def _mix(a: float, u: Tuple[float, ...], b: float, v: Tuple[float, ...]) -> Tuple[float, ...]:
    """The row ``a * u + b * v``."""
    return (a * u[0] + b * v[0], a * u[1] + b * v[1], a * u[2] + b * v[2], a * u[3] + b * v[3])


def _magnitude_if_usable(m: Matrix4) -> Optional[float]:
    """The largest |entry| of ``m`` if it is usable, else None.

    Usable: finite entries and an invertible (finite, non-zero determinant) linear part.
    """
    entries = m[0] + m[1] + m[2]
    total = sum(entries)
    if total - total != 0.0 and not all(map(math.isfinite, entries)):
        return None  # (a finite sum proves all entries finite; an infinite one may lie)
    (a, b, c, _), (d, e, f, _), (g, h, i, _) = m[0], m[1], m[2]
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if det == 0.0 or not math.isfinite(det):
        return None
    return max(map(abs, entries))


def _apply(m: Matrix4, p: Vec3) -> Vec3:
    x, y, z = p
    return tuple(r[0] * x + r[1] * y + r[2] * z + r[3] for r in m[:3])  # type: ignore[return-value]


def _unit(v: Vec3) -> Vec3:
    """``v`` normalised without overflow or underflow; ``v`` must be finite and non-zero."""
    big = max(abs(c) for c in v)
    x, y, z = (c / big for c in v)
    n = math.sqrt(x * x + y * y + z * z)
    return (x / n, y / n, z / n)


def _cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _fmt(v: Union[float, Sequence[float]]) -> str:
    if isinstance(v, (tuple, list)):
        return "(" + ", ".join(_fmt(c) for c in v) + ")"
    return f"{v:g}"


# --------------------------------------------------------------------------------------
# The parser
# --------------------------------------------------------------------------------------


class _Parser:
    """One pass over one input. Holds the state the format threads through the lines.

    Handlers read the current line from ``self._ln`` (number), ``self._line`` (text),
    ``self._toks`` (tokens before any comment; ``_toks[0]`` is the command as written)
    and ``self._cmd`` (the command's canonical spelling).
    """

    def __init__(self, file: str, base_dir: Optional[str]):
        self.file = file
        self.base_dir = base_dir
        self.diagnostics: List[Diagnostic] = []
        self.n_errors = 0
        # camera: value and (line, column of the command) of each camera command given
        default = Camera()
        self.camera = {"eye": default.eye, "lookat": default.lookat, "up": default.up,
                       "fov": default.fov}
        self.camera_at: Dict[str, Tuple[int, int, str]] = {}
        self.background: Vec3 = (0.0, 0.0, 0.0)
        self.background_line: Optional[int] = None
        self.materials: List[Material] = [Material()]
        self.texture: Optional[Texture] = None
        self.texture_cache: Dict[str, Union[Texture, Tuple[str, ...]]] = {}
        self.checker: Optional[float] = None
        self.stack: List[Matrix4] = [IDENTITY]  # composites, see the module docstring
        self.stack_magnitude: List[float] = [1.0]  # largest |entry| of each composite
        self.objects: List[SceneObject] = []
        self.corners: Dict[Vec3, Vec3] = {}  # each distinct triangle corner, once (see _triangle)
        self.lights: List[Light] = []
        self.first_object_at = (0, "")  # (line, text) of the first object, for a warning
        self.suggestions: Dict[str, str] = {}
        self._ln = 0
        self._line = ""
        self._toks: List[str] = []
        self._cmd = ""  # canonical name of the current line's command
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

    def run(self, data: Union[str, bytes]) -> Scene:
        with _no_cyclic_gc():
            return self._run(data)

    def _run(self, data: Union[str, bytes]) -> Scene:
        handlers = self._handlers
        for ln, line in self._decoded_lines(data):
            # _tokens(line), inlined: this loop runs once per line of the input
            toks = line.split() if line.isascii() else _tokens(line)
            if not toks:
                continue
            if "#" in line:
                toks = _before_comment(toks)
                if not toks:
                    continue
            self._ln, self._line, self._toks = ln, line, toks
            entry = handlers.get(toks[0].lower())
            if entry is None:
                self._unknown_command()
            else:
                self._cmd, handler = entry
                handler()
        return self._finish()

    def _decoded_lines(self, data: Union[str, bytes]) -> Iterator[Tuple[int, str]]:
        """(line number, text) of every line that may be parsed; reports bad characters."""
        if isinstance(data, (bytes, bytearray, memoryview)):
            data = bytes(data)
            try:
                text = data.decode("utf-8")
            except UnicodeDecodeError:
                return self._decode_line_by_line(data)
        else:
            text = data
        if text.startswith("\ufeff"):  # a UTF-8 byte order mark is not content
            text = text[1:]
        lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
        if _FORBIDDEN.search(text) is None:
            return enumerate(lines, 1)  # the common case: a plain iterator, no generator
        return ((ln, line) for ln, line in enumerate(lines, 1)
                if not self._line_has_bad_character(ln, line))

    def _decode_line_by_line(self, data: bytes):
        for ln, raw in enumerate(_split_lines(data), 1):
            if ln == 1 and raw.startswith(b"\xef\xbb\xbf"):
                raw = raw[3:]
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError as exc:
                column = len(raw[:exc.start].decode("utf-8", "replace")) + 1
                bad = raw[exc.start:exc.end].hex(" ")
                self._error_at(ln, column, f"invalid UTF-8 (byte {bad}); a scene is UTF-8 text",
                               raw.decode("utf-8", "replace"))
                continue
            if self._line_has_bad_character(ln, line):
                continue
            yield ln, line

    def _line_has_bad_character(self, ln: int, line: str) -> bool:
        m = _FORBIDDEN.search(line)
        if m is None:
            return False
        ch = m.group()
        what = "a NUL byte" if ch == "\0" else \
            "a lone surrogate" if "\ud800" <= ch <= "\udfff" else "a control character"
        shown = _FORBIDDEN.sub("\ufffd", line)  # one column each, so the caret still fits
        self._error_at(ln, m.start() + 1,
                       f"{what} (U+{ord(ch):04X}) is not allowed in a scene", shown)
        return True

    # ---- diagnostics -------------------------------------------------------------

    def _error_at(self, ln: int, column: int, message: str, source: str) -> None:
        self.diagnostics.append(Diagnostic(Severity.ERROR, self.file, ln, column, message, source))
        self.n_errors += 1

    def _report(self, severity: Severity, column: int, message: str,
                ln: Optional[int] = None, source: Optional[str] = None) -> None:
        self.diagnostics.append(Diagnostic(severity, self.file, self._ln if ln is None else ln,
                                           column, message,
                                           self._line if source is None else source))
        if severity is Severity.ERROR:
            self.n_errors += 1

    def _error(self, column: int, message: str) -> None:
        self._report(Severity.ERROR, column, message)

    def _warning(self, column: int, message: str) -> None:
        self._report(Severity.WARNING, column, message)

    def _column(self, index: int) -> int:
        """1-based column of token ``index`` of the current line."""
        return _spans(self._line)[index][0] + 1

    def _end_column(self) -> int:
        """1-based column just past the last (non-comment) token of the current line."""
        return _spans(self._line)[len(self._toks) - 1][1] + 1

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
        column = self._column(start + len(names)) if found > len(names) else self._end_column()
        self._error(column, message)
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
            if total - total == 0.0 and (self._line.isascii() or all(map(str.isascii, toks))):
                return values
        what = what or f"`{self._cmd}`"
        ok = True
        for i, (tok, name) in enumerate(zip(toks, names), start):
            problem = _number_problem(tok)
            if problem is not None:
                self._error(self._column(i), f"expected a number for `{name}` of {what}, "
                                             f"found `{tok}`{problem}")
                ok = False
        return values if ok else None

    def _operands(self) -> Optional[Tuple[float, ...]]:
        """All operands of a fixed-operand command, checked; None (reported) on error."""
        names = OPERANDS[self._cmd]
        toks = self._toks
        if len(toks) != len(names) + 1:
            self._count_ok(names)
            return None
        try:  # the common case, inlined: every operand a finite ASCII float literal
            values = tuple(map(float, toks[1:]))
            total = sum(values)
            if total - total == 0.0 and self._line.isascii():
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
                self._warning(self._column(start + i),
                              f"negative `{name}` ({_fmt(value)}) in {what}")

    # ---- camera and background ---------------------------------------------------

    def _note_camera(self, name: str) -> None:
        earlier = self.camera_at.get(name)
        if earlier is not None:
            self._warning(self._column(0), f"`{name}` given again; this value replaces the one "
                                           f"on line {earlier[0]} (the last one wins)")
        self.camera_at[name] = (self._ln, self._column(0), self._line)

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
            self._error(self._column(1),
                        f"`fov` must be strictly between 0 and 180 degrees, found {_fmt(fov)}")
        self._note_camera("fov")
        self.camera["fov"] = fov

    def _background(self) -> None:
        values = self._operands()
        if values is None:
            return
        if self.background_line is not None:
            self._warning(self._column(0), f"`background` given again; this value replaces the "
                                           f"one on line {self.background_line} (the last one wins)")
        self._warn_negative(_RGB, values, 1, "`background`")
        self.background = values  # type: ignore[assignment]
        self.background_line = self._ln

    def _check_camera(self) -> Camera:
        """Whole-camera checks, reported at the last camera line involved."""
        eye, lookat, up = self.camera["eye"], self.camera["lookat"], self.camera["up"]
        at = self.camera_at

        def report(involved, message):
            lines = [at[n] for n in involved if n in at]
            ln, column, text = max(lines) if lines else (1, 1, "")
            self._report(Severity.ERROR, column, message, ln=ln, source=text)

        if eye == lookat:
            report(("eye", "lookat"), f"the camera's `eye` and `lookat` are the same point "
                                      f"{_fmt(eye)}, so it has no view direction")
        elif up == (0.0, 0.0, 0.0):
            report(("up",), "the camera's `up` is the zero vector")
        else:
            view = tuple(b - a for a, b in zip(eye, lookat))
            if not all(map(math.isfinite, view)):
                view = tuple(b / 2 - a / 2 for a, b in zip(eye, lookat))
            side = _cross(_unit(view), _unit(up))  # type: ignore[arg-type]
            if math.sqrt(sum(c * c for c in side)) < _PARALLEL_EPS:
                report(("eye", "lookat", "up"),
                       f"the camera's `up` {_fmt(up)} is parallel to its view direction "
                       f"{_fmt(view)} (from `eye` to `lookat`)")
        line = max((ln for ln, _, _ in at.values()), default=None)
        return Camera(eye=eye, lookat=lookat, up=up, fov=self.camera["fov"], line=line)

    # ---- objects -----------------------------------------------------------------

    def _add(self, kind: ObjectKind, vertices=None) -> None:
        if not self.objects:
            self.first_object_at = (self._ln, self._line)
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
        n = _cross(e1, e2)
        if n[0] == 0.0 and n[1] == 0.0 and n[2] == 0.0:
            self._warning(self._column(0), "zero-area triangle: its corners are collinear "
                                           "(it will not be visible)")
        # Only a transform (not the identity at the bottom) can carry corners out of range.
        if (len(self.stack) > 1
                and max(map(abs, values)) * self.stack_magnitude[-1] > _SAFE_MAGNITUDE ** 2):
            corners = [_apply(self.stack[-1], p) for p in (p0, p1, p2)]  # type: ignore[arg-type]
            if not all(math.isfinite(c) for p in corners for c in p):
                self._error(self._column(0), "the current transform carries this triangle "
                                             "beyond the floating-point range")
        self._add(ObjectKind.TRIANGLE, vertices=(p0, p1, p2))

    # ---- lights ------------------------------------------------------------------

    def _light(self) -> None:
        toks = self._toks
        # Where is the kind? The first token after `light` that is not a number.
        kind_at = 4
        if len(toks) < 5 or toks[4].lower() not in _LIGHT_KINDS:
            kind_at = next((i for i in range(1, len(toks))
                            if _number_problem(toks[i]) is not None), None)
        if kind_at is not None and kind_at != 4 and toks[kind_at].lower() in _LIGHT_KINDS:
            self._error(self._column(kind_at),
                        f"`light` takes 3 color operands (r g b) before the kind "
                        f"`{toks[kind_at]}`, found {kind_at - 1}")
            return
        if len(toks) < 5:
            self._error(self._end_column(), f"`light` takes a color r g b and then a kind "
                                            f"({_LIGHT_KIND_LIST}), found {len(toks) - 1} operands")
            return
        word = toks[4].lower()
        kind = _LIGHT_KINDS.get(word)
        color = self._floats(_RGB, 1, what="`light`")
        if kind is None:
            guess = difflib.get_close_matches(word, list(_LIGHT_KINDS), n=1, cutoff=0.5)
            hint = f"; did you mean `{guess[0]}`?" if guess else f"; expected {_LIGHT_KIND_LIST}"
            self._error(self._column(4), f"unknown light kind `{toks[4]}`{hint}")
            return
        names = _LIGHT_OPERANDS[kind]
        what = _LIGHT_WHAT[kind]
        if not self._count_ok(names, start=5, what=what):
            return
        values = self._floats(names, start=5, what=what)
        if color is None or values is None:
            return
        self._warn_negative(_RGB, color, 1, "a light's color")
        position = direction = shape = None
        if kind is LightKind.POINT:
            position = values
        elif kind is LightKind.DIRECTIONAL:
            direction = values
            if direction == (0.0, 0.0, 0.0):
                self._error(self._column(5), "a directional light's direction (x y z) "
                                             "must not be the zero vector")
        elif kind is LightKind.SPOT:
            position, direction, shape = values[0:3], values[3:6], values[6]
            if direction == (0.0, 0.0, 0.0):
                self._error(self._column(8), "a spotlight's axis (x' y' z') "
                                             "must not be the zero vector")
            if shape < 0:
                self._error(self._column(11), f"a spotlight's shape coefficient `s` must be "
                                              f">= 0, found {_fmt(shape)}")
        self.lights.append(Light(kind=kind, color=color, index=len(self.lights) + 1,  # type: ignore[arg-type]
                                 line=self._ln, position=position, direction=direction,
                                 shape=shape))

    # ---- the transform stack -----------------------------------------------------

    def _push(self, composite: Optional[Matrix4]) -> None:
        """Push the new ``composite`` (``T @ current``). None, after an error in the line,
        pushes a no-op so that later `pop` lines still match their pushes."""
        magnitude = None if composite is None else _magnitude_if_usable(composite)
        if magnitude is None:
            if composite is not None:
                self._error(self._column(0), f"`{self._cmd}` makes the transform overflow or "
                                             f"become singular in floating point")
            composite, magnitude = self.stack[-1], self.stack_magnitude[-1]
        self.stack.append(composite)
        self.stack_magnitude.append(magnitude)

    def _translate(self) -> None:
        values = self._operands()
        self._push(None if values is None else _translated(self.stack[-1], *values))

    def _scale(self) -> None:
        values = self._operands()
        if values is not None and 0.0 in values:
            for i, v in enumerate(values):
                if v == 0.0:
                    self._error(self._column(1 + i), f"`scale` factor `{_XYZ[i]}` is zero; "
                                                     f"a scale must be invertible")
            values = None
        self._push(None if values is None else _scaled(self.stack[-1], *values))

    def _rotate(self) -> None:
        values = self._operands()
        axis = self._cmd[-1].lower()
        self._push(None if values is None else _rotated(self.stack[-1], axis, values[0]))

    def _reset(self) -> None:
        if len(self._toks) != 1:
            self._count_ok(())
        del self.stack[1:], self.stack_magnitude[1:]

    def _pop(self) -> None:
        if len(self._toks) != 1:
            self._count_ok(())
        if len(self.stack) == 1:
            self._error(self._column(0), "`pop` on an empty transform stack "
                                         "(nothing has been pushed since the start or `reset`)")
            return
        self.stack.pop()
        self.stack_magnitude.pop()

    # ---- material, texture, checkerboard -----------------------------------------

    def _material(self) -> None:
        values = self._operands()
        if values is None:
            return
        r, g, b, ka, kd, ks, n, kr, kt, eta = values
        names = OPERANDS["material"]
        self._warn_negative(names, values, 1, "`material`", only=_WARN_NEGATIVE_MATERIAL)
        if n < 0:
            self._error(self._column(7), f"the Phong coefficient `n` must be >= 0, found {_fmt(n)}")
        if eta <= 0:
            self._error(self._column(10),
                        f"the index of refraction `eta` must be > 0, found {_fmt(eta)}")
        self.materials.append(Material(
            color=(r, g, b), ambient_mix=ka, diffuse_mix=kd, specular_mix=ks, phong_coeff=n,
            reflectivity=kr, refractivity=kt, ior=eta, index=len(self.materials), line=self._ln))

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
        self.texture = self._load_texture(name, column)

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
                self._error(column, "unterminated quoted filename: the closing `\"` is missing")
                return None
            after = body[close + 1:].lstrip(" \t")
            if after and not after.startswith("#"):
                self._error(column + len(body) - len(after),
                            f"unexpected text `{after.split()[0]}` after the quoted filename")
                return None
            name = body[1:close]
            if not name:
                self._error(column, "the quoted filename is empty")
                return None
            return name, column, True
        words = self._toks[1:]
        if not words:
            self._error(self._end_column(), "`texture` takes a filename (or `none`), found nothing")
            return None
        last = _spans(line)[len(self._toks) - 1][1]
        return line[column - 1:last], column, False

    def _load_texture(self, name: str, column: int) -> Optional[Texture]:
        try:
            base = self.base_dir if self.base_dir is not None else os.getcwd()
            path = os.path.abspath(os.path.join(base, name))
        except (OSError, ValueError) as exc:
            self._error(column, f"cannot resolve the texture path `{name}`: {_os_reason(exc)}")
            return None
        cached = self.texture_cache.get(path)
        if cached is None:
            cached = self._probe_texture(name, path)
            self.texture_cache[path] = cached
        if isinstance(cached, Texture):
            return cached
        self._error(column, cached[0])
        return None

    def _probe_texture(self, name: str, path: str) -> Union[Texture, Tuple[str]]:
        try:
            fmt = _detect_texture_format(path)
        except FileNotFoundError:
            return (f"texture file `{name}` not found (looked for {path})",)
        except (OSError, ValueError) as exc:
            return (f"cannot read texture file `{name}` ({path}): {_os_reason(exc)}",)
        if fmt is None:
            return (f"texture file `{name}` is not an image in an accepted format; accepted: "
                    f"{', '.join(TEXTURE_FORMATS)}",)
        return Texture(path=path, format=fmt)

    # ---- unknown commands --------------------------------------------------------

    def _unknown_command(self) -> None:
        word = self._toks[0]
        key = word.lower()
        hint = self.suggestions.get(key)
        if hint is None:
            guess = difflib.get_close_matches(key, list(_CANONICAL), n=1, cutoff=0.6)
            hint = (f"; did you mean `{_CANONICAL[guess[0]]}`?" if guess
                    else "; the commands are " + ", ".join(COMMANDS))
            self.suggestions[key] = hint
        self._error(self._column(0), f"unknown command `{word}`{hint}")

    # ---- the end -----------------------------------------------------------------

    def _finish(self) -> Scene:
        camera = self._check_camera()
        if self.objects and not self.lights:
            ln, text = self.first_object_at
            self._report(Severity.WARNING, len(text) - len(text.lstrip(" \t")) + 1,
                         "the scene has objects but no light: it renders black except for "
                         "the background", ln=ln, source=text)
        diagnostics = sorted(self.diagnostics, key=lambda d: (d.line, d.column))
        if self.n_errors:
            raise RayError(diagnostics)
        return Scene(file=self.file, camera=camera, background=self.background,
                     materials=tuple(self.materials), objects=tuple(self.objects),
                     lights=tuple(self.lights), warnings=tuple(diagnostics))


def _number_problem(token: str) -> Optional[str]:
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
