"""Parameter keys in the .RAY text: which keys a file can hold, their values as written,
and the text with new values written back (the half of ``raymitsuba fit`` that edits text).

:func:`rewrite_scene` returns the .RAY text with only the given keys' numbers replaced,
every other byte unchanged (comments, spacing, line ends), in either dialect. Each key is
parsed by :class:`~raymitsuba.format.commands.ParamKey`; the command it lives on is found
from the model's positions (``Material.line`` / ``.column``, ``Light.line`` / ``.column``,
``Scene.background_at``), the operand from the table of commands
(:mod:`raymitsuba.format.commands`: which token feeds which field, and whether the file
holds the value or its reciprocal -- MIT 6.837's ``index`` is 1 / eta), and the token from
the dialect's own lexical rules (:func:`~raymitsuba.format.lexer.tokens_from`; a MIT 6.837
command's operands may run onto the next lines). A number whose value did not change (as
float32, the renderer's precision) keeps its original spelling; a changed one is written
as ``f"{x:.6g}"``.
"""

from __future__ import annotations

import math
import re
from array import array
from dataclasses import dataclass
from typing import Dict, List, Sequence, Tuple, Union

from raymitsuba.format import commands as C
from raymitsuba.format.commands import ParamKey
from raymitsuba.format.keys import geometry_places
from raymitsuba.format.lexer import LINE_END, tokens_from
from raymitsuba.model import Material, Scene

Value = Union[float, Tuple[float, ...]]

MATERIAL_FIELDS = Material.FIELDS

_LINE_END_KEPT = re.compile(f"({LINE_END.pattern})")  # re.split keeps the line ends


class ParameterError(ValueError):
    """A request about a scene's parameters that cannot be carried out (an unknown key, a
    key with no line to write it to, a value that cannot be written)."""


def parse_key(key: str) -> ParamKey:
    """``key`` parsed (a ParameterError if it is not a parameter key)."""
    try:
        return ParamKey.parse(key)
    except ValueError as e:
        raise ParameterError(str(e)) from None


def source_lines(data: Union[bytes, str]) -> List[str]:
    """The lines of the .RAY source ``data`` (bytes or text), without their line ends, as
    :func:`rewrite_scene` numbers them."""
    text = bytes(data).decode("utf-8", "surrogateescape") if isinstance(
        data, (bytes, bytearray, memoryview)) else data
    return _LINE_END_KEPT.split(text)[0::2]


def writable_keys(model: Scene, data: Union[bytes, str, None] = None) -> List[str]:
    """Every parameter key whose value has a place in the .RAY file: the fields of each
    ``material`` / ``surface`` line (mat1, mat2, ...), of each ``light`` line by kind, the
    background's color if it has a line and, given the file's text ``data``, the geometry
    and camera keys (:mod:`raymitsuba.format.keys`)."""
    keys = [f"mat{m.index}.{name}" for m in model.materials if m.line is not None
            for name in MATERIAL_FIELDS]
    for light in model.lights:
        keys += [f"light{light.index}.{name}" for name in C.light_fields(light.kind)]
    if model.background_at is not None:
        keys.append("background.color")
    if data is not None:
        keys += list(geometry_places(source_lines(data), model.dialect))
    return keys


def key_listing(model: Scene, data: Union[bytes, str]) -> List[str]:
    """``KEY LINE:COL VALUE [VALUE ...]`` for every key of the file (``check --params``): the
    position of its first number and its numbers as written."""
    lines = source_lines(data)
    out = []
    for key in writable_keys(model, data):
        place = place_of(model, key, lines)
        tokens = list(tokens_from(lines, place.line, place.column, model.dialect))
        spans = [tokens[position] for position, _ in place.operands]
        texts = [lines[ln - 1][b:e] for ln, b, e in spans]
        out.append(f"{key} {spans[0][0]}:{spans[0][1] + 1} " + " ".join(texts))
    return out


def model_values(model: Scene, keys: Sequence[str],
                 data: Union[bytes, str, None] = None) -> Dict[str, Value]:
    """The values of ``keys`` as written in ``model`` (e.g. a ground-truth scene); geometry
    and camera keys need the file's text ``data``."""
    out: Dict[str, Value] = {}
    places = None
    for key in keys:
        parsed = parse_key(key)
        name = parsed.field
        if parsed.is_geometry:
            if places is None:
                places = geometry_places(source_lines(data), model.dialect) if data is not None \
                    else {}
            if key not in places:
                raise ParameterError(f"`{key}`: the scene has no such line")
            values = places[key].values
            out[key] = values[0] if len(values) == 1 else values
            continue
        if parsed.owner == "background":
            value = model.background
        elif parsed.owner == "mat":
            material = _material(model, parsed)
            value = getattr(material, name)
        else:
            light = _light(model, parsed)
            value = getattr(light, "shape" if name == "shape_coefficient" else name)
            if value is None:
                raise ParameterError(f"`{key}`: light {parsed.index} is a {light.kind.value} light "
                               f"and has no {name}")
        out[key] = tuple(float(v) for v in value) if isinstance(value, tuple) else float(value)
    return out


def _format(x: float) -> str:
    text = f"{x:.6g}"
    return "0" if text == "-0" else text


def _material(model: Scene, key: ParamKey) -> Material:
    if key.index is None or key.index >= len(model.materials):
        raise ParameterError(f"`{key}`: the scene has no material {key.index}")
    if key.field not in MATERIAL_FIELDS:
        raise ParameterError(f"`{key}`: a material has no {key.field}")
    return model.materials[key.index]


