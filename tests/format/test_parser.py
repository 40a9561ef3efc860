"""Tests of raymitsuba.format.parser against docs/format.md, rule by rule.

Scenes are written inline. Diagnostics are compared as (line, column, message
fragment); helpers at the top keep each test to the point.
"""

from __future__ import annotations

import math
import os
import struct
import zlib

import pytest

from raymitsuba.model import (IDENTITY, Camera, LightKind, Material, ObjectKind, RayError,
                              Scene, Severity, Texture)
from raymitsuba.format.parser import COMMANDS, LINE_END, parse, parse_file, parse_text, token_spans

LIT = "light 1 1 1 ambient\n"  # appended where a test does not want the "no light" warning


# ---- helpers ---------------------------------------------------------------------------


def ok(text, **kwargs) -> Scene:
    """Parse ``text``, which must be valid."""
    return parse_text(text, **kwargs)


def errors(text, **kwargs):
    """The errors of invalid ``text`` as (line, column, message)."""
    with pytest.raises(RayError) as info:
        parse_text(text, **kwargs)
    return [(d.line, d.column, d.message) for d in info.value.errors]


def error(text, **kwargs):
    """The single error of ``text`` as (line, column, message)."""
    found = errors(text, **kwargs)
    assert len(found) == 1, found
    return found[0]


def warnings(text, **kwargs):
    return [(d.line, d.column, d.message) for d in ok(text, **kwargs).warnings]


def apply(m, p):
    """The 4x4 row-major matrix ``m`` applied to the point ``p``."""
    return tuple(r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3] for r in m[:3])


def close(a, b, tol=1e-12):
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def only_object(text):
    scene = ok(text + "\n" + LIT)
    assert len(scene.objects) == 1
    return scene.objects[0]


