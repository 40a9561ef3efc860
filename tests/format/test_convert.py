"""Tests of ``raymitsuba convert`` (raymitsuba/format/convert.py, convert_cli.py): a MIT 6.837
scene and its COMP 575 conversion mean the same scene and render the same image."""

from __future__ import annotations

import numpy as np
import pytest
from click.testing import CliRunner

from raymitsuba.cli import main
from raymitsuba.format.convert import number, to_comp575
from raymitsuba.format.parser import parse_text
from support import render_ray

SCENE_6837 = """\
# a glass ball in front of a fan-shaped mesh / MIT 6.837 dialect
viewport 32 24
eye 0.5 1 9
lookat 0 0 0
fov 40
background 0.1 0.15 0.3
light 0.2 0.2 0.2 ambient
light 0.8 0.8 0.7 point 4 5 6
light 0.3 0.3 0.3 directional -1 -1 -1
surface 0.9 0.9 1   0.1 0.2 0.6 40   0.1 0.8 0.666
sphere 0.6 -0.2 1 1.1
surface 1 0.4 0.1 0.2 0.8 0.2 10 0.3 0 1
triangles
  v -3 -2 -1
  v 3 -2 -1
  v 3 2 -1.5
  v -3 2 -1.5
  v 0 3.5 -2
  f 0 1 2 3
  surface 0.2 0.8 0.3 0.2 0.8 0 1 0 0 1
  f 3 2 4
  f 4 4 2
end
sphere -1.8 1.2 0
  0.5
"""


def converted(text=SCENE_6837):
    return to_comp575(parse_text(text, file="s.ray"))


def test_numbers_read_back_exactly():
    for x in (0.1, 1 / 0.666, 22.72583086449134, -0.0, 3.0, 1e-300, 123456789012.5):
        assert float(number(x)) == x
    assert number(3.0) == "3" and number(0.5) == "0.5"


def test_the_conversion_is_the_same_scene():
    original = parse_text(SCENE_6837)
    comp = parse_text(converted())
    assert comp.dialect == "comp575"
    assert comp.camera.fov == original.camera.vertical_fov(32, 24)
    assert (comp.camera.eye, comp.camera.lookat, comp.camera.up) == (
        original.camera.eye, original.camera.lookat, original.camera.up)
    assert comp.background == original.background
    assert [(li.kind, li.color, li.position, li.direction) for li in comp.lights] == [
        (li.kind, li.color, li.position, li.direction) for li in original.lights]
    fields = lambda m: (m.color, m.ambient_mix, m.diffuse_mix, m.specular_mix,  # noqa: E731
                        m.phong_coeff, m.reflectivity, m.refractivity, m.ior)
    assert [fields(m) for m in comp.materials] == [fields(m) for m in original.materials]
    spheres = [(o.to_world, o.material) for o in comp.objects if o.kind.value == "sphere"]
    assert spheres == [(o.to_world, o.material) for o in original.objects]
    triangles = [(o.vertices, o.material) for o in comp.objects if o.kind.value == "triangle"]
    expected = [(tuple(m.vertices[i] for i in face), m.material)
                for m in original.meshes for face in m.faces]
    assert triangles == expected


def test_the_conversion_says_the_size_and_the_fov():
    text = converted()
    assert "# Image size: 32 x 24 (its `viewport`). COMP 575 has no viewport command:" in text
    assert "--width 32 --height 24" in text
    assert "# surface 1 (line 10): eta = 1 / index = 1.5015015015015014" in text
    assert "no `viewport`" in converted("sphere 0 0 0 1\n")


def test_both_dialects_render_the_same_image_pixel_for_pixel(mitsuba):
    original = render_ray(SCENE_6837, width=None, height=None)
    assert original.shape == (24, 32, 3)  # the viewport
    comp = render_ray(converted(), width=32, height=24)
    assert original.std() > 0.05  # not a blank image
    np.testing.assert_array_equal(original, comp)


def test_the_same_scene_written_by_hand_in_both_dialects(mitsuba):
    mit = ("viewport 24 16\nfov 50\nlight 1 1 1 point 2 3 8\n"
           "surface 1 0 0 0.1 0.9 0.4 30 0 0 1\nsphere 0.5 0 0 1.5\n")
    comp = ("eye 0 0 10\nfov 34.53798914089611\nlight 1 1 1 point 2 3 8\n"
            "material 1 0 0 0.1 0.9 0.4 30 0 0 1\nscale 1.5 1.5 1.5\ntranslate 0.5 0 0\nsphere\n")
    assert parse_text(mit).camera.vertical_fov(24, 16) == pytest.approx(34.53798914089611, abs=1e-12)
    np.testing.assert_array_equal(render_ray(mit, width=None, height=None),
                                  render_ray(comp, width=24, height=16))


# ---- the command -------------------------------------------------------------------------------


def run(*args):
    return CliRunner().invoke(main, list(args))


def test_convert_writes_the_comp_575_file(tmp_path):
    source, out = tmp_path / "in.ray", tmp_path / "out.ray"
    source.write_text(SCENE_6837)
    result = run("convert", str(source), "-o", str(out))
    assert result.exit_code == 0, result.output
    assert "wrote" in result.stdout and "32 x 24" in result.stdout
    assert "degenerate" in result.stderr  # the scene's warnings are shown
    assert parse_text(out.read_text()).dialect == "comp575"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["in.ray", "out.ray"]  # no temporary


def test_convert_of_a_bad_scene_exits_2_and_writes_nothing(tmp_path):
    source, out = tmp_path / "in.ray", tmp_path / "out.ray"
    source.write_text("sphere 0 0 0 -1\n")
    result = run("convert", str(source), "-o", str(out))
    assert result.exit_code == 2 and ":1:14: error: a sphere's radius" in result.stderr
    assert not out.exists()


def test_convert_of_a_comp_575_scene_exits_2(tmp_path):
    source, out = tmp_path / "in.ray", tmp_path / "out.ray"
    source.write_text("sphere\nlight 1 1 1 ambient\n")
    result = run("convert", str(source), "-o", str(out))
    assert result.exit_code == 2 and "already in the COMP 575 dialect" in result.stderr
    assert not out.exists()
    forced = run("convert", "--dialect", "mit6837", str(source), "-o", str(out))
    assert forced.exit_code == 2 and "takes 4 operands" in forced.stderr
