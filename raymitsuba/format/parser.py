"""The .RAY parser: text in, an immutable :class:`~raymitsuba.model.Scene` out.

Public entry points:

* :func:`parse_file` -- read a .RAY file;
* :func:`parse_text` -- parse a string (or bytes) already in memory;
* :func:`parse` -- either of the two, guessed from the argument;
* :func:`detect_dialect` -- which dialect a text is in;
* :data:`LINE_END` and :func:`token_spans` -- the lexical rules, for tools that edit
  .RAY text in place (:mod:`raymitsuba.format.writeback` writes fitted numbers back).

Each takes ``dialect``: ``"auto"`` (the default: decided from the text, see
:func:`detect_dialect`), ``"comp575"`` or ``"mit6837"``. The modules the work is split
into are listed in the package's index (:mod:`raymitsuba.format`).

The contract with callers: the result is a :class:`Scene`, or a :class:`RayError` is
raised carrying **every** error of the input (the parser carries on after a bad line)
and the warnings. Nothing else escapes, whatever the input. Work is linear in the size
of the input.
"""

from __future__ import annotations

import os
import re
import stat
from typing import List, Optional, Tuple, Union

from raymitsuba.format import commands as C
from raymitsuba.format.comp575 import Comp575Parser
from raymitsuba.format.diagnostics import Diagnostics
from raymitsuba.format.lexer import COMP575, LINE_END, MIT6837, decode, strip_comment_6837, token_spans
from raymitsuba.format.mit6837 import Mit6837Parser
from raymitsuba.model import Diagnostic, RayError, Scene, Severity
from raymitsuba.util import no_cyclic_gc
from raymitsuba.format.textures import TEXTURE_FORMATS, os_reason

__all__ = ["parse", "parse_file", "parse_text", "detect_dialect", "token_spans", "COMMANDS",
           "DIALECT_CHOICES", "LINE_END", "OPERANDS", "TEXTURE_FORMATS"]

PathOrText = Union[str, bytes, "os.PathLike[str]"]

#: The values of ``dialect``.
DIALECT_CHOICES = ("auto", COMP575, MIT6837)
#: Every COMP 575 command, canonical spelling. Keywords are matched case-insensitively.
COMMANDS: Tuple[str, ...] = C.COMMAND_NAMES[COMP575]
#: Operand names of every COMP 575 command with a fixed list of numeric operands.
OPERANDS = {name: command.names for name, command in C.COMP575_COMMANDS.items()}

# --------------------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------------------


def parse_file(path: "Union[str, bytes, os.PathLike[str]]", dialect: str = "auto") -> Scene:
    """Parse the .RAY file at ``path`` (in ``dialect``, see the module docstring).

    Relative texture paths resolve against the file's directory. A file that
    cannot be read (missing, a directory, no permission, a device) is reported
    as a :class:`RayError` at line 1, column 1.
    """
    if not isinstance(path, (str, bytes, os.PathLike)):
        raise TypeError(f"parse_file() takes a path, not {type(path).__name__}")
    _check_dialect(dialect)
    shown = _display_name(path)
    try:
        path = os.fsdecode(path)
        data = _read_scene_bytes(path)
        base_dir = os.path.dirname(os.path.abspath(path))
    except (OSError, ValueError) as exc:
        raise RayError([Diagnostic(Severity.ERROR, shown, 1, 1,
                                   f"cannot read the scene file: {os_reason(exc)}")]) from None
    return _run(data, shown, base_dir, dialect)


def parse_text(text: Union[str, bytes], file: str = "<string>",
               base_dir: Optional[str] = None, dialect: str = "auto") -> Scene:
    """Parse .RAY source held in memory.

    ``file`` is the name shown in diagnostics and stored in ``Scene.file``;
    relative texture paths resolve against ``base_dir`` (default: the current
    directory at parse time). ``bytes`` are decoded as UTF-8 exactly like a file.
    """
    if not isinstance(text, (str, bytes, bytearray, memoryview)):
        raise TypeError(f"parse_text() takes str or bytes, not {type(text).__name__}")
    return _run(text, file, base_dir, dialect)


def parse(path_or_text: PathOrText, dialect: str = "auto") -> Scene:
    """Parse a .RAY file or .RAY text, whichever ``path_or_text`` is.

    An ``os.PathLike`` is a path. A ``str`` is a path when it names an existing
    file, or when it is a single line ending in ``.ray`` (any case) -- then a
    missing file is reported as such; any other ``str``, and ``bytes``, are text.
    """
    if isinstance(path_or_text, os.PathLike):
        return parse_file(path_or_text, dialect)
    if not isinstance(path_or_text, (str, bytes, bytearray, memoryview)):
        raise TypeError(f"parse() takes a path, str or bytes, not {type(path_or_text).__name__}")
    if isinstance(path_or_text, str) and _looks_like_path(path_or_text):
        return parse_file(path_or_text, dialect)
    return parse_text(path_or_text, dialect=dialect)


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


# --------------------------------------------------------------------------------------
# Dialects
# --------------------------------------------------------------------------------------