def png_bytes(width=2, height=2) -> bytes:
    """A tiny valid RGB PNG, written by hand."""
    def chunk(kind, data):
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))
    raw = b"".join(b"\x00" + b"\x80\x40\x20" * width for _ in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


# ---- defaults ----------------------------------------------------------------------------


class TestDefaults:
    def test_empty_text_gives_every_default(self):
        scene = ok("")
        assert scene.camera == Camera(eye=(0, 0, 5), lookat=(0, 0, 0), up=(0, 1, 0), fov=45,
                                      line=None)
        assert scene.background == (0.0, 0.0, 0.0)
        assert scene.materials == (Material(),)
        assert scene.objects == () and scene.lights == () and scene.warnings == ()
        assert scene.file == "<string>"

    def test_default_material_is_1_1_1_1_1_0_1_0_0_1(self):
        m = ok("").materials[0]
        assert (m.color, m.ambient_mix, m.diffuse_mix, m.specular_mix, m.phong_coeff,
                m.reflectivity, m.refractivity, m.ior) == ((1, 1, 1), 1, 1, 0, 1, 0, 0, 1)
        assert m.index == 0

    def test_empty_file(self, tmp_path):
        path = tmp_path / "empty.ray"
        path.write_bytes(b"")
        scene = parse_file(path)
        assert scene.objects == () and scene.camera.eye == (0, 0, 5)
        assert scene.file == str(path)

    def test_blank_and_comment_lines_only(self):
        assert ok("\n   \n\t\n# a comment\n   # indented comment\n#\n").objects == ()

    def test_objects_start_with_identity_default_material_no_texture_no_checker(self):
        obj = only_object("plane")
        assert obj.to_world == IDENTITY
        assert (obj.material, obj.texture, obj.checker, obj.line) == (0, None, None, 1)


# ---- camera ----------------------------------------------------------------------------


class TestCamera:
    def test_values_and_line(self):
        cam = ok("eye 1 2 3\nlookat 4 5 6\nup 0 0 1\nfov 60\n").camera
        assert (cam.eye, cam.lookat, cam.up, cam.fov, cam.line) == (
            (1, 2, 3), (4, 5, 6), (0, 0, 1), 60, 4)

    def test_line_is_the_last_camera_command(self):
        assert ok("fov 30\neye 0 0 9\n\nsphere\n" + LIT).camera.line == 2

    @pytest.mark.parametrize("command", ["eye 0 0 9", "lookat 0 1 0", "up 1 1 0", "fov 50"])
    def test_repeated_camera_command_warns_and_last_wins(self, command):
        name = command.split()[0]
        first = {"eye": "eye 0 0 7", "lookat": "lookat 0 0 1", "up": "up 0 1 1",
                 "fov": "fov 20"}[name]
        scene = ok(f"{first}\n# between\n  {command}\n")
        (w,) = scene.warnings
        assert (w.severity, w.line, w.column) == (Severity.WARNING, 3, 3)
        assert f"`{name}` given again" in w.message and "line 1" in w.message
        assert getattr(scene.camera, name) == tuple(float(v) for v in command.split()[1:]) \
            or getattr(scene.camera, name) == float(command.split()[1])

    @pytest.mark.parametrize("fov", ["0", "180", "200", "-5", "0.0", "-0"])
    def test_fov_outside_open_interval_is_an_error_at_its_operand(self, fov):
        line, column, message = error(f"\nfov {fov}\n")
        assert (line, column) == (2, 5)
        assert "between 0 and 180" in message

    @pytest.mark.parametrize("fov", ["1e-9", "0.5", "179.999"])
    def test_fov_inside_interval(self, fov):
        assert ok(f"fov {fov}").camera.fov == float(fov)

    def test_eye_equal_to_lookat_reported_at_the_later_line(self):
        assert error("eye 1 1 1\nsphere\n  lookat 1 1 1\n")[:2] == (3, 3)
        assert error("lookat 1 1 1\neye 1 1 1\n")[:2] == (2, 1)

    def test_eye_equal_to_default_lookat(self):
        line, column, message = error("fov 40\neye 0 0 0\n")
        assert (line, column) == (2, 1) and "same point" in message

    def test_up_parallel_to_view_direction(self):
        line, column, message = error("up 0 0 1\neye 0 0 5\nlookat 0 0 -2\n")
        assert (line, column) == (3, 1) and "parallel" in message

    def test_up_parallel_reported_at_up_when_up_is_last(self):
        assert error("eye 0 5 0\nup 0 -3 0\n")[:2] == (2, 1)

    def test_up_zero_vector(self):
        line, _, message = error("up 0 0 0")
        assert line == 1 and "zero vector" in message

    def test_nearly_parallel_up_is_accepted(self):
        assert ok("eye 0 10 0\nup 0 1 1e-6\n").camera.up == (0, 1, 1e-6)

    def test_far_apart_eye_and_lookat_do_not_overflow(self):
        cam = ok("eye 1e308 0 0\nlookat -1e308 0 0\n").camera
        assert cam.eye == (1e308, 0, 0)
        assert "parallel" in error("eye 0 1e308 0\nlookat 0 -1e308 0\n")[2]


class TestBackground:
    def test_value(self):
        assert ok("background 0.1 0.2 0.3").background == (0.1, 0.2, 0.3)

    def test_negative_component_warns_at_it(self):
        assert warnings("background 0 -1 0") == [(1, 14, "negative `g` (-1) in `background`")]

    def test_repeated_background_warns_and_last_wins(self):
        scene = ok("background 1 1 1\nbackground 0 0 1\n")
        assert scene.background == (0, 0, 1)
        assert [(w.line, w.column) for w in scene.warnings] == [(2, 1)]


# ---- objects -----------------------------------------------------------------------------


class TestObjects:
    @pytest.mark.parametrize("kind", ["sphere", "plane", "cylinder", "cone"])
    def test_each_primitive(self, kind):
        obj = only_object(kind)
        assert obj.kind is ObjectKind(kind) and obj.vertices is None

    def test_triangle_corners_in_object_space(self):
        obj = only_object("translate 1 0 0\ntriangle 0 0 0 1 0 0 0 1 0")
        assert obj.kind is ObjectKind.TRIANGLE
        assert obj.vertices == ((0, 0, 0), (1, 0, 0), (0, 1, 0))
        assert apply(obj.to_world, obj.vertices[1]) == (2, 0, 0)

    def test_objects_in_file_order_with_lines(self):
        scene = ok("sphere\n\ncone\ncylinder\n" + LIT)
        assert [(o.kind.value, o.line) for o in scene.objects] == [
            ("sphere", 1), ("cone", 3), ("cylinder", 4)]

    def test_zero_area_triangle_warns(self):
        assert warnings("triangle 0 0 0 1 1 1 2 2 2\n" + LIT) == [
            (1, 1, "zero-area triangle: its corners are collinear (it will not be visible)")]
        assert warnings("triangle 1 2 3 1 2 3 4 5 6\n" + LIT)[0][:2] == (1, 1)

    @pytest.mark.parametrize("line, column, found", [
        ("sphere 1", 8, 1), ("plane x y", 7, 2), ("cone 0", 6, 1), ("cylinder 1 2 3", 10, 3)])
    def test_primitives_take_no_operands(self, line, column, found):
        kind = line.split()[0]
        # forced: with operands, a `sphere` marks a file as MIT 6.837 (tests/format/test_parser_6837.py)
        assert error(line + "\n" + LIT, dialect="comp575") == (
            1, column, f"`{kind}` takes no operands, found {found}")

    def test_triangle_operand_count(self):
        assert error("triangle 0 0 0 1 0 0 0 1\n") == (
            1, 25, "`triangle` takes 9 operands (x0 y0 z0 x1 y1 z1 x2 y2 z2), found 8")

    def test_triangle_beyond_float_range_is_an_error(self):
        line, _, message = error("scale 1e300 1 1\ntriangle 0 0 0 1e10 0 0 0 1 0\n" + LIT)
        assert line == 2 and "floating-point range" in message


# ---- the transform stack ------------------------------------------------------------------


class TestTransformStack:
    def test_worked_example_translate_then_scale(self):
        obj = only_object("translate 2 0 0\nscale 2 2 2\nsphere")
        assert obj.to_world == ((2, 0, 0, 4), (0, 2, 0, 0), (0, 0, 2, 0), (0, 0, 0, 1))
        assert apply(obj.to_world, (0, 0, 0)) == (4, 0, 0)  # centre
        assert apply(obj.to_world, (1, 0, 0)) == (6, 0, 0)  # radius 2

    def test_worked_example_scale_then_translate(self):
        obj = only_object("scale 2 2 2\ntranslate 2 0 0\nsphere")
        assert apply(obj.to_world, (0, 0, 0)) == (2, 0, 0)
        assert apply(obj.to_world, (1, 0, 0)) == (4, 0, 0)

    @pytest.mark.parametrize("command, point, image", [
        ("rotateZ 90", (1, 0, 0), (0, 1, 0)),
        ("rotateZ 90", (0, 1, 0), (-1, 0, 0)),
        ("rotateX 90", (0, 1, 0), (0, 0, 1)),
        ("rotateX 90", (0, 0, 1), (0, -1, 0)),
        ("rotateY 90", (0, 0, 1), (1, 0, 0)),
        ("rotateY 90", (1, 0, 0), (0, 0, -1)),
        ("rotateZ -90", (1, 0, 0), (0, -1, 0)),
        ("rotateZ 180", (1, 0, 0), (-1, 0, 0)),
        ("rotateZ 450", (1, 0, 0), (0, 1, 0)),
        ("rotateY 360", (1, 2, 3), (1, 2, 3)),
    ])
    def test_rotations_are_right_handed_and_exact_at_quarter_turns(self, command, point, image):
        assert apply(only_object(command + "\nsphere").to_world, point) == image

    def test_rotation_by_an_arbitrary_angle(self):
        m = only_object("rotateZ 30\nsphere").to_world
        c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
        assert close(apply(m, (1, 0, 0)), (c, s, 0))
        assert close(apply(m, (0, 1, 0)), (-s, c, 0))

    def test_translate_then_rotate(self):
        m = only_object("translate 1 0 0\nrotateZ 90\nsphere").to_world
        assert apply(m, (0, 0, 0)) == (0, 1, 0)

    def test_rotate_then_translate(self):
        m = only_object("rotateZ 90\ntranslate 1 0 0\nsphere").to_world
        assert apply(m, (0, 0, 0)) == (1, 0, 0)
        assert apply(m, (1, 0, 0)) == (1, 1, 0)

    def test_worked_example_cylinder(self):
        m = only_object("translate 0 0 -3\nrotateY 90\nscale 1 2 1\ncylinder").to_world
        assert apply(m, (0, 0, 0)) == (-3, 0, 0)
        assert apply(m, (0, 0.5, 0)) == (-3, 1, 0)  # top cap centre: height 2
        assert apply(m, (0, 0, 1)) == (-2, 0, 0)  # a rim point: radius 1

    def test_three_transforms_compose_newest_on_the_left(self):
        m = only_object("scale 1 2 3\nrotateX 90\ntranslate 10 20 30\nsphere").to_world
        # p -> scale -> rotateX 90 ((x, y, z) -> (x, -z, y)) -> translate
        assert apply(m, (1, 1, 1)) == (11, 17, 32)

    def test_non_uniform_scale(self):
        assert only_object("scale 1 2 3\nsphere").to_world == (
            (1, 0, 0, 0), (0, 2, 0, 0), (0, 0, 3, 0), (0, 0, 0, 1))

    def test_pop_removes_the_most_recent(self):
        scene = ok("translate 5 0 0\nscale 3 3 3\nsphere\npop\nsphere\npop\nsphere\n" + LIT)
        centres = [apply(o.to_world, (0, 0, 0)) for o in scene.objects]
        edges = [apply(o.to_world, (1, 0, 0)) for o in scene.objects]
        assert centres == [(15, 0, 0), (5, 0, 0), (0, 0, 0)]
        assert edges == [(18, 0, 0), (6, 0, 0), (1, 0, 0)]
        assert scene.objects[2].to_world == IDENTITY

    def test_reset_empties_the_stack(self):
        scene = ok("translate 1 2 3\nrotateY 30\nreset\nsphere\n" + LIT)
        assert scene.objects[0].to_world == IDENTITY

    def test_pop_on_an_empty_stack(self):
        assert error("\n  pop\n") == (2, 3, "`pop` on an empty transform stack "
                                             "(nothing has been pushed since the start or `reset`)")

    def test_pop_after_reset_is_an_error(self):
        assert error("translate 1 0 0\nreset\npop\n")[:2] == (3, 1)

    def test_one_pop_too_many(self):
        assert error("scale 2 2 2\npop\npop\n")[:2] == (3, 1)

    def test_stack_does_not_affect_lights_or_camera(self):
        scene = ok("translate 9 9 9\neye 1 2 3\nlight 1 1 1 point 4 5 6\n")
        assert scene.camera.eye == (1, 2, 3) and scene.lights[0].position == (4, 5, 6)

    @pytest.mark.parametrize("line, column, axis", [
        ("scale 0 1 1", 7, "x"), ("scale 1 0 1", 9, "y"), ("scale 1 1 -0", 11, "z")])
    def test_zero_scale_factor(self, line, column, axis):
        assert error(line) == (1, column, f"`scale` factor `{axis}` is zero; "
                                          f"a scale must be invertible")

    def test_negative_scale_is_fine(self):
        assert apply(only_object("scale -1 1 1\nsphere").to_world, (1, 0, 0)) == (-1, 0, 0)

    def test_transform_overflow(self):
        line, column, message = error("translate 1e308 0 0\ntranslate 1e308 0 0\n")
        assert (line, column) == (2, 1) and "overflow or become singular" in message

    def test_transform_underflow_to_singular(self):
        assert error("scale 1e-200 1 1\nscale 1e-200 1 1\n")[:2] == (2, 1)

    def test_bad_transform_line_still_pushes_so_pops_match(self):
        assert errors("translate 1 x 3\nrotateX\npop\npop\n") == [
            (1, 13, "expected a number for `y` of `translate`, found `x`"),
            (2, 8, "`rotateX` takes 1 operand (theta), found 0")]


# ---- lights ------------------------------------------------------------------------------


class TestLights:
    def test_every_kind(self):
        scene = ok("light 0.1 0.2 0.3 ambient\n"
                   "light 1 1 1 point 1 2 3\n"
                   "light 0.5 0.5 0.5 directional 0 -1 0\n"
                   "light 1 0 0 spotlight 0 5 0 0 -1 0 8\n")
        amb, point, direc, spot = scene.lights
        assert (amb.kind, amb.color, amb.index, amb.line) == (LightKind.AMBIENT, (0.1, 0.2, 0.3), 1, 1)
        assert amb.position is amb.direction is amb.shape is None
        assert (point.kind, point.position, point.direction, point.index) == (
            LightKind.POINT, (1, 2, 3), None, 2)
        assert (direc.kind, direc.direction, direc.position) == (
            LightKind.DIRECTIONAL, (0, -1, 0), None)
        assert (spot.kind, spot.position, spot.direction, spot.shape, spot.index, spot.line) == (
            LightKind.SPOT, (0, 5, 0), (0, -1, 0), 8, 4, 4)

    def test_directions_are_kept_as_written(self):
        assert ok("light 1 1 1 directional 0 -7 0").lights[0].direction == (0, -7, 0)

    def test_kinds_are_case_insensitive(self):
        scene = ok("light 1 1 1 Point 0 0 0\nLIGHT 1 1 1 AMBIENT\nlight 1 1 1 SpotLight 0 0 0 1 0 0 0\n")
        assert [li.kind for li in scene.lights] == [LightKind.POINT, LightKind.AMBIENT,
                                                     LightKind.SPOT]

    @pytest.mark.parametrize("direction", ["0 0 0", "-0 0 -0", "0.0 0e5 0"])
    def test_zero_directional(self, direction):
        assert error(f"light 1 1 1 directional {direction}") == (
            1, 25, "a directional light's direction (x y z) must not be the zero vector")

    def test_zero_spot_axis(self):
        assert error("light 1 1 1 spotlight 0 5 0 0 0 0 1") == (
            1, 29, "a spotlight's axis (x' y' z') must not be the zero vector")

    def test_negative_spot_shape(self):
        assert error("light 1 1 1 spotlight 0 5 0 0 -1 0 -2") == (
            1, 36, "a spotlight's shape coefficient `s` must be >= 0, found -2")

    def test_zero_spot_shape_is_fine(self):
        assert ok("light 1 1 1 spotlight 0 5 0 0 -1 0 0").lights[0].shape == 0

    def test_negative_color_warns(self):
        assert warnings("light 1 -0.5 1 ambient") == [(1, 9, "negative `g` (-0.5) in a light's color")]

    def test_unknown_kind_with_suggestion(self):
        assert error("light 1 1 1 pont 0 0 0") == (1, 13, "unknown light kind `pont`; "
                                                          "did you mean `point`?")

    def test_unknown_kind_without_suggestion(self):
        assert error("light 1 1 1 zzzz")[2] == ("unknown light kind `zzzz`; expected ambient, "
                                                "point, directional or spotlight")

    def test_kind_after_too_few_color_operands(self):
        assert error("light 1 1 point 0 0 0") == (
            1, 11, "`light` takes 3 color operands (r g b) before the kind `point`, found 2")

    def test_missing_kind(self):
        assert error("light 1 1 1  # no kind") == (
            1, 12, "`light` takes a color r g b and then a kind (ambient, point, directional "
                   "or spotlight), found 3 operands")

    @pytest.mark.parametrize("line, column, message", [
        ("light 1 1 1 point 0 0", 22, "`light ... point` takes 3 operands (x y z), found 2"),
        ("light 1 1 1 ambient 3", 21, "`light ... ambient` takes no operands, found 1"),
        ("light 1 1 1 directional 1 2 3 4", 31,
         "`light ... directional` takes 3 operands (x y z), found 4"),
        ("light 1 1 1 spotlight 0 0 0 1 1 1", 34,
         "`light ... spotlight` takes 7 operands (x y z x' y' z' s), found 6"),
    ])
    def test_operand_count_per_kind(self, line, column, message):
        assert error(line) == (1, column, message)

    def test_non_number_in_color(self):
        assert error("light 1 one 1 ambient") == (
            1, 9, "expected a number for `g` of `light`, found `one`")


# ---- materials ---------------------------------------------------------------------------


class TestMaterials:
    def test_fields_and_numbering(self):
        scene = ok("sphere\nmaterial 0.1 0.2 0.3 0.4 0.5 0.6 7 0.8 0.9 1.5\ncone\n"
                   "material 1 1 1 0 1 0 1 0 0 1\nplane\n" + LIT)
        m1 = scene.materials[1]
        assert (m1.color, m1.ambient_mix, m1.diffuse_mix, m1.specular_mix, m1.phong_coeff,
                m1.reflectivity, m1.refractivity, m1.ior, m1.index, m1.line) == (
            (0.1, 0.2, 0.3), 0.4, 0.5, 0.6, 7, 0.8, 0.9, 1.5, 1, 2)
        assert scene.materials[2].index == 2
        assert [o.material for o in scene.objects] == [0, 1, 2]

    def test_negative_phong_coefficient(self):
        assert error("material 1 1 1 1 1 1 -1 0 0 1") == (
            1, 22, "the Phong coefficient `n` must be >= 0, found -1")

    @pytest.mark.parametrize("eta", ["0", "-1.5", "-0"])
    def test_eta_not_positive(self, eta):
        assert error(f"material 1 1 1 1 1 1 1 0 0 {eta}") == (
            1, 28, f"the index of refraction `eta` must be > 0, found {float(eta):g}")

    def test_phong_zero_is_fine(self):
        assert ok("material 1 1 1 1 1 1 0 0 0 1").materials[1].phong_coeff == 0

    def test_negative_values_warn_each(self):
        assert warnings("material -1 1 1 1 -0.5 1 1 0 -2 1") == [
            (1, 10, "negative `r` (-1) in `material`"),
            (1, 19, "negative `kd` (-0.5) in `material`"),
            (1, 30, "negative `kt` (-2) in `material`")]

    def test_operand_count(self):
        assert error("material 1 1 1 1 1 1 1 0 0") == (
            1, 27, "`material` takes 10 operands (r g b ka kd ks n kr kt eta), found 9")


# ---- lexical rules -----------------------------------------------------------------------


class TestLexical:
    @pytest.mark.parametrize("command", ["rotateX 10", "rotatex 10", "ROTATEX 10", "RoTaTeX 10"])
    def test_command_names_are_case_insensitive(self, command):
        assert only_object(command + "\nsphere").to_world == only_object("rotateX 10\nsphere").to_world

    def test_every_command_in_upper_case(self, tmp_path):
        (tmp_path / "t.png").write_bytes(png_bytes())
        text = ("EYE 0 0 9\nLOOKAT 0 0 0\nUP 0 1 0\nFOV 30\nBACKGROUND 0 0 0\nSPHERE\nPLANE\n"
                "CYLINDER\nCONE\nTRIANGLE 0 0 0 1 0 0 0 1 0\nLIGHT 1 1 1 AMBIENT\n"
                "TRANSLATE 1 1 1\nSCALE 1 1 1\nROTATEX 1\nROTATEY 1\nROTATEZ 1\nPOP\nRESET\n"
                "MATERIAL 1 1 1 1 1 1 1 1 1 1\nTEXTURE t.png\nTEXTURE NONE\nCHECKERBOARD 1\n")
        scene = ok(text, base_dir=str(tmp_path))
        assert len(scene.objects) == 5 and scene.camera.fov == 30

    def test_the_vocabulary(self):
        assert set(COMMANDS) == {"eye", "lookat", "up", "fov", "background", "sphere", "plane",
                                 "cylinder", "cone", "triangle", "light", "translate", "scale",
                                 "rotateX", "rotateY", "rotateZ", "reset", "pop", "material",
                                 "texture", "checkerboard"}

    def test_trailing_comments(self):
        scene = ok("sphere # a ball\ntranslate 1 2 3 #move\nsphere\t#tabbed\n" + LIT)
        assert len(scene.objects) == 2
        assert apply(scene.objects[1].to_world, (0, 0, 0)) == (1, 2, 3)

    def test_hash_inside_a_token_is_not_a_comment(self):
        assert error("sphere#x")[2].startswith("unknown command `sphere#x`")
        assert error("translate 1 2 3#x")[:2] == (1, 15)

    def test_tabs_separate_tokens(self):
        assert apply(only_object("\ttranslate\t1 \t2\t3\nsphere").to_world, (0, 0, 0)) == (1, 2, 3)

    @pytest.mark.parametrize("ending", ["\n", "\r\n", "\r"])
    def test_line_endings(self, ending):
        text = ending.join(["sphere", "", "bogus", "cone", LIT.strip()]) + ending
        with pytest.raises(RayError) as info:
            parse_text(text)
        assert [(d.line, d.column) for d in info.value.errors] == [(3, 1)]
        assert info.value.errors[0].source_line == "bogus"

    def test_mixed_line_endings(self):
        scene = ok("sphere\r\ncone\rplane\ncylinder\r\n\r" + LIT)
        assert [o.line for o in scene.objects] == [1, 2, 3, 4]

    @pytest.mark.parametrize("literal, value", [
        ("1", 1.0), ("+1", 1.0), ("1.", 1.0), ("-0.5", -0.5), (".5", 0.5), ("1e-3", 0.001),
        ("1E3", 1000.0), ("-.25e+2", -25.0), ("007", 7.0), ("1_000", 1000.0), ("1e-400", 0.0)])
    def test_float_forms(self, literal, value):
        assert ok(f"fov 45\nbackground {literal} 0 0").background[0] == value

    @pytest.mark.parametrize("literal, reason", [
        ("nan", "(nan and infinity are not allowed)"),
        ("-inf", "(nan and infinity are not allowed)"),
        ("Infinity", "(nan and infinity are not allowed)"),
        ("+NaN", "(nan and infinity are not allowed)"),
        ("1e400", "(too large for a double)"),
        ("-1e309", "(too large for a double)"),
        ("abc", ""), ("1..2", ""), ("0x10", ""), ("1,5", ""), ("--1", ""),
        ("\u0661", "(numbers are written in ASCII digits)"),
    ])
    def test_rejected_numbers(self, literal, reason):
        assert error(f"translate 1 {literal} 3") == (
            1, 13, f"expected a number for `y` of `translate`, found `{literal}`"
                   + (f" {reason}" if reason else ""))

    def test_utf8_byte_order_mark_is_ignored(self):
        assert len(parse_text("\ufeffsphere\n" + LIT).objects) == 1
        assert len(parse_text(b"\xef\xbb\xbfsphere\n" + LIT.encode()).objects) == 1

    def test_invalid_utf8_is_an_error_at_its_column(self):
        data = b"sphere\nlight 1 1 1 ambient\n  \xc3\xa9 \xff sphere\n\xe2\x82\n"
        with pytest.raises(RayError) as info:
            parse_text(data)
        assert [(d.line, d.column) for d in info.value.errors] == [(3, 5), (4, 1)]
        assert "invalid UTF-8 (byte ff)" in info.value.errors[0].message

    def test_invalid_utf8_does_not_hide_other_errors(self):
        with pytest.raises(RayError) as info:
            parse_text(b"\xff\npop\n")
        assert [(d.line, d.column) for d in info.value.errors] == [(1, 1), (2, 1)]

    def test_non_ascii_text_elsewhere_is_fine(self):
        assert ok("# \u00e9t\u00e9 \u2603\nsphere # caf\u00e9\n" + LIT).objects[0].line == 2

    def test_non_ascii_space_is_part_of_a_token(self):
        assert error("sphere\u00a0\n" + LIT)[2].startswith("unknown command `sphere\u00a0`")

    @pytest.mark.parametrize("char, what", [("\0", "a NUL byte"), ("\x0c", "a control character"),
                                            ("\x1b", "a control character"),
                                            ("\x85", "a control character"),
                                            ("\ud800", "a lone surrogate")])
    def test_forbidden_characters(self, char, what):
        line, column, message = error(f"sphere\nsphe{char}re\n" + LIT)
        assert (line, column) == (2, 5)
        assert message.startswith(what) and f"U+{ord(char):04X}" in message

    def test_nul_byte_in_a_file(self, tmp_path):
        path = tmp_path / "nul.ray"
        path.write_bytes(b"eye 0 0\x00 5\n")
        with pytest.raises(RayError) as info:
            parse_file(path)
        (d,) = info.value.errors
        assert (d.line, d.column) == (1, 8) and d.file == str(path)

    # The same rules, exported for tools that edit .RAY text in place (raymitsuba.fit).

    def test_token_spans_are_the_command_and_operands_before_a_comment(self):
        line = "material\t1 2  3 # 4 5"
        assert [line[a:b] for a, b in token_spans(line)] == ["material", "1", "2", "3"]
        assert token_spans("   # only a comment") == [] and token_spans("") == []
        assert token_spans("a#b c") == [(0, 3), (4, 5)]  # a # inside a token is not a comment

    def test_token_spans_keep_unicode_spaces_inside_tokens(self):
        line = "texture my\u00a0file.png"
        assert [line[a:b] for a, b in token_spans(line)] == ["texture", "my\u00a0file.png"]

    def test_line_end_is_cr_lf_cr_or_lf_and_nothing_else(self):
        text = "a\r\nb\rc\nd\x0be\x0cf\u2028g"
        assert LINE_END.split(text) == ["a", "b", "c", "d\x0be\x0cf\u2028g"]


# ---- errors ----------------------------------------------------------------------------


class TestErrors:
    def test_unknown_command_suggests_the_closest(self):
        assert error("rotatey2 90") == (1, 1, "unknown command `rotatey2`; did you mean `rotateY`?")
        assert error("  spere")[1:] == (3, "unknown command `spere`; did you mean `sphere`?")
        assert error("LookAtt 0 0 0")[2].endswith("did you mean `lookat`?")

    def test_unknown_command_far_from_everything_lists_the_commands(self):
        message = error("xyzzy")[2]
        assert message.startswith("unknown command `xyzzy`; the commands are eye, lookat")
        assert all(name in message for name in COMMANDS)

    def test_too_few_operands_points_past_the_last_token(self):
        assert error("translate 1 2") == (1, 14, "`translate` takes 3 operands (x y z), found 2")
        assert error("translate 1 2   # comment") == (1, 14, "`translate` takes 3 operands (x y z), found 2")
        assert error("fov") == (1, 4, "`fov` takes 1 operand (theta), found 0")

    def test_too_many_operands_points_at_the_first_extra(self):
        assert error("eye 1 2 3 4 5") == (1, 11, "`eye` takes 3 operands (x y z), found 5")
        assert error("reset now") == (1, 7, "`reset` takes no operands, found 1")

    def test_every_non_number_of_a_line_is_reported(self):
        assert errors("scale a 1 b") == [
            (1, 7, "expected a number for `x` of `scale`, found `a`"),
            (1, 11, "expected a number for `z` of `scale`, found `b`")]

    def test_several_errors_in_one_pass(self):
        text = ("eye 0 0 5\n"          # 1
                "rotatey2 3\n"         # 2 unknown command
                "sphere\n"             # 3
                "translate 1 2\n"      # 4 too few
                "pop\n"                # 5 fine: the bad translate pushed a no-op
                "pop\n"                # 6 empty stack
                "scale 1 0 1\n"        # 7 zero scale
                "material 1 1 1 1 1 1 -1 0 0 0\n"  # 8 n < 0 and eta <= 0
                "light 1 1 1 directional 0 0 0\n"  # 9 zero direction
                "fov 180\n"            # 10 fov
                "lookat 0 0 5\n")      # 11 eye == lookat
        assert [(line, column) for line, column, _ in errors(text)] == [
            (2, 1), (4, 14), (6, 1), (7, 9), (8, 22), (8, 29), (9, 25), (10, 5), (11, 1)]

    def test_error_carries_warnings_too_sorted_by_position(self):
        with pytest.raises(RayError) as info:
            parse_text("eye 0 0 4\neye 0 0 3\nbogus\nbackground -1 0 0\n")
        kinds = [(d.line, d.severity) for d in info.value.diagnostics]
        assert kinds == [(2, Severity.WARNING), (3, Severity.ERROR), (4, Severity.WARNING)]
        assert len(info.value.errors) == 1

    def test_diagnostic_fields_and_format(self):
        with pytest.raises(RayError) as info:
            parse_text("sphere\n\ttranslate 1 two 3\n", file="scene.ray")
        d = info.value.errors[0]
        assert (d.file, d.line, d.column, d.source_line) == ("scene.ray", 2, 14, "\ttranslate 1 two 3")
        assert d.format() == ("scene.ray:2:14: error: expected a number for `y` of `translate`, "
                              "found `two`\n     translate 1 two 3\n                 ^")
        assert str(info.value).startswith("scene.ray:1:1: warning: the scene has objects but no light")


# ---- textures and checkerboard -------------------------------------------------------------


@pytest.fixture
def images(tmp_path):
    """A directory of tiny files, one per accepted format, plus some that are not images."""
    files = {
        "wood.png": png_bytes(),
        "photo.jpg": b"\xff\xd8\xff\xe0" + b"\0" * 16,
        "sky.exr": b"\x76\x2f\x31\x01" + b"\0" * 16,
        "sun.hdr": b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n",
        "sun2.hdr": b"#?RGBE\n",
        "depth.pfm": b"PF\n2 2\n-1\n",
        "grey.pfm": b"Pf 2 2 -1\n",
        "ascii.ppm": b"P3\n1 1\n255\n0 0 0\n",
        "raw.ppm": b"P6\n1 1\n255\n\0\0\0",
        "bits.pbm": b"P1 1 1 0",
        "grey.pgm": b"P5\n1 1\n255\n\0",
        "paint.bmp": b"BM" + b"\0" * 30,
        "old.tga": bytes([0, 0, 2]) + b"\0" * 15 + b"\0\0\0\0",
        "photo.fsf": png_bytes(),
        "garbage.fsf": b"FSF1 this is not an image at all",
        "tga_bytes.png": bytes([0, 0, 2]) + b"\0" * 20,
        "bad_header.tga": bytes([0, 7, 99]) + b"\0" * 20,
        "short.tga": bytes([0, 0, 2]),
        "empty.png": b"",
        "notes.txt": b"P7 is not netpbm\n",
        "my file #1.png": png_bytes(),
    }
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
    return tmp_path


class TestTextures:
    @pytest.mark.parametrize("name, fmt", [
        ("wood.png", "png"), ("photo.jpg", "jpeg"), ("sky.exr", "exr"), ("sun.hdr", "hdr"),
        ("sun2.hdr", "hdr"), ("depth.pfm", "pfm"), ("grey.pfm", "pfm"), ("ascii.ppm", "ppm"),
        ("raw.ppm", "ppm"), ("bits.pbm", "ppm"), ("grey.pgm", "ppm"), ("paint.bmp", "bmp"),
        ("old.tga", "tga"), ("photo.fsf", "png")])
    def test_accepted_formats_detected_from_contents(self, images, name, fmt):
        obj = ok(f"texture {name}\nsphere\n" + LIT, base_dir=str(images)).objects[0]
        assert obj.texture == Texture(path=str(images / name), format=fmt)

    @pytest.mark.parametrize("name", ["garbage.fsf", "tga_bytes.png", "bad_header.tga",
                                      "short.tga", "empty.png", "notes.txt"])
    def test_rejected_contents_list_the_accepted_formats(self, images, name):
        line, column, message = error(f"sphere\ntexture {name}\n" + LIT, base_dir=str(images))
        assert (line, column) == (2, 9)
        assert message.startswith(f"texture file `{name}` is not an image in an accepted format")
        for fmt in ("EXR", "HDR", "PFM", "PNG", "JPEG", "PPM", "BMP", "TGA"):
            assert fmt in message

    def test_missing_texture_file(self, tmp_path):
        line, column, message = error("texture  nothere.png  # c", base_dir=str(tmp_path))
        assert (line, column) == (1, 10)
        assert message == (f"texture file `nothere.png` not found "
                           f"(looked for {tmp_path / 'nothere.png'})")

    def test_directory_is_not_a_texture(self, tmp_path):
        (tmp_path / "dir.png").mkdir()
        assert "cannot read texture file `dir.png`" in error("texture dir.png",
                                                             base_dir=str(tmp_path))[2]

    @pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
    def test_fifo_is_not_a_texture_and_does_not_hang(self, tmp_path):
        os.mkfifo(tmp_path / "pipe.png")
        assert "not a regular file" in error("texture pipe.png", base_dir=str(tmp_path))[2]

    def test_symlink_loop_is_unreadable(self, tmp_path):
        (tmp_path / "loop.png").symlink_to(tmp_path / "loop.png")
        line, column, message = error("texture loop.png", base_dir=str(tmp_path))
        assert (line, column) == (1, 9)
        assert message.startswith(f"cannot read texture file `loop.png` ({tmp_path / 'loop.png'}):")

    def test_overlong_name_is_unreadable(self, tmp_path):
        assert "cannot read texture file" in error("texture " + "a" * 5000 + ".png",
                                                   base_dir=str(tmp_path))[2]

    @pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0,
                        reason="needs a non-root POSIX user for file permissions")
    def test_unreadable_texture(self, images):
        path = images / "wood.png"
        path.chmod(0)
        try:
            assert "cannot read texture file `wood.png`" in error(
                "texture wood.png", base_dir=str(images))[2]
        finally:
            path.chmod(0o644)

    def test_relative_path_resolves_against_the_scene_file(self, images, tmp_path, monkeypatch):
        scenes = tmp_path / "scenes"
        scenes.mkdir()
        (scenes / "tex").mkdir()
        (scenes / "tex" / "a.png").write_bytes(png_bytes())
        (scenes / "s.ray").write_text("texture tex/a.png\nsphere\n" + LIT)
        monkeypatch.chdir(images)
        assert parse_file(scenes / "s.ray").objects[0].texture.path == str(scenes / "tex" / "a.png")

    def test_text_resolves_against_cwd_by_default(self, images, monkeypatch):
        monkeypatch.chdir(images)
        assert ok("texture wood.png\nsphere\n" + LIT).objects[0].texture.path == str(images / "wood.png")

    def test_absolute_path(self, images):
        path = images / "wood.png"
        assert ok(f"texture {path}\nsphere\n" + LIT, base_dir="/nonexistent").objects[0].texture.path == str(path)

    def test_quoted_filename_with_spaces_and_hash(self, images):
        scene = ok('texture   "my file #1.png"   # the quoted name\nsphere\n' + LIT,
                   base_dir=str(images))
        assert scene.objects[0].texture.path == str(images / "my file #1.png")

    def test_unquoted_filename_keeps_inner_spaces_up_to_a_comment(self, images):
        (images / "my wood.png").write_bytes(png_bytes())
        scene = ok("texture my wood.png  # oak\nsphere\n" + LIT, base_dir=str(images))
        assert scene.objects[0].texture.path == str(images / "my wood.png")

    def test_texture_applies_to_later_objects_until_none(self, images):
        scene = ok("sphere\ntexture wood.png\ncone\nplane\nTexture NONE\ncylinder\n" + LIT,
                   base_dir=str(images))
        formats = [o.texture and o.texture.format for o in scene.objects]
        assert formats == [None, "png", "png", None]

    def test_quoted_none_is_a_file(self, images):
        assert "texture file `none` not found" in error('texture "none"', base_dir=str(images))[2]

    @pytest.mark.parametrize("line, column, message", [
        ('texture "a b.png', 9, 'unterminated quoted filename: the closing `"` is missing'),
        ('texture "wood.png" extra', 20, "unexpected text `extra` after the quoted filename"),
        ('texture ""', 9, "the quoted filename is empty"),
        ("texture", 8, "`texture` takes a filename (or `none`), found nothing"),
        ("texture   # only a comment", 8, "`texture` takes a filename (or `none`), found nothing"),
    ])
    def test_filename_syntax_errors(self, images, line, column, message):
        assert error(line, base_dir=str(images)) == (1, column, message)

    def test_checkerboard_only_on_planes(self):
        scene = ok("plane\ncheckerboard 0.5\nplane\nsphere\ncheckerboard -1\nplane\n"
                   "checkerboard 2\ncheckerboard 0\nplane\n" + LIT)
        assert [o.checker for o in scene.objects] == [None, 0.5, None, None, None]

    def test_checkerboard_operands(self):
        assert error("checkerboard") == (1, 13, "`checkerboard` takes 1 operand (size), found 0")


