"""The lexical rules of both .RAY dialects: line ends, characters, comments, tokens.

Both dialects share the lines and characters: UTF-8 text (a byte-order mark is
ignored), lines ending in ``\\n``, ``\\r\\n`` or ``\\r`` (:data:`LINE_END`), control
characters and lone surrogates forbidden (:data:`FORBIDDEN`); tokens are separated by
spaces and tabs only (other Unicode spaces stay inside a token).

They differ in comments and in how far a command reaches:

* **COMP 575**: one command per line; a token that *starts* with ``#`` begins a
  comment running to the end of the line (a ``#`` inside a token does not).
  :func:`line_tokens`, :func:`token_spans`.
* **MIT 6.837**: any ``#`` or ``/`` starts a comment running to the end of the line,
  wherever it is (the original tokenizer treats both so); a command takes its
  operands from the tokens that follow, across line breaks. :func:`stream_6837`
  yields :class:`Token` values with their line and columns.

Columns are 1-based characters of the decoded line (a tab is one column); spans are
0-based ``[start, end)``.
"""

from __future__ import annotations

import re
from typing import Callable, Iterator, List, NamedTuple, Sequence, Tuple, Union

COMP575 = "comp575"
MIT6837 = "mit6837"

#: What ends a line, in both dialects.
LINE_END = re.compile(r"\r\n|\r|\n")
#: Characters that may not appear anywhere in a scene: C0/C1 control characters other
#: than tab (line ends are consumed by the line splitting), DEL, and lone surrogates
#: (which only a Python ``str`` can carry; they are not Unicode text).
FORBIDDEN = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\x7f-\x9f\ud800-\udfff]")
#: The ASCII characters allowed in a scene (tab, the line ends, the printable ones): what
#: :func:`decode` strips to find a FORBIDDEN one in ASCII text (a C loop, a few times faster
#: than the regular expression's search).
_PLAIN_ASCII = bytes([9, 10, 13, *range(32, 127)])
_TOKEN = re.compile(r"[^ \t]+")
_COMMENT_6837 = re.compile(r"[#/]")

#: ``report(line, column, message, source_line)``: where lexical errors go.
Reporter = Callable[[int, int, str, str], None]


class Token(NamedTuple):
    """One token of the MIT 6.837 stream."""

    text: str
    line: int  # 1-based
    start: int  # 0-based span in its line
    end: int

    @property
    def column(self) -> int:
        return self.start + 1


# -- lines -------------------------------------------------------------------------------------
def split_lines(text: str) -> List[str]:
    """The lines of ``text`` without their line ends."""
    if "\r" in text:  # (a search is a fraction of a copy: most files have none)
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text.split("\n")


def _split_byte_lines(data: bytes) -> List[bytes]:
    return data.replace(b"\r\n", b"\n").replace(b"\r", b"\n").split(b"\n")


def decode(data: Union[str, bytes, bytearray, memoryview], report: Reporter) -> List[str]:
    """The lines of ``data`` (line ``n`` is item ``n - 1``), decoded.

    A line holding invalid UTF-8 or a forbidden character is reported through
    ``report`` and comes back empty, so that no parser reads it (its neighbours are
    still read, with their own line numbers).
    """
    if isinstance(data, (bytes, bytearray, memoryview)):
        data = bytes(data)
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError:
            return _decode_line_by_line(data, report)
    else:
        text = data
    if text.startswith("\ufeff"):  # a UTF-8 byte order mark is not content
        text = text[1:]
    lines = split_lines(text)
    if text.isascii():
        clean = not text.encode("ascii").translate(None, _PLAIN_ASCII)
    else:
        clean = FORBIDDEN.search(text) is None
    if clean:
        return lines  # the common case
    return ["" if _has_bad_character(ln, line, report) else line
            for ln, line in enumerate(lines, 1)]