# The markers of each dialect (docs/format.md, "Telling the dialects apart"): a line that
# starts with one of these words. A `sphere` with operands is MIT 6.837, a `sphere` alone
# COMP 575 -- unless the next token of the file is a number (MIT 6.837 operands may run
# across lines). A `cylinder` with operands is neither (a later program's command).
_END = r"(?=[ \t#/]|$)"
_MIT_WORDS = r"[ \t]*(surface|triangles|v|f|end|viewport|sphere(?=[ \t]+[^ \t#/]))" + _END
_MIT_MARKERS = re.compile("^" + _MIT_WORDS, re.MULTILINE | re.IGNORECASE)
#: The same after a line end: a pattern that starts with a literal is searched for that
#: literal first (about twice as fast over a long text as trying ``^`` everywhere).
_MIT_MARKERS_BELOW = re.compile("\n" + _MIT_WORDS, re.MULTILINE | re.IGNORECASE)
_COMP_MARKERS = re.compile(
    r"^[ \t]*(material|plane|cone|triangle|translate|scale|rotate[xyz]|pop|reset|texture|"
    r"checkerboard|cylinder(?=[ \t]*(?:#|$))|sphere(?=[ \t]*(?:[#/]|$))|"
    r"light(?=[^\n#]*[ \t]spotlight(?:[ \t#]|$)))" + _END,
    re.MULTILINE | re.IGNORECASE)
_NEXT_TOKEN = re.compile(r"[^ \t\n]+")


def _marker(text: str, m: "re.Match[str]") -> Tuple[int, int, str]:
    line_start = text.rfind("\n", 0, m.start(1)) + 1
    return text.count("\n", 0, m.start(1)) + 1, m.start(1) - line_start + 1, m.group(1)


def _sphere_with_operands_below(text: str, end: int) -> bool:
    """Whether the first token after ``end`` (comments skipped) is a number."""
    for line in text[end:end + 4096].split("\n")[1:]:
        m = _NEXT_TOKEN.search(strip_comment_6837(line))
        if m is not None:
            try:
                float(m.group())
                return True
            except ValueError:
                return False
    return False


#: ``_MIT_MARKERS`` of lower-case text: the search :func:`first_mit_marker` makes.
_MIT_MARKERS_LOWER = re.compile("^" + _MIT_WORDS, re.MULTILINE)
_MIT_MARKERS_BELOW_LOWER = re.compile("\n" + _MIT_WORDS, re.MULTILINE)


def first_mit_marker(text: str) -> Optional["re.Match[str]"]:
    """The first match of ``_MIT_MARKERS`` in ``text``, or None.

    A text of ASCII is searched in lower case, case-sensitively (over a long file, less than
    half the time of the case-insensitive search, which folds every character it tries), and
    the match found is made again on ``text`` itself, which keeps the word's case.
    """
    if not text.isascii():
        return _MIT_MARKERS.match(text) or _MIT_MARKERS_BELOW.search(text)
    low = text.lower()  # (ASCII: the same length, the same positions)
    if _MIT_MARKERS_LOWER.match(low):
        return _MIT_MARKERS.match(text)
    m = _MIT_MARKERS_BELOW_LOWER.search(low)
    return None if m is None else _MIT_MARKERS_BELOW.match(text, m.start())


def _first_markers(lines: List[str]):
    """(first MIT 6.837 marker, first COMP 575 marker), each (line, column, word) or None."""
    text = "\n".join(lines)
    mit = first_mit_marker(text)
    found_mit = None if mit is None else _marker(text, mit)
    found_comp = None
    for m in _COMP_MARKERS.finditer(text):
        if m.group(1).lower() == "sphere" and _sphere_with_operands_below(text, m.end(1)):
            if found_mit is None or m.start(1) < mit.start(1):  # type: ignore[union-attr]
                found_mit = _marker(text, m)
            continue
        found_comp = _marker(text, m)
        break
    return found_mit, found_comp


def detect_dialect(lines: List[str], diagnostics: Optional[Diagnostics] = None) -> Optional[str]:
    """The dialect of the decoded ``lines``: MIT 6.837 when a marker of it is present,
    otherwise COMP 575. Markers of both are an error, reported to ``diagnostics``
    at the later of the two; the answer is then None."""
    mit, comp = _first_markers(lines)
    if mit is None:
        return COMP575
    if comp is None:
        return MIT6837
    if diagnostics is not None:
        at = max(mit, comp)
        diagnostics.error(at[0], at[1], f"line {mit[0]} uses `{mit[2]}` (MIT 6.837) but line "
                                        f"{comp[0]} uses `{comp[2]}` (COMP 575); a file is in one "
                                        f"dialect (force one with --dialect, or dialect= in the "
                                        f"API)", lines[at[0] - 1])
    return None


def _run(data: Union[str, bytes], file: str, base_dir: Optional[str], dialect: str) -> Scene:
    _check_dialect(dialect)
    with no_cyclic_gc():
        lexical = Diagnostics(file)
        lines = decode(data, lexical.error)
        if dialect == "auto":
            detected = detect_dialect(lines, lexical)
            if detected is None:
                lexical.result()  # raises: a file of mixed dialects is not read further
            dialect = detected  # type: ignore[assignment]
        parser = Mit6837Parser(file) if dialect == MIT6837 else Comp575Parser(file, base_dir)
        parser.diag.items += lexical.items
        parser.diag.n_errors += lexical.n_errors
        return parser.run(lines)


def _check_dialect(dialect: str) -> None:
    if dialect not in DIALECT_CHOICES:
        raise ValueError(f"dialect must be one of {', '.join(DIALECT_CHOICES)}, not {dialect!r}")