def _light(model: Scene, key: ParamKey):
    if key.index is None or not 1 <= key.index <= len(model.lights):
        raise ParameterError(f"`{key}`: the scene has no light {key.index}")
    return model.lights[key.index - 1]


@dataclass(frozen=True)
class Place:
    """Where the operands of a key are: the command's line and column, and the token
    position of each component's operand with the operand (which may be a reciprocal)."""

    line: int
    column: int
    operands: Tuple[Tuple[int, C.Operand], ...]


def place_of(model: Scene, key: str, lines: Sequence[str] = ()) -> Place:
    """Where ``key``'s operands are written in the .RAY text the model was parsed from (its
    ``lines``, needed for the geometry and camera keys)."""
    parsed = parse_key(key)
    if parsed.is_geometry:
        place = geometry_places(lines, model.dialect).get(key)
        if place is None:
            raise ParameterError(f"`{key}`: the scene has no line for it")
        return Place(place.line, place.column, place.operands)
    if parsed.owner == "background":
        if model.background_at is None or parsed.field != "color":
            raise ParameterError(f"`{key}`: the scene has no `background` line to write it to")
        command = C.COMP575_COMMANDS["background"]
        line, column = model.background_at
    elif parsed.owner == "mat":
        material = _material(model, parsed)
        if material.line is None:
            raise ParameterError(f"`{key}`: the default material has no `material` or `surface` line")
        command = C.command_table(model.dialect)[C.MATERIAL_COMMAND[model.dialect]]
        line, column = material.line, material.column or 1
    else:
        light = _light(model, parsed)
        positions = C.light_positions(light.kind, parsed.field)
        if not positions:
            raise ParameterError(f"`{key}`: a {light.kind.value} light has no {parsed.field}")
        operands = C.LIGHT_COLOR if parsed.field == "color" else C.LIGHT_OPERANDS[light.kind]
        chosen = [o for o in operands if o.field == parsed.field]
        return Place(light.line, light.column or 1, tuple(zip(positions, chosen)))
    return Place(line, column, tuple(zip(command.positions(parsed.field),
                                         command.operand_for(parsed.field))))


def rewrite_scene(data: Union[bytes, str], model: Scene, values: Dict[str, Value],
                  exact: bool = False) -> Union[bytes, str]:
    """The .RAY source ``data`` with the operands of ``values``' keys replaced by the values.

    Every other byte is kept. ``model`` must be the parse of ``data`` (its line numbers
    locate the operands). A number whose value is unchanged (as float32, the precision of
    the renderer) keeps its original spelling. ``exact``: changed numbers are written with
    every digit (``repr``, which reads back as the same float64) instead of ``.6g``."""
    is_bytes = isinstance(data, (bytes, bytearray))
    text = bytes(data).decode("utf-8", "surrogateescape") if is_bytes else data
    parts = _LINE_END_KEPT.split(text)  # line, end, line, end, ..., line
    lines = parts[0::2]
    edits: Dict[int, Dict[Tuple[int, int], str]] = {}  # line -> (start, end) -> new text
    geometry = {}  # the geometry keys' places, found once
    if any(parse_key(key).is_geometry for key in values):
        geometry = geometry_places(lines, model.dialect)
    for key, value in values.items():
        if parse_key(key).is_geometry:
            if key not in geometry:
                raise ParameterError(f"`{key}`: the scene has no line for it")
            found = geometry[key]
            place = Place(found.line, found.column, found.operands)
        else:
            place = place_of(model, key)
        components = value if isinstance(value, tuple) else (value,)
        if len(components) != len(place.operands):
            raise ParameterError(f"`{key}`: expected {len(place.operands)} value(s), "
                           f"got {len(components)}")
        if not 1 <= place.line <= len(lines):
            raise ParameterError(f"line {place.line} is not in the scene text")
        tokens = list(tokens_from(lines, place.line, place.column, model.dialect))
        for (position, operand), component in zip(place.operands, components):
            if not math.isfinite(component):
                raise ParameterError(f"`{key}`: cannot write the non-finite value {component}")
            if position >= len(tokens):
                raise ParameterError(f"line {place.line} does not have operand {position}: "
                               f"{lines[place.line - 1]!r}")
            line, begin, end = tokens[position]
            original = lines[line - 1][begin:end]
            written = operand.written(component)
            if exact:
                new = original if float(original) == written else repr(float(written))
            else:
                new = original if _same_float32(original, operand, component) \
                    else _format(written)
            edits.setdefault(line, {})[(begin, end)] = new
    for line, changes in edits.items():
        source = lines[line - 1]
        out, last = [], 0
        for (begin, end), new in sorted(changes.items()):
            out += [source[last:begin], new]
            last = end
        out.append(source[last:])
        parts[2 * (line - 1)] = "".join(out)
    result = "".join(parts)
    return result.encode("utf-8", "surrogateescape") if is_bytes else result


def _same_float32(token: str, operand: C.Operand, value: float) -> bool:
    """Whether the number ``token`` already means ``value`` (as float32, the renderer's
    precision) for ``operand``."""
    try:
        return _float32(operand.value(float(token))) == _float32(value)
    except (ValueError, ZeroDivisionError):
        return False


def _float32(x: float) -> float:
    """``x`` rounded to float32 (inf past its range), as the renderer holds it."""
    return array("f", [x])[0]
