"""The ``raytextured`` BSDF (plugins/textured.py): a shared ``rayphong`` material whose base
color is multiplied by an object's texture and checkerboard, C(si) = color * texture * checker;
everything else is the material's."""

import numpy as np
import pytest

C = (0.8, 0.4, 0.2)
TEXEL = (0.5, 0.25, 1.0)


@pytest.fixture(scope="module")
def bsdfs(mitsuba):
    """(the material, the material x a constant texture x a checker of squares 0.5)."""
    mi = mitsuba
    material = mi.load_dict({"type": "rayphong", "color": mi.ScalarColor3f(*C), "ambient_mix": 0.5,
                             "diffuse_mix": 0.7, "specular_mix": 0.3, "phong_coeff": 8.0,
                             "reflectivity": 0.25, "refractivity": 0.5, "ior": 1.4})
    texture = {"type": "bitmap", "bitmap": mi.Bitmap(np.tile(np.float32(TEXEL), (2, 2, 1))),
               "raw": True, "filter_type": "nearest"}
    textured = mi.load_dict({"type": "raytextured", "material": material, "texture": texture,
                             "checker": {"type": "raychecker", "size": 0.5}})
    return material, textured


def interaction(mi, u, v):
    """Hits at texture coordinates (u, v), seen head-on (local frame: normal +z)."""
    si = mi.SurfaceInteraction3f()
    si.uv = mi.Point2f(np.float32(u), np.float32(v))
    si.wi = mi.Vector3f(0.0, 0.0, 1.0)
    si.sh_frame = mi.Frame3f(mi.Vector3f(0.0, 0.0, 1.0))
    return si


# (0.1, 0.1) and (0.6, 0.6) are on even squares of side 0.5; (0.6, 0.1) on an odd one
UV = ([0.1, 0.6, 0.6], [0.1, 0.6, 0.1])
CHECKER = np.array([1.0, 1.0, 0.0])


def test_base_color_is_color_times_texture_times_checker(mitsuba, bsdfs):
    _, textured = bsdfs
    got = np.array(textured.eval_attribute_3("color", interaction(mitsuba, *UV))).T
    np.testing.assert_allclose(got, CHECKER[:, None] * np.multiply(C, TEXEL), rtol=1e-6)


def test_ambient_reflectance_is_ka_times_the_textured_color(mitsuba, bsdfs):
    _, textured = bsdfs
    got = np.array(textured.eval_attribute_3("ambient_reflectance", interaction(mitsuba, *UV))).T
    np.testing.assert_allclose(got, 0.5 * CHECKER[:, None] * np.multiply(C, TEXEL), rtol=1e-6)


def test_scalar_attributes_are_the_materials(mitsuba, bsdfs):
    _, textured = bsdfs
    si = interaction(mitsuba, *UV)
    for name, value in (("reflectivity", 0.25), ("refractivity", 0.5), ("ior", 1.4)):
        assert np.array(textured.eval_attribute_1(name, si)).ravel()[0] == pytest.approx(value)
        assert textured.has_attribute(name)


def test_eval_is_the_materials_phong_term_with_the_textured_color(mitsuba, bsdfs):
    mi = mitsuba
    material, textured = bsdfs
    si = interaction(mi, *UV)
    wo = mi.Vector3f(0.6, 0.0, 0.8)  # toward a light 37 degrees off the normal
    n_dot_l = 0.8
    highlight = 0.3 * max(2 * n_dot_l * 1.0 - 0.8, 0.0) ** 8.0  # ks (R.V)^n, R.V = 2(N.L)(N.V) - L.V
    got = np.array(textured.eval(mi.BSDFContext(), si, wo)).T
    want = 0.7 * CHECKER[:, None] * np.multiply(C, TEXEL) * n_dot_l + highlight
    np.testing.assert_allclose(got, want, rtol=1e-5)
    # where the texel is 1 everywhere it would be the material's own eval
    plain = np.array(material.eval(mi.BSDFContext(), si, wo)).ravel()
    np.testing.assert_allclose(plain, 0.7 * np.array(C) * n_dot_l + highlight, rtol=1e-5)


def test_it_has_no_parameters_of_its_own(mitsuba, bsdfs):
    # the material's parameters are listed once, under the material's id (mat{i}.*)
    _, textured = bsdfs
    assert list(mitsuba.traverse(textured).keys()) == []
