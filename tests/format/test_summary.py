"""Tests of raymitsuba/format/summary.py: exact world bounding boxes, the summary's lines, and
check_scenes' routing of summaries and diagnostics."""

from __future__ import annotations

import math

from raymitsuba.format.parser import parse_text
from raymitsuba.format.summary import check_scenes, object_bounds, scene_bounds, summarize


def bounds(text):
    return scene_bounds(parse_text(text + "\nlight 1 1 1 ambient\n"))


# ---- bounds --------------------------------------------------------------------------------


def test_sphere_box_follows_translate_then_scale():
    assert bounds("translate 2 0 0\nscale 2 2 2\nsphere") == ((2, -2, -2), (6, 2, 2))


def test_ellipsoid_is_exact_under_rotation():
    lo, hi = bounds("scale 3 1 1\nrotateZ 45\nsphere")
    # the x half-extent of M = Rz(45) S(3,1,1) is the norm of row 0: sqrt(4.5 + 0.5)
    assert math.isclose(hi[0], math.sqrt(5)) and math.isclose(lo[1], -math.sqrt(5))
    assert hi[2] == 1 and lo[2] == -1


def test_cylinder_box_is_half_its_axis_plus_the_projected_disk():
    assert bounds("cylinder") == ((-1, -0.5, -1), (1, 0.5, 1))
    lo, hi = bounds("rotateX 90\ncylinder")  # axis along z
    assert (lo, hi) == ((-1, -1, -0.5), (1, 1, 0.5))


def test_tilted_cylinder_is_exact():
    lo, hi = bounds("rotateZ 30\ncylinder")
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    # x: half the axis (0.5 * |-s|) plus the disk radius projected (|c|)
    assert math.isclose(hi[0], 0.5 * s + c) and math.isclose(hi[1], 0.5 * c + s)


def test_cone_box_holds_the_base_disk_and_the_apex():
    assert bounds("cone") == ((-1, -0.5, -1), (1, 0.5, 1))
    assert bounds("rotateZ 90\ncone") == ((-0.5, -1, -1), (0.5, 1, 1))
    assert bounds("scale 1 4 1\ncone") == ((-1, -2, -1), (1, 2, 1))


def test_cone_apex_sticking_out_sideways():
    # a tall cone turned to lie along +x: the apex at x = 2 bounds it on the right
    lo, hi = bounds("scale 1 4 1\nrotateZ -90\ncone")
    assert (lo, hi) == ((-2, -1, -1), (2, 1, 1))


def test_triangle_uses_its_transformed_corners():
    assert bounds("translate 0 0 1\ntriangle 0 0 0 2 0 0 0 3 0") == ((0, 0, 1), (2, 3, 1))


def test_plane_has_no_box():
    scene = parse_text("plane\nlight 1 1 1 ambient")
    assert object_bounds(scene.objects[0]) is None and scene_bounds(scene) is None


def test_scene_box_is_the_union_of_the_finite_objects():
    assert bounds("sphere\ntranslate 10 0 0\nsphere\nplane") == ((-1, -1, -1), (11, 1, 1))


def test_an_object_under_a_mirroring_transform_keeps_an_ordered_box():
    assert bounds("scale -1 2 1\ntranslate 3 0 0\nsphere") == ((2, -2, -1), (4, 2, 1))
    assert bounds("scale -2 1 1\ntriangle 1 0 0 2 0 0 1 1 0") == ((-4, 0, 0), (-2, 1, 0))


# ---- the summary ---------------------------------------------------------------------------


def test_summarize_is_the_file_then_the_indented_lines():
    text = summarize(parse_text(
        "eye 1 2 -0.0\nbackground 0.25 0.5 1\nmaterial 1 0 0 1 1 0 1 0 0 1\n"
        "sphere\ncone\nsphere\nplane\nlight 1 1 1 point 0 5 5\nlight 0.1 0.1 0.1 ambient\n"
        "light 0 0 0 ambient\n", file="x.ray"))
    assert text.splitlines() == [
        "x.ray: ok",
        "  dialect    COMP 575",
        "  camera     eye (1, 2, 0)  lookat (0, 0, 0)  up (0, 1, 0)  fov 45",  # -0 shows as 0
        "  background (0.25, 0.5, 1)",
        "  objects    4 (2 sphere, 1 plane, 1 cone)",  # in the order of ObjectKind
        "  lights     3 (2 ambient, 1 point)",
        "  materials  1 declared (plus the default)",
        "  bounds     (-1, -1, -1) to (1, 1, 1)  (planes are infinite and left out)",
        "  warnings   0",
    ]


def test_numbers_have_six_significant_digits():
    text = summarize(parse_text("eye 0.1234567 1e-7 123456789\n"))
    assert "eye (0.123457, 1e-07, 1.23457e+08)" in text


def test_no_finite_objects_no_bounds():
    assert "  bounds     none (no finite objects)" in summarize(parse_text(""))


# ---- check_scenes ----------------------------------------------------------------------------


class Echo:
    """Records what check_scenes prints, as (stream, text)."""

    def __init__(self):
        self.lines = []

    def __call__(self, text, err=False):
        self.lines.append(("stderr" if err else "stdout", text))


def test_summaries_go_to_stdout_diagnostics_to_stderr_and_any_error_makes_it_false(tmp_path):
    good, bad = tmp_path / "good.ray", tmp_path / "bad.ray"
    good.write_text("sphere\n")  # a warning: no light
    bad.write_text("sphere 1\nfov 0\nlight 1 1 1 ambient\n")
    echo = Echo()
    assert check_scenes([str(good)], echo) is True
    assert [stream for stream, _ in echo.lines] == ["stderr", "stdout"]
    assert echo.lines[0][1].startswith(f"{good}:1:1: warning:")
    assert echo.lines[1][1].startswith(f"{good}: ok\n")

    echo = Echo()
    assert check_scenes([str(bad), str(good)], echo, dialect="comp575") is False
    err = [text for stream, text in echo.lines if stream == "stderr"]
    assert err[0].startswith(f"{bad}:1:8: error:") and err[1].startswith(f"{bad}:2:5: error:")
    assert err[2] == f"{bad}: invalid, 2 errors"
    assert any(text.startswith(f"{good}: ok") for stream, text in echo.lines if stream == "stdout")


def test_one_error_is_singular(tmp_path):
    path = tmp_path / "one.ray"
    path.write_text("pop\n")
    echo = Echo()
    assert check_scenes([str(path)], echo) is False
    assert echo.lines[-1] == ("stderr", f"{path}: invalid, 1 error")