# ---- entry points --------------------------------------------------------------------------


class TestEntryPoints:
    def test_parse_file_missing(self, tmp_path):
        with pytest.raises(RayError) as info:
            parse_file(tmp_path / "missing.ray")
        (d,) = info.value.errors
        assert (d.line, d.column) == (1, 1) and "cannot read the scene file" in d.message

    def test_parse_file_directory(self, tmp_path):
        with pytest.raises(RayError) as info:
            parse_file(tmp_path)
        assert "Is a directory" in info.value.errors[0].message

    def test_parse_file_str_and_bytes_paths(self, tmp_path):
        path = tmp_path / "a.ray"
        path.write_text("sphere\n" + LIT)
        assert len(parse_file(str(path)).objects) == 1
        assert parse_file(os.fsencode(path)).file == str(path)

    def test_parse_dispatch(self, tmp_path, monkeypatch):
        path = tmp_path / "scene.txt"
        path.write_text("cone\n" + LIT)
        assert parse(path).objects[0].kind is ObjectKind.CONE          # PathLike
        assert parse(str(path)).objects[0].kind is ObjectKind.CONE     # existing file
        assert parse("sphere").objects[0].kind is ObjectKind.SPHERE    # text
        assert parse(b"plane").objects[0].kind is ObjectKind.PLANE     # bytes are text
        with pytest.raises(RayError) as info:
            parse(str(tmp_path / "nothere.RAY"))                       # named like a scene
        assert "cannot read the scene file" in info.value.errors[0].message
        assert parse("sphere\n# x.ray").objects[0].kind is ObjectKind.SPHERE

    def test_file_name_in_diagnostics(self):
        with pytest.raises(RayError) as info:
            parse_text("bogus", file="my.ray")
        assert info.value.errors[0].file == "my.ray"
        assert parse_text("", file="my.ray").file == "my.ray"

    def test_wrong_argument_type_is_a_type_error(self):
        with pytest.raises(TypeError):
            parse_text(42)  # type: ignore[arg-type]
        with pytest.raises(TypeError):
            parse_file(3)  # type: ignore[arg-type]

    def test_lazy_exports_from_the_package(self):
        import raymitsuba
        assert raymitsuba.parse_text is parse_text


