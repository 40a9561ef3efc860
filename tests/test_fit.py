"""Tests of raymitsuba/fit.py: which keys, fitting, clamping, writing back (the ``fit``
command is tested in test_fit_cli.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from raymitsuba import fit as F
from raymitsuba.format.parser import parse_text

# Comments, tabs, odd spacing, several materials and every kind of light: everything but
# the fitted numbers must survive a rewrite byte for byte.
SCENE = (
    "# a test scene\r\n"
    "eye 0.1 0.05 5\r\n"
    "fov 35   # degrees\r\n"
    "light 0.9 0.85 0.8 point 1.5 1 6\r\n"
    "light\t0.3 0.3 0.3   ambient # fill\r\n"
    "light 1 1 1 directional -0.3 -0.2 -1\r\n"
    "light 1 1 1 spotlight 0 3 3 0 -1 -1 4 # spot\r\n"
    "material 0.8 0.45 0.3 0.4 \t 0.40 0.5 12 0 0 1 # the sphere\r\n"
    "sphere\r\n"
    "material 1 1 1 1 1 0 1 0 0 1\n"
    "\n"
    "material 1 1 1 1 1 0 1 0 0.5 1e0\r"
    "translate 3 0 0\r"
    "sphere\n"
)

# A tiny scene for fits: one sphere, ambient + point light.
TRUE = """\
eye 0.1 0.05 5
fov 35
light 0.9 0.85 0.8 point 1.5 1 6
light 0.3 0.3 0.3 ambient
material 0.8 0.45 0.3 0.4 0.7 0.5 12 0 0 1
sphere
"""


def perturbed(text, old, new):
    assert old in text
    return text.replace(old, new)


@pytest.fixture(scope="module")
def mi():
    from raymitsuba.backend import mitsuba

    return mitsuba()


def render(text, size=24):
    import raymitsuba

    return raymitsuba.render(raymitsuba.load(text, width=size, height=size)).numpy()


# -- keys ---------------------------------------------------------------------------------------
class TestKeys:
    def test_writable_keys_follow_the_lines(self):
        model = parse_text(SCENE)
        keys = F.writable_keys(model)
        assert "mat0.color" not in keys  # the default material has no line
        assert {f"mat{i}.{f}" for i in (1, 2, 3) for f in F.MATERIAL_FIELDS} <= set(keys)
        assert "light1.position" in keys and "light1.direction" not in keys
        assert "light2.color" in keys and "light2.position" not in keys
        assert "light3.direction" in keys and "light3.position" not in keys
        assert {"light4.position", "light4.direction", "light4.shape_coefficient"} <= set(keys)

    def test_default_keys(self):
        model = parse_text(SCENE)
        keys = F.default_keys(model)
        # mat1 and mat3 are used by objects; mat2 is not. kr = 0 everywhere; mat3 has kt > 0.
        assert "mat1.diffuse_mix" in keys and "mat1.phong_coeff" in keys
        assert not any(k.startswith("mat2.") for k in keys)
        assert "mat1.reflectivity" not in keys and "mat1.refractivity" not in keys
        assert "mat1.ior" not in keys
        assert "mat3.refractivity" in keys and "mat3.ior" in keys
        assert [k for k in keys if k.startswith("light")] == [f"light{j}.color" for j in range(1, 5)]

    def test_patterns_and_unknown_keys(self):
        model = parse_text(SCENE)
        assert F.select_keys(model, ["mat1.*"]) == [f"mat1.{f}" for f in F.MATERIAL_FIELDS]
        assert F.select_keys(model, ["light1.color", "light1.color"]) == ["light1.color"]
        with pytest.raises(F.FitError, match=r"unknown parameter `mat1\.diffuse`; valid keys: .*mat1\.diffuse_mix"):
            F.select_keys(model, ["mat1.diffuse"])
        with pytest.raises(F.FitError, match="default material"):
            F.select_keys(model, ["mat0.color"])
        with pytest.raises(F.FitError):
            F.select_keys(model, ["light2.position"])  # an ambient light has no position


# -- writing back -------------------------------------------------------------------------------
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
        out = F.rewrite_scene(SCENE.encode(), model, self.VALUES)
        assert out == self.EXPECTED.encode()
        again = parse_text(out)
        assert again.lights[0].position == (2.0, -1.0, 6.5)
        assert again.lights[3].shape == 7.25
        assert again.materials[1].diffuse_mix == 0.6986

    def test_text_in_text_out_and_unchanged_values(self):
        model = parse_text(SCENE)
        same = {key: F.model_values(model, [key])[key] for key in self.VALUES}
        assert F.rewrite_scene(SCENE, model, same) == SCENE

    def test_formatting(self):
        model = parse_text(TRUE)
        out = F.rewrite_scene(TRUE, model, {"mat1.phong_coeff": 12.345678901, "mat1.ior": 1e-3,
                                            "mat1.reflectivity": 1e-4, "mat1.ambient_mix": -0.0})
        line = out.splitlines()[4]
        assert line == "material 0.8 0.45 0.3 0 0.7 0.5 12.3457 0.0001 0 0.001"

    def test_a_byte_order_mark_and_utf8_comments_survive(self):
        text = "\ufeffmaterial 1 1 1 1 0.5 0 1 0 0 1 # café\nsphere\n"
        model = parse_text(text.encode())
        out = F.rewrite_scene(text.encode(), model, {"mat1.diffuse_mix": 0.25})
        assert out == text.replace("0.5", "0.25").encode()

    def test_non_finite_values_are_refused(self):
        with pytest.raises(F.FitError):
            F.rewrite_scene(TRUE, parse_text(TRUE), {"mat1.ior": float("nan")})

    def test_write_scene_is_atomic(self, tmp_path):
        path = tmp_path / "out.ray"
        F.write_scene(str(path), b"sphere\n")
        assert path.read_bytes() == b"sphere\n"
        assert os.listdir(tmp_path) == ["out.ray"]


# -- fitting ------------------------------------------------------------------------------------
class TestFit:
    def test_recovers_a_perturbed_diffuse_mix(self, mi):
        import raymitsuba

        target = render(TRUE)
        loaded = raymitsuba.load(perturbed(TRUE, "0.4 0.7 0.5", "0.4 0.4 0.5"), width=24, height=24)
        steps = []
        result = F.fit(loaded, target, ["mat1.diffuse_mix"], iters=60, lr=0.05,
                       callback=steps.append)
        assert result.start["mat1.diffuse_mix"] == pytest.approx(0.4)
        assert result.fitted["mat1.diffuse_mix"] == pytest.approx(0.7, abs=5e-3)
        assert result.final_loss < 1e-3 * result.losses[0]
        assert [s.iteration for s in steps] == list(range(1, 61))
        assert result.history[0].values["mat1.diffuse_mix"] == pytest.approx(0.4)
        assert result.iterations == 60 and result.seconds > 0
        assert result.start_image.shape == result.fitted_image.shape == (24, 24, 3)
        # The scene now holds the fitted value, detached.
        assert F.to_python(loaded.params["mat1.diffuse_mix"]) == result.fitted["mat1.diffuse_mix"]

    def test_values_stay_in_range(self, mi):
        """A black target pulls the color, kd, ks, the exponent and kt (which lets the grey
        background through the sphere) below their bounds: every value stays in range at
        every step, and kt stops at 1e-4, not 0."""
        import raymitsuba

        target = np.zeros((16, 16, 3), np.float32)  # black: everything wants to go down
        text = "background 0.5 0.5 0.5\n" + perturbed(TRUE, "0.4 0.7 0.5 12 0 0 1",
                                                    "0.4 0.05 0.05 0.05 0 0.05 0.05")
        loaded = raymitsuba.load(text, width=16, height=16)
        keys = ["mat1.color", "mat1.diffuse_mix", "mat1.specular_mix", "mat1.phong_coeff",
                "mat1.refractivity", "mat1.ior", "light1.color"]
        result = F.fit(loaded, target, keys, iters=40, lr=0.1)
        for step in result.history[1:] + [F.Step(0, 0.0, result.fitted)]:
            for key, value in step.values.items():
                low = F.LOWER_BOUNDS[F.field_of(key)]
                assert np.min(value) >= np.float32(low), (key, value)
        assert result.fitted["mat1.diffuse_mix"] == 0.0
        assert result.fitted["mat1.refractivity"] == pytest.approx(1e-4)  # not 0: see fit.py

    def test_set_values_takes_what_to_python_gives(self, mi):
        import raymitsuba

        loaded = raymitsuba.load(TRUE, width=8, height=8)
        values = {"mat1.color": (0.25, 0.5, 0.75), "mat1.phong_coeff": 7.0,
                  "light1.position": (1.0, 2.0, 3.0)}
        F.set_values(loaded, values)
        assert {key: F.to_python(loaded.params[key]) for key in values} == values

    def test_clamp_value(self):
        assert F.clamp_value("mat1.color", (-1.0, 0.5, 2.0)) == (0.0, 0.5, 2.0)
        assert F.clamp_value("mat2.ior", -3.0) == 1e-3
        assert F.clamp_value("mat2.reflectivity", 0.0) == 1e-4
        assert F.clamp_value("light1.position", (-5.0, 0.0, 1.0)) == (-5.0, 0.0, 1.0)
        assert F.clamp_value("light4.shape_coefficient", -1.0) == 0.0

    def test_wrong_target_size_and_key(self, mi):
        import raymitsuba

        loaded = raymitsuba.load(TRUE, width=8, height=8)
        with pytest.raises(F.FitError, match="target is 9x8"):
            F.fit(loaded, np.zeros((8, 9, 3)), ["mat1.diffuse_mix"], iters=1)
        with pytest.raises(F.FitError, match="unknown parameter"):
            F.fit(loaded, np.zeros((8, 8, 3)), ["mat1.nope"], iters=1)


# -- both dialects ------------------------------------------------------------------------------
MIT = ("# MIT 6.837 / index is n_outside / n_inside\r\n"
       "background 0.1 0.2 0.3\r\n"
       "light 1 1 1 point 0 4 6\r\n"
       "surface 0.9 0.9 1 0.1 0.2 0.6 40\r\n"
       "   0.1 0.8 0.5   / glass, written across lines\r\n"
       "sphere 0 0 0 1\r\n"
       "triangles\r\nv 0 0 -2\r\nv 1 0 -2\r\nv 0 1 -2\r\n"
       "surface 1 0 0 0.2 0.8 0 1 0 0 1\r\nf 0 1 2\r\nend\r\n")


class TestBothDialects:
    def test_mit_6837_keys_count_surfaces(self):
        model = parse_text(MIT)
        keys = F.writable_keys(model)
        assert {"mat1.ior", "mat2.color", "light1.position", "background.color"} <= set(keys)
        assert "mat3.color" not in keys
        assert F.default_keys(model)[:1] == ["mat1.color"]
        assert any(k.startswith("mat2.") for k in F.default_keys(model))  # the mesh's surface

    def test_the_fitted_index_is_written_back_as_one_over_eta(self):
        model = parse_text(MIT)
        assert model.materials[1].ior == 2.0
        out = F.rewrite_scene(MIT, model, {"mat1.ior": 1.6, "mat1.refractivity": 0.75,
                                           "mat1.specular_mix": 0.6})
        assert out == MIT.replace("   0.1 0.8 0.5   /", "   0.1 0.75 0.625   /")
        assert parse_text(out).materials[1].ior == pytest.approx(1.6)

    def test_an_unchanged_index_keeps_its_spelling(self):
        model = parse_text(MIT)
        assert F.rewrite_scene(MIT, model, {"mat1.ior": 2.0}) == MIT

    def test_the_background_is_written_back_in_both_dialects(self):
        out = F.rewrite_scene(MIT, parse_text(MIT), {"background.color": (0.5, 0.2, 0.25)})
        assert "background 0.5 0.2 0.25\r\n" in out
        comp = "fov 30\n  background\t0 0 0 # sky\nsphere\n"
        out = F.rewrite_scene(comp, parse_text(comp), {"background.color": (0.1, 0, 0.2)})
        assert out == "fov 30\n  background\t0.1 0 0.2 # sky\nsphere\n"
        assert F.model_values(parse_text(comp), ["background.color"]) == {
            "background.color": (0.0, 0.0, 0.0)}

    def test_no_background_line_no_background_key(self):
        model = parse_text("sphere\n")
        assert "background.color" not in F.writable_keys(model)
        with pytest.raises(F.FitError, match="no `background` line"):
            F.select_keys(model, ["background.color"])
        with pytest.raises(F.FitError, match="no `background` line"):
            F.rewrite_scene("sphere\n", model, {"background.color": (1, 1, 1)})

    def test_bad_keys_are_fit_errors(self):
        with pytest.raises(F.FitError, match="is not a parameter key"):
            F.model_values(parse_text(MIT), ["mat1"])
        with pytest.raises(F.FitError, match="no light 7"):
            F.model_values(parse_text(MIT), ["light7.color"])

    def test_two_surfaces_on_one_line(self):
        text = "surface 1 1 1 1 1 0 1 0 0 1 surface 0.5 0.5 0.5 1 1 0 1 0 0 1\nsphere 0 0 0 1\n"
        out = F.rewrite_scene(text, parse_text(text), {"mat2.color": (0.25, 0.5, 0.5),
                                                       "mat1.diffuse_mix": 0.75})
        assert out == ("surface 1 1 1 1 0.75 0 1 0 0 1 surface 0.25 0.5 0.5 1 1 0 1 0 0 1\n"
                       "sphere 0 0 0 1\n")
