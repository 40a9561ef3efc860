"""Tests of raymitsuba/model.py: diagnostics as printed, RayError, the defaults, immutability."""

from __future__ import annotations

import dataclasses

import pytest

from raymitsuba.model import (IDENTITY, Camera, Diagnostic, Light, LightKind, Material,
                              ObjectKind, RayError, Scene, SceneObject, Severity, Texture)


def diagnostic(column, source_line="sphere 1 2", severity=Severity.ERROR, message="oops"):
    return Diagnostic(severity, "scene.ray", 3, column, message, source_line)


# ---- Diagnostic.format -------------------------------------------------------------------


def test_format_is_file_line_column_severity_message_then_the_line_and_a_caret():
    assert diagnostic(8).format() == ("scene.ray:3:8: error: oops\n"
                                      "    sphere 1 2\n"
                                      "           ^")


@pytest.mark.parametrize("column", [1, 2, 7, 10, 11])
def test_the_caret_stands_under_the_column(column):
    quoted, caret = diagnostic(column).format().splitlines()[1:]
    assert caret.index("^") == column - 1 + 4  # both lines are indented by 4
    assert caret.strip() == "^"
    if column <= len("sphere 1 2"):
        assert quoted[caret.index("^")] == "sphere 1 2"[column - 1]


def test_a_caret_just_past_the_end_marks_a_missing_operand():
    caret = diagnostic(11).format().splitlines()[2]
    assert caret == " " * 4 + " " * len("sphere 1 2") + "^"


def test_a_tab_is_one_column_so_the_caret_still_lines_up():
    # columns count characters, a tab being one: the quoted line shows each tab as one space
    quoted, caret = diagnostic(9, "\tsphere\t1").format().splitlines()[1:]
    assert quoted == "     sphere 1"
    assert quoted[caret.index("^")] == "1"


def test_a_column_below_1_puts_the_caret_at_the_start():
    assert diagnostic(0).format().splitlines()[2] == "    ^"


def test_without_a_source_line_only_the_head_is_printed():
    assert diagnostic(1, source_line="").format() == "scene.ray:3:1: error: oops"


def test_warnings_say_warning_and_str_is_format():
    d = diagnostic(1, severity=Severity.WARNING, message="careful")
    assert d.format().startswith("scene.ray:3:1: warning: careful\n")
    assert str(d) == d.format()


# ---- RayError ----------------------------------------------------------------------------


def test_ray_error_carries_every_diagnostic_and_prints_them_all():
    error, warning = diagnostic(8), diagnostic(1, severity=Severity.WARNING, message="hm")
    exc = RayError([error, warning])
    assert exc.diagnostics == (error, warning)
    assert exc.errors == (error,)
    assert str(exc) == error.format() + "\n" + warning.format()


# ---- defaults: the format's --------------------------------------------------------------


def test_camera_defaults():
    assert Camera() == Camera(eye=(0.0, 0.0, 5.0), lookat=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0),
                              fov=45.0, line=None)


def test_the_default_material_is_material_1_1_1_1_1_0_1_0_0_1_numbered_0():
    m = Material()
    assert (m.color, m.ambient_mix, m.diffuse_mix, m.specular_mix, m.phong_coeff,
            m.reflectivity, m.refractivity, m.ior) == ((1, 1, 1), 1, 1, 0, 1, 0, 0, 1)
    assert m.index == 0 and m.line is None


def test_material_fields_are_its_parameters_in_the_format_order():
    names = [f.name for f in dataclasses.fields(Material)]
    assert Material.FIELDS == tuple(names[:8])
    assert names[8:] == ["index", "line", "column"]


def test_an_empty_scene_has_the_default_camera_material_and_black_background():
    scene = Scene(file="x.ray")
    assert scene.camera == Camera() and scene.materials == (Material(),)
    assert scene.background == (0.0, 0.0, 0.0)
    assert scene.objects == scene.lights == scene.warnings == ()


def test_kinds_are_spelled_as_in_the_format():
    assert [k.value for k in LightKind] == ["ambient", "point", "directional", "spotlight"]
    assert [k.value for k in ObjectKind] == ["sphere", "plane", "cylinder", "cone", "triangle"]


def test_identity_is_the_4x4_identity_row_major():
    assert IDENTITY == tuple(tuple(float(i == j) for j in range(4)) for i in range(4))


# ---- immutable values ----------------------------------------------------------------------


VALUES = [
    Camera(),
    Material(),
    Light(LightKind.POINT, (1.0, 1.0, 1.0), 1, 2, position=(0.0, 5.0, 0.0)),
    Texture("/tmp/t.png", "png"),
    SceneObject(ObjectKind.SPHERE, IDENTITY, 0, 1),
    Scene(file="x.ray"),
    diagnostic(1),
]


@pytest.mark.parametrize("value", VALUES, ids=lambda v: type(v).__name__)
def test_values_are_immutable_hashable_and_compare_by_value(value):
    name = dataclasses.fields(value)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(value, name, None)
    assert value == dataclasses.replace(value) and hash(value) == hash(dataclasses.replace(value))


@pytest.mark.parametrize("value", VALUES, ids=lambda v: type(v).__name__)
def test_values_have_no_per_instance_dict(value):
    # slots: a scene of a million lines holds hundreds of thousands of these
    assert not hasattr(value, "__dict__")


def test_maker_builds_what_init_builds():
    """model.maker (the parser's bulk path): the same record as __init__, field for field."""
    from raymitsuba.model import maker

    m = maker(Material)((0.5, -0.0, 1.0), 0.1, 0.2, 0.3, 4.0, 0.5, 0.6, 1.5, 3, 7, 2)
    assert m == Material((0.5, -0.0, 1.0), 0.1, 0.2, 0.3, 4.0, 0.5, 0.6, 1.5, 3, 7, 2)
    assert type(m) is Material and hash(m) == hash(Material((0.5, 0.0, 1.0), 0.1, 0.2, 0.3, 4.0,
                                                            0.5, 0.6, 1.5, 3, 7, 2))
    o = maker(SceneObject)(ObjectKind.SPHERE, IDENTITY, 0, 1, None, None, None)
    assert o == SceneObject(ObjectKind.SPHERE, IDENTITY, 0, 1)
    with pytest.raises(dataclasses.FrozenInstanceError):
        o.line = 2  # type: ignore[misc]
