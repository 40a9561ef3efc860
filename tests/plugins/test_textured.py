"""The ``raytextured`` BSDF (plugins/textured.py): a shared ``rayphong`` material seen through
an object's texture and checkerboard. It provides the surface interface (plugins/whitted/protocol.py):
the shared material itself, its image texture, its checker's square size. What the integrator
makes of them, C(si) = color * texture * checker, is pinned in tests/plugins/whitted/test_surfaces.py."""

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


def test_it_is_a_surface_of_the_shared_material(mitsuba, bsdfs):
    from raymitsuba.plugins.whitted import protocol

    material, textured = bsdfs
    assert protocol.check_surface(textured) is textured
    assert textured.material is material  # the very object: values and gradients are shared


def test_its_textures_are_the_image_then_the_checker_size(mitsuba, bsdfs):
    mi = mitsuba
    _, textured = bsdfs
    assert textured.checker_size == 0.5
    (image,) = textured.image_textures
    si = mi.SurfaceInteraction3f()
    si.uv = mi.Point2f(0.3, 0.7)
    np.testing.assert_allclose(np.array(image.eval(si)).ravel(), TEXEL, rtol=1e-6)


def test_without_textures_it_has_none(mitsuba, bsdfs):
    material, _ = bsdfs
    plain = mitsuba.load_dict({"type": "raytextured", "material": material})
    assert plain.checker_size == 0.0 and plain.image_textures == ()


def test_the_checker_must_be_a_raychecker(mitsuba, bsdfs):
    material, _ = bsdfs
    with pytest.raises(Exception, match="raychecker"):
        mitsuba.load_dict({"type": "raytextured", "material": material,
                           "checker": {"type": "checkerboard"}})


def test_it_has_no_parameters_of_its_own(mitsuba, bsdfs):
    # the material's parameters are listed once, under the material's id (mat{i}.*)
    _, textured = bsdfs
    assert list(mitsuba.traverse(textured).keys()) == []
