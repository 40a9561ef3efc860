"""Tests of raymitsuba/format/commands.py: the tables of commands of both dialects and the
parameter keys."""

from __future__ import annotations

import pytest

from raymitsuba.format import commands as C
from raymitsuba.model import LightKind, Material
from support import REPO


def test_both_dialects_have_a_table():
    assert set(C.COMMAND_NAMES) == {"comp575", "mit6837"}
    assert set(C.COMMAND_NAMES["mit6837"]) == {
        "eye", "lookat", "up", "fov", "viewport", "background", "surface", "sphere",
        "triangles", "v", "f", "end", "light"}
    assert "material" in C.COMMAND_NAMES["comp575"] and "surface" not in C.COMMAND_NAMES["comp575"]


def test_operand_names_and_positions():
    material = C.COMP575_COMMANDS["material"]
    assert material.names == ("r", "g", "b", "ka", "kd", "ks", "n", "kr", "kt", "eta")
    assert material.positions("color") == (1, 2, 3)
    assert material.positions("ior") == (10,)
    surface = C.MIT6837_COMMANDS["surface"]
    assert surface.names[-1] == "index" and surface.positions("phong_coeff") == (7,)
    assert C.MIT6837_COMMANDS["sphere"].names == ("cx", "cy", "cz", "r")


def test_every_material_field_has_an_operand_in_both_dialects():
    for dialect, name in C.MATERIAL_COMMAND.items():
        command = C.command_table(dialect)[name]
        assert {o.field for o in command.operands} == set(Material.FIELDS)


def test_the_6837_index_is_a_reciprocal():
    (index,) = C.MIT6837_COMMANDS["surface"].operand_for("ior")
    assert index.value(0.5) == 2.0 and index.written(2.0) == 0.5
    (eta,) = C.COMP575_COMMANDS["material"].operand_for("ior")
    assert eta.value(1.5) == 1.5


def test_light_positions():
    assert C.light_positions(LightKind.POINT, "color") == (1, 2, 3)
    assert C.light_positions(LightKind.POINT, "position") == (5, 6, 7)
    assert C.light_positions(LightKind.SPOT, "direction") == (8, 9, 10)
    assert C.light_positions(LightKind.SPOT, "shape_coefficient") == (11,)
    assert C.light_positions(LightKind.AMBIENT, "position") == ()
    assert C.light_fields(LightKind.SPOT) == ("color", "position", "direction", "shape_coefficient")
    assert C.LIGHT_KINDS["mit6837"] == (LightKind.AMBIENT, LightKind.POINT, LightKind.DIRECTIONAL)


@pytest.mark.parametrize("key, parsed", [
    ("mat3.color", C.ParamKey("mat", 3, "color")),
    ("light12.position", C.ParamKey("light", 12, "position")),
    ("background.color", C.ParamKey("background", None, "color")),
])
def test_param_keys_parse_and_print(key, parsed):
    assert C.ParamKey.parse(key) == parsed and str(parsed) == key


@pytest.mark.parametrize("key", ["mat.color", "mat1", "light1.", "background2.color", "x.y",
                                 "mat1.color.r", "MAT1.color"])
def test_bad_param_keys(key):
    with pytest.raises(ValueError, match="is not a parameter key"):
        C.ParamKey.parse(key)


def test_the_format_reference_names_every_command_of_both_tables():
    import os

    root = REPO
    with open(os.path.join(root, "docs", "format.md"), encoding="utf-8") as f:
        text = f.read()
    for dialect in C.DIALECTS:
        for name in C.command_table(dialect):
            assert f"`{name}" in text, name
    for word in C.LATER_6837_COMMANDS:
        assert f"`{word}`" in text
