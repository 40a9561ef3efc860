"""Geometry and camera keys: where each is in the text, ``check --params``, and the
byte-exact write-back of their numbers (both dialects)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from raymitsuba.format import parse_text
from raymitsuba.format.commands import ParamKey
from raymitsuba.format.keys import geometry_places
from raymitsuba.format.writeback import (ParameterError, model_values, rewrite_scene,
                                         source_lines, writable_keys)

COMP = (b"eye 0 1 5  # first camera\r\n"
        b"eye\t0 2 6\n"
        b"fov 40\n"
        b"material 1 0 0 0.2 0.8 0 1 0 0 1\n"
        b"light 1 1 1 point 1 2 3\n"
        b"translate 0 0.5 -1\n"
        b"ROTATEY 30   # any case\n"
        b"scale 1 2 1\n"
        b"sphere\n"
        b"pop\n"
        b"triangle 0 0 0  1 0 0  0 1 0\n"
        b"checkerboard 0.5\n"
        b"plane\n")

MIT = (b"eye 0 0 10 fov 30\n"
       b"surface 1 0 0 0.2 0.8 0 1 0 0 1\n"
       b"light 1 1 1 point 3 3 3\n"
       b"sphere 0 0 0 1 sphere 1 1\n"
       b"  -1 0.5  # its radius on the next line\n"
       b"triangles\n"
       b"v 0 0 0\n"
       b"v 1 0 0 v 0 1 0\n"
       b"f 0 1 2\n"
       b"end\n")


def places(data):
    model = parse_text(data)
    return model, geometry_places(source_lines(data), model.dialect)


def test_comp575_keys_count_each_commands_lines_and_the_camera_is_the_last_line():
    model, found = places(COMP)
    assert list(found) == ["camera.eye", "camera.fov", "translate1.offset", "rotateY1.angle",
                           "scale1.factors", "triangle1.v0", "triangle1.v1", "triangle1.v2",
                           "checkerboard1.size"]
    assert found["camera.eye"].values == (0.0, 2.0, 6.0)
    assert found["camera.eye"].first == (2, 5)  # after the tab
    assert found["rotateY1.angle"].values == (30.0,)
    assert found["triangle1.v1"].values == (1.0, 0.0, 0.0)


def test_mit6837_keys_follow_the_token_stream():
    model, found = places(MIT)
    assert found["sphere2.center"].values == (1.0, 1.0, -1.0)
    assert found["sphere2.radius"].values == (0.5,)
    assert found["sphere2.radius"].first == (5, 6)
    assert [found[f"v{n}.position"].values for n in (1, 2, 3)] == [
        (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)]
    assert found["camera.fov"].values == (30.0,)


@pytest.mark.parametrize("data, values", [
    (COMP, {"translate1.offset": (0.25, 0.5, -1.0), "camera.eye": (0.0, 2.5, 6.0),
            "rotateY1.angle": 31.5, "triangle1.v2": (0.0, 1.0, 0.125),
            "checkerboard1.size": 0.75, "mat1.diffuse_mix": 0.5}),
    (MIT, {"sphere2.radius": 0.75, "sphere2.center": (1.0, 1.5, -1.0),
           "v3.position": (0.0, 2.0, 0.0), "camera.fov": 33.0}),
])
def test_geometry_keys_are_written_back_byte_exact(data, values):
    model = parse_text(data)
    out = rewrite_scene(data, model, values)
    assert model_values(parse_text(out), list(values), out) == values
    # only the changed numbers differ: every other byte is the same
    unchanged = rewrite_scene(data, model, model_values(model, list(values), data))
    assert unchanged == data
    assert len(out.split(b"\n")) == len(data.split(b"\n"))


def test_only_the_numbers_of_the_key_change():
    model = parse_text(COMP)
    out = rewrite_scene(COMP, model, {"camera.eye": (0.0, 2.5, 6.0)})
    assert out == COMP.replace(b"eye\t0 2 6", b"eye\t0 2.5 6")


def test_unknown_geometry_keys_are_errors():
    model = parse_text(COMP)
    assert "translate1.offset" in writable_keys(model, COMP)
    assert "translate1.offset" not in writable_keys(model)  # (no text: no geometry keys)
    with pytest.raises(ParameterError, match="translate2.offset"):
        rewrite_scene(COMP, model, {"translate2.offset": (0.0, 0.0, 0.0)})
    with pytest.raises(ValueError):
        ParamKey.parse("translate.offset")


def test_check_params_lists_every_key(tmp_path):
    path = tmp_path / "scene.ray"
    path.write_bytes(COMP)
    out = subprocess.run([sys.executable, "-m", "raymitsuba", "check", "--params", str(path)],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert "camera.eye 2:5 0 2 6" in lines
    assert "translate1.offset 6:11 0 0.5 -1" in lines
    assert "light1.position 5:19 1 2 3" in lines
    assert "mat1.diffuse_mix 4:20 0.8" in lines
    assert len(lines) == 8 + 2 + 2 + 7  # material, light, camera, geometry