def _decode_line_by_line(data: bytes, report: Reporter) -> List[str]:
    out = []
    for ln, raw in enumerate(_split_byte_lines(data), 1):
        out.append("")
        if ln == 1 and raw.startswith(b"\xef\xbb\xbf"):
            raw = raw[3:]
        try:
            line = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            column = len(raw[:exc.start].decode("utf-8", "replace")) + 1
            bad = raw[exc.start:exc.end].hex(" ")
            report(ln, column, f"invalid UTF-8 (byte {bad}); a scene is UTF-8 text",
                   raw.decode("utf-8", "replace"))
            continue
        if not _has_bad_character(ln, line, report):
            out[-1] = line
    return out


def _has_bad_character(ln: int, line: str, report: Reporter) -> bool:
    m = FORBIDDEN.search(line)
    if m is None:
        return False
    ch = m.group()
    what = "a NUL byte" if ch == "\0" else \
        "a lone surrogate" if "\ud800" <= ch <= "\udfff" else "a control character"
    shown = FORBIDDEN.sub("\ufffd", line)  # one column each, so the caret still fits
    report(ln, m.start() + 1, f"{what} (U+{ord(ch):04X}) is not allowed in a scene", shown)
    return True


# -- COMP 575 tokens ---------------------------------------------------------------------------
def line_tokens(line: str) -> List[str]:
    """The COMP 575 tokens of ``line`` before any trailing comment."""
    # For ASCII text without control characters str.split() splits on exactly
    # spaces and tabs; otherwise Unicode spaces must stay inside tokens.
    toks = line.split() if line.isascii() else [t for t in line.replace("\t", " ").split(" ") if t]
    return before_comment(toks) if "#" in line else toks


def before_comment(toks: List[str]) -> List[str]:
    """``toks`` up to the first token that starts with ``#`` (a COMP 575 comment), if any."""
    for i, tok in enumerate(toks):
        if tok[0] == "#":
            return toks[:i]
    return toks


def spans(line: str) -> List[Tuple[int, int]]:
    """0-based [start, end) spans of every space-separated token of ``line``, comments included."""
    return [m.span() for m in _TOKEN.finditer(line)]


def token_spans(line: str, dialect: str = COMP575) -> List[Tuple[int, int]]:
    """0-based [start, end) character spans of the tokens of one line (without its line end)
    before any comment, as the parser of ``dialect`` reads them."""
    if dialect == MIT6837:
        return spans(strip_comment_6837(line))
    return spans(line)[:len(line_tokens(line))]


# -- MIT 6.837 tokens --------------------------------------------------------------------------
def strip_comment_6837(line: str) -> str:
    """``line`` up to its first ``#`` or ``/`` (a MIT 6.837 comment)."""
    m = _COMMENT_6837.search(line)
    return line if m is None else line[:m.start()]


def stream_6837(lines: Sequence[str], first: int = 1) -> Iterator[Token]:
    """Every MIT 6.837 token of ``lines`` (numbered from ``first``), in order."""
    for ln, line in enumerate(lines, first):
        code = strip_comment_6837(line) if ("#" in line or "/" in line) else line
        for m in _TOKEN.finditer(code):
            yield Token(m.group(), ln, m.start(), m.end())


# -- locating operands again (for tools that edit .RAY text in place) --------------------------
def tokens_from(lines: Sequence[str], line: int, column: int,
                dialect: str = COMP575) -> Iterator[Tuple[int, int, int]]:
    """(1-based line, start, end) of the token at ``line``:``column`` (1-based) and of the
    tokens after it that the same command may read: the rest of its line in COMP 575, the
    rest of the file in MIT 6.837."""
    if dialect == MIT6837:
        for tok in stream_6837(lines[line - 1:], line):
            if tok.line > line or tok.start >= column - 1:
                yield tok.line, tok.start, tok.end
        return
    for start, end in token_spans(lines[line - 1]):
        if start >= column - 1:
            yield line, start, end