class TestWarnings:
    def test_objects_without_light(self):
        assert warnings("\n  sphere\ncone\n") == [
            (2, 3, "the scene has objects but no light: it renders black except for the background")]

    def test_ambient_light_is_enough(self):
        assert warnings("sphere\nlight 0.1 0.1 0.1 ambient\n") == []

    def test_lights_without_objects_do_not_warn(self):
        assert warnings("light 1 1 1 point 0 0 0\n") == []

    def test_valid_scene_with_every_kind_of_warning(self):
        scene = ok("eye 0 0 4\neye 0 0 6\nbackground -0.1 0 0\nmaterial 1 1 1 -1 1 1 1 0 0 1\n"
                   "triangle 0 0 0 0 0 0 0 0 0\nlight -1 1 1 ambient\n")
        assert [w.line for w in scene.warnings] == [2, 3, 4, 5, 6]
        assert all(w.severity is Severity.WARNING for w in scene.warnings)


@pytest.mark.parametrize("text", [
    "material 1 0 0 0.1 0.7 0.3 20 0 0 1\ntranslate 1 2 3\nsphere\npop\n"
    "light 1 1 1 point 0 5 5\n",
    "surface 1 0 0 0.1 0.7 0.3 20 0 0 1\nsphere 0 0 0 1\nlight 1 1 1 point 0 5 5\n",
], ids=["comp575", "mit6837"])
def test_a_parse_leaves_no_cycle_behind(text):
    """The parser is not a cycle (its handlers are the class's functions, not bound methods):
    a scene no longer referenced is freed at once, not at the next full collection (which,
    until it came, kept each parse's whole scene and slowed the parses after it). Only the
    parse's own objects are looked for among the garbage: other tests' may be there."""
    import gc

    from raymitsuba.format.comp575 import Comp575Parser
    from raymitsuba.format.mit6837 import Mit6837Parser
    from raymitsuba.model import SceneObject
    gc.collect()
    was_enabled = gc.isenabled()
    gc.disable()
    gc.set_debug(gc.DEBUG_SAVEALL)  # what a collection finds unreachable stays in gc.garbage
    try:
        scene = parse_text(text)
        assert scene.objects
        del scene
        gc.collect()
        left = [type(o).__name__ for o in gc.garbage
                if isinstance(o, (Comp575Parser, Mit6837Parser, SceneObject))]
    finally:
        gc.set_debug(0)
        gc.garbage.clear()
        if was_enabled:
            gc.enable()
    assert not left
