"""Tests of raymitsuba/format/writeback.py: which keys a file can hold, their values as written,
and only the fitted numbers rewritten, in both dialects."""

from __future__ import annotations

import pytest

from raymitsuba.format import writeback as W
from raymitsuba.format.parser import parse_text
from support import FIT_MIT_SCENE as MIT
from support import FIT_SCENE as SCENE
from support import FIT_SPHERE as TRUE


class TestKeys:
    def test_writable_keys_follow_the_lines(self):
        model = parse_text(SCENE)
        keys = W.writable_keys(model)
        assert "mat0.color" not in keys  # the default material has no line
        assert {f"mat{i}.{f}" for i in (1, 2, 3) for f in W.MATERIAL_FIELDS} <= set(keys)
        assert "light1.position" in keys and "light1.direction" not in keys
        assert "light2.color" in keys and "light2.position" not in keys
        assert "light3.direction" in keys and "light3.position" not in keys
        assert {"light4.position", "light4.direction", "light4.shape_coefficient"} <= set(keys)


class TestRewrite:
    VALUES = {
        "mat1.diffuse_mix": 0.6986,
        "mat1.color": (0.5, 0.45, 0.123456789),  # g unchanged: keeps its spelling
        "mat3.ior": 1.0,  # unchanged (written `1e0`): kept as is
        "light1.position": (2.0, -1.0, 6.5),
        "light3.direction": (-0.25, -0.2, -1.0),
        "light4.direction": (0.0, -1.0, -0.9),
        "light4.shape_coefficient": 7.25,
        "light2.color": (0.1, 0.2, 0.3),
    }
    EXPECTED = (
        "# a test scene\r\n"
        "eye 0.1 0.05 5\r\n"
        "fov 35   # degrees\r\n"
        "light 0.9 0.85 0.8 point 2 -1 6.5\r\n"
        "light\t0.1 0.2 0.3   ambient # fill\r\n"
        "light 1 1 1 directional -0.25 -0.2 -1\r\n"
        "light 1 1 1 spotlight 0 3 3 0 -1 -0.9 7.25 # spot\r\n"
        "material 0.5 0.45 0.123457 0.4 \t 0.6986 0.5 12 0 0 1 # the sphere\r\n"
        "sphere\r\n"
        "material 1 1 1 1 1 0 1 0 0 1\n"
        "\n"
        "material 1 1 1 1 1 0 1 0 0.5 1e0\r"
        "translate 3 0 0\r"
        "sphere\n"
    )

    def test_only_the_fitted_numbers_change(self):
        model = parse_text(SCENE)
        out = W.rewrite_scene(SCENE.encode(), model, self.VALUES)
        assert out == self.EXPECTED.encode()
        again = parse_text(out)
        assert again.lights[0].position == (2.0, -1.0, 6.5)
        assert again.lights[3].shape == 7.25
        assert again.materials[1].diffuse_mix == 0.6986

    def test_text_in_text_out_and_unchanged_values(self):
        model = parse_text(SCENE)
        same = {key: W.model_values(model, [key])[key] for key in self.VALUES}
        assert W.rewrite_scene(SCENE, model, same) == SCENE

    def test_formatting(self):
        model = parse_text(TRUE)
        out = W.rewrite_scene(TRUE, model, {"mat1.phong_coeff": 12.345678901, "mat1.ior": 1e-3,
                                            "mat1.reflectivity": 1e-4, "mat1.ambient_mix": -0.0})
        line = out.splitlines()[4]
        assert line == "material 0.8 0.45 0.3 0 0.7 0.5 12.3457 0.0001 0 0.001"

    def test_a_byte_order_mark_and_utf8_comments_survive(self):
        text = "\ufeffmaterial 1 1 1 1 0.5 0 1 0 0 1 # café\nsphere\n"
        model = parse_text(text.encode())
        out = W.rewrite_scene(text.encode(), model, {"mat1.diffuse_mix": 0.25})
        assert out == text.replace("0.5", "0.25").encode()

    def test_non_finite_values_are_refused(self):
        with pytest.raises(W.ParameterError):
            W.rewrite_scene(TRUE, parse_text(TRUE), {"mat1.ior": float("nan")})


class TestBothDialects:
    def test_the_fitted_index_is_written_back_as_one_over_eta(self):
        model = parse_text(MIT)
        assert model.materials[1].ior == 2.0
        out = W.rewrite_scene(MIT, model, {"mat1.ior": 1.6, "mat1.refractivity": 0.75,
                                           "mat1.specular_mix": 0.6})
        assert out == MIT.replace("   0.1 0.8 0.5   /", "   0.1 0.75 0.625   /")
        assert parse_text(out).materials[1].ior == pytest.approx(1.6)

    def test_an_unchanged_index_keeps_its_spelling(self):
        model = parse_text(MIT)
        assert W.rewrite_scene(MIT, model, {"mat1.ior": 2.0}) == MIT

    def test_the_background_is_written_back_in_both_dialects(self):
        out = W.rewrite_scene(MIT, parse_text(MIT), {"background.color": (0.5, 0.2, 0.25)})
        assert "background 0.5 0.2 0.25\r\n" in out
        comp = "fov 30\n  background\t0 0 0 # sky\nsphere\n"
        out = W.rewrite_scene(comp, parse_text(comp), {"background.color": (0.1, 0, 0.2)})
        assert out == "fov 30\n  background\t0.1 0 0.2 # sky\nsphere\n"
        assert W.model_values(parse_text(comp), ["background.color"]) == {
            "background.color": (0.0, 0.0, 0.0)}

    def test_bad_keys_are_fit_errors(self):
        with pytest.raises(W.ParameterError, match="is not a parameter key"):
            W.model_values(parse_text(MIT), ["mat1"])
        with pytest.raises(W.ParameterError, match="no light 7"):
            W.model_values(parse_text(MIT), ["light7.color"])

    def test_two_surfaces_on_one_line(self):
        text = "surface 1 1 1 1 1 0 1 0 0 1 surface 0.5 0.5 0.5 1 1 0 1 0 0 1\nsphere 0 0 0 1\n"
        out = W.rewrite_scene(text, parse_text(text), {"mat2.color": (0.25, 0.5, 0.5),
                                                       "mat1.diffuse_mix": 0.75})
        assert out == ("surface 1 1 1 1 0.75 0 1 0 0 1 surface 0.25 0.5 0.5 1 1 0 1 0 0 1\n"
                       "sphere 0 0 0 1\n")
