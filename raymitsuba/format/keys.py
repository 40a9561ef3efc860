"""Where the geometry and camera keys of a .RAY text are, and their values as written.

The keys (``camera.eye``, ``translate2.offset``, ``sphere1.radius``, ...) are stated by
:class:`~raymitsuba.format.commands.ParamKey`; which command holds which fields, by the
table of commands (:data:`~raymitsuba.format.commands.GEOMETRY_COMMANDS`,
:data:`~raymitsuba.format.commands.CAMERA_COMMANDS`, each operand's ``field``). This module
finds each key's command in the text with the dialect's own lexical rules (COMP 575: one
command per line, the first token, any case; MIT 6.837: the parser's cutting of the token
stream into commands), counting each command's lines over the whole file from 1; a camera
key is the last line of its command (the one in effect).

``geometry_places(lines, dialect)`` -> {key: KeyPlace}, in file order: the command's line
and column (of the command word), the token position and operand of each component, and
the numbers as written. Only a valid scene's text is read (the parser has checked it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Dict, Sequence, Tuple

from raymitsuba.format import commands as C
from raymitsuba.format.lexer import COMP575, MIT6837, line_tokens, stream_6837, token_spans


@dataclass(frozen=True)
class KeyPlace:
    """Where one key's operands are written, and what they say."""

    line: int  # of the command word (1-based)
    column: int  # of the command word (1-based)
    operands: Tuple[Tuple[int, C.Operand], ...]  # (token position, operand) per component
    first: Tuple[int, int]  # (line, column) of the first number
    values: Tuple[float, ...]  # the numbers as written, one per component


def _commands_575(lines: Sequence[str]):
    """(canonical command, line, column, [(line, start, end, text) of every token])."""
    canonical = {name.lower(): name for name in C.COMP575_COMMANDS}
    for ln, line in enumerate(lines, 1):
        toks = line_tokens(line)
        if not toks:
            continue
        name = canonical.get(toks[0].lower())
        if name is None:
            continue
        spans = token_spans(line, COMP575)
        yield name, ln, spans[0][0] + 1, [(ln, b, e, line[b:e]) for b, e in spans]


def _commands_6837(lines: Sequence[str]):
    from raymitsuba.format.mit6837 import Mit6837Parser

    canonical = {name.lower(): name for name in C.MIT6837_COMMANDS}
    for command in Mit6837Parser._commands(stream_6837(lines)):
        name = canonical.get(command[0].text.lower())
        if name is None:
            continue
        yield name, command[0].line, command[0].start + 1, \
            [(t.line, t.start, t.end, t.text) for t in command]


def geometry_places(lines: Sequence[str], dialect: str) -> Dict[str, KeyPlace]:
    """Every geometry and camera key of the decoded ``lines`` (a valid scene in ``dialect``),
    in file order of their commands (camera keys where their last line is)."""
    geometry = C.GEOMETRY_COMMANDS[dialect]
    table = C.command_table(dialect)
    commands = _commands_6837(lines) if dialect == MIT6837 else _commands_575(lines)
    counts: Dict[str, int] = {}
    found: Dict[str, KeyPlace] = {}
    for name, line, column, toks in commands:
        if name in C.CAMERA_COMMANDS:
            head = "camera"
        elif name in geometry:
            counts[name] = counts.get(name, 0) + 1
            head = f"{name}{counts[name]}"
        else:
            continue
        command = table[name]
        for field in C.geometry_fields(name, dialect):
            positions = command.positions(field)
            if max(positions) >= len(toks):
                continue  # (not a valid command: the parser reported it)
            key = f"{head}.{field}"
            found.pop(key, None)  # a later camera line replaces an earlier one, in order too
            first = toks[positions[0]]
            found[key] = KeyPlace(line, column, tuple(zip(positions, command.operand_for(field))),
                                  (first[0], first[1] + 1),
                                  tuple(float(toks[p][3]) for p in positions))
    return found

