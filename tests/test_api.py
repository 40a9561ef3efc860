"""The Python API: load() from text, a path or a Scene; render(); the parameter keys that
mi.traverse exposes, and that changing them changes the image as the contract says."""

import math
import os

import numpy as np
import pytest

import raymitsuba
from raymitsuba.model import RayError, Scene

SCENE = """\
background 0.1 0.2 0.3
light 0.25 0.5 1 ambient
light 1 1 1 point 0 0 5
material 0.8 0.6 0.4  0.5 0.25 0 1  0 0 1
sphere
light 0.5 0.5 0.5 directional 0 0 -1
light 1 0 0 spotlight 0 5 5  0 -1 0  2
"""
MATERIAL_FIELDS = ("color", "ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
                   "reflectivity", "refractivity", "ior")


@pytest.fixture(scope="module")
def loaded():
    return raymitsuba.load(SCENE, width=9, height=9)


def test_load_and_render(loaded, mitsuba):
    import drjit as dr

    assert isinstance(loaded.model, Scene)
    assert (loaded.options.width, loaded.options.height, loaded.options.spp,
            loaded.options.max_depth, loaded.options.srgb) == (9, 9, 1, 5, False)
    assert isinstance(loaded.scene, mitsuba.Scene)
    assert loaded.scene_dict["integrator"]["type"] == "raywhitted"
    image = raymitsuba.render(loaded)
    assert isinstance(image, mitsuba.TensorXf) and dr.shape(image) == (9, 9, 3)
    pixels = np.array(image)
    # The centre pixel: N = L = V = (0, 0, 1) for the point and the directional light, and
    # the spotlight at (0, 5, 5) sees the point (0, 0, 1) at cos a = 5 / sqrt(41), with
    # N.L = 4 / sqrt(41): ka A C + kd C (I_point + I_dir + I_spot cos^2 a N.L).
    color = np.array([0.8, 0.6, 0.4])
    cos_a = 5 / math.sqrt(41)
    want = 0.5 * np.array([0.25, 0.5, 1]) * color + 0.25 * color * (
        1 + 0.5 + np.array([1, 0, 0]) * cos_a ** 2 * 4 / math.sqrt(41))
    np.testing.assert_allclose(pixels[4, 4], want, rtol=0, atol=1e-6)
    np.testing.assert_allclose(pixels[0, 0], [0.1, 0.2, 0.3], rtol=0, atol=1e-7)


def test_load_from_a_path_and_from_a_scene(tmp_path, loaded):
    from PIL import Image

    (tmp_path / "tex").mkdir()
    Image.new("RGB", (2, 2), (255, 255, 255)).save(tmp_path / "tex" / "white.png")
    path = tmp_path / "scene.ray"
    path.write_text(SCENE.replace("sphere\n", "texture tex/white.png\nsphere\n"))  # relative
    want = np.array(raymitsuba.render(loaded))
    for source in (str(path), path, raymitsuba.parse_file(str(path))):
        from_file = raymitsuba.load(source, width=9, height=9)
        np.testing.assert_allclose(np.array(raymitsuba.render(from_file)), want,
                                   rtol=0, atol=1e-6)  # a white texel changes nothing
    model = raymitsuba.parse_text(SCENE)
    again = raymitsuba.load(model, width=9, height=9)
    assert again.model is model
    assert np.array(raymitsuba.render(again)).tobytes() == want.tobytes()


def test_load_rejects_a_bad_scene():
    with pytest.raises(RayError):
        raymitsuba.load("sphere 1\n", width=4, height=4)


def test_parameter_keys(loaded):
    keys = set(loaded.params.keys())
    for i in (0, 1):
        for field in MATERIAL_FIELDS:
            assert f"mat{i}.{field}" in keys
    assert "mat2.color" not in keys
    assert {"light1.color", "light2.color", "light2.position", "light3.color",
            "light3.direction", "light4.color", "light4.position", "light4.direction",
            "light4.shape_coefficient", "background.color"} <= keys
    # each light exposes only what its kind has
    assert not {"light1.position", "light1.direction", "light2.direction",
                "light2.shape_coefficient", "light3.position", "light0.color"} & keys


def test_equal_materials_and_lights_keep_their_own_keys():
    """Mitsuba merges objects whose properties are all equal when it loads a scene; two
    equal `material` lines are still two materials (mat1, mat2), two equal `light` lines two
    lights, and changing one changes only the objects under it."""
    scene = ("light 0.5 0.5 0.5 point 0 0 5\nlight 0.5 0.5 0.5 point 0 0 5\n"
             "eye 0 0 8\nmaterial 1 0 0 0 1 0 1 0 0 1\ntranslate -1.5 0 0\nsphere\n"
             "material 1 0 0 0 1 0 1 0 0 1\nreset\ntranslate 1.5 0 0\nsphere\n")
    loaded = raymitsuba.load(scene, width=33, height=9)
    keys = set(loaded.params.keys())
    assert {"mat1.color", "mat2.color", "light1.color", "light2.color"} <= keys
    before = np.array(raymitsuba.render(loaded))
    loaded.params["mat2.color"] = [0.0, 1.0, 0.0]
    loaded.params.update()
    after = np.array(raymitsuba.render(loaded))
    # The left sphere (mat1) is unchanged; the right one (mat2) turned green: the same
    # kd (N.L) (two lights of 0.5 each) now in the green channel.
    np.testing.assert_array_equal(after[:, :16], before[:, :16])
    np.testing.assert_array_equal(after[4, 24, [1, 0, 2]], before[4, 24])


def test_the_scenes_shapes_are_the_translators_in_its_order():
    """Every shape of the dict is a shape of the scene, itself and in the dict's order, in
    every load. Mitsuba's optimizing loader merged the meshes of one material into one plain
    mesh (cornell_box.ray's three walls of mat1: no longer planes), put the merged shapes
    after the others in an order set by the materials' addresses, and a ray tying between
    two walls then hit whichever came first: the anti-aliased image differed in about one
    load in fifteen."""
    path = os.path.join(os.path.dirname(__file__), "..", "scenes", "cornell_box.ray")
    for _ in range(3):
        loaded = raymitsuba.load(path, width=8, height=6)
        shapes = [key for key, value in loaded.scene_dict.items()
                  if isinstance(value, dict) and value["type"] in ("rayplane", "sphere")]
        assert len(shapes) == 7
        assert [shape.id() for shape in loaded.scene.shapes()] == shapes


def test_params_are_traversed_at_their_first_use_and_kept():
    # A render through the integrator (as the CLI renders) does not traverse the scene;
    # loaded.params does, once.
    loaded = raymitsuba.load(SCENE, width=9, height=9)
    assert loaded._params is None
    image = loaded.integrator.render_array(loaded.scene)
    assert loaded._params is None and image.shape == (9, 9, 3)
    params = loaded.params
    assert params is loaded.params and "mat1.color" in params
    np.testing.assert_array_equal(np.array(raymitsuba.render(loaded)), image)


def test_changing_parameters_changes_the_render():
    loaded = raymitsuba.load(SCENE, width=9, height=9)
    params = loaded.params
    params["mat1.color"] = [0.2, 0.4, 1.0]
    params["mat1.diffuse_mix"] = 0.0
    params["light1.color"] = [1.0, 1.0, 1.0]
    params["background.color"] = [0.0, 0.5, 0.0]
    params.update()
    pixels = np.array(raymitsuba.render(loaded))
    # only the ambient term is left: ka A C with the new A and C
    np.testing.assert_allclose(pixels[4, 4], 0.5 * np.array([0.2, 0.4, 1.0]), rtol=0, atol=1e-6)
    np.testing.assert_allclose(pixels[0, 0], [0.0, 0.5, 0.0], rtol=0, atol=1e-7)

    params["mat1.diffuse_mix"] = 1.0
    params["mat1.ambient_mix"] = 0.0
    params["light2.color"] = [0.0, 0.0, 0.0]
    params["light4.color"] = [0.0, 0.0, 0.0]
    params["light3.direction"] = [-3.0, 0.0, -4.0]  # now from (3, 0, 4) / 5: N.L = 4 / 5
    params.update()
    pixels = np.array(raymitsuba.render(loaded))
    np.testing.assert_allclose(pixels[4, 4], 0.5 * 0.8 * np.array([0.2, 0.4, 1.0]),
                               rtol=0, atol=1e-6)


def test_render_spp_override():
    text = ("light 1 1 1 ambient\nmaterial 1 1 1  1 0 0 1  0 0 1\n"
            "triangle -14 -9.7 0  14 9.9 0  -20 20 0\n")
    one = raymitsuba.load(text, width=12, height=12)
    four = raymitsuba.load(text, width=12, height=12, spp=4)
    assert four.options.spp == 4
    a = np.array(raymitsuba.render(one, spp=4))
    b = np.array(raymitsuba.render(four))
    assert a.tobytes() == b.tobytes()
    assert not np.array_equal(a, np.array(raymitsuba.render(one)))  # edge pixels differ


# -- the MIT 6.837 dialect ----------------------------------------------------------------------
MIT = ("viewport 12 8\nlight 1 1 1 point 0 2 9\nsurface 0.5 0.5 1 0.2 0.8 0 1 0 0 0.5\n"
       "sphere 0 0 0 2\ntriangles v -3 -3 -1 v 3 -3 -1 v 0 3 -1 f 0 1 2 end\n")


def test_load_takes_the_dialect_and_the_viewport(mitsuba):
    loaded = raymitsuba.load(MIT)
    assert loaded.model.dialect == "mit6837"
    assert (loaded.options.width, loaded.options.height) == (12, 8)
    assert np.array(raymitsuba.render(loaded)).shape == (8, 12, 3)
    assert (raymitsuba.load(MIT, width=6).options.width, raymitsuba.load(MIT, width=6).options.height) == (6, 8)
    assert raymitsuba.load("sphere\n").options.width == 512
    with pytest.raises(RayError):
        raymitsuba.load(MIT, dialect="comp575")


def test_mit_6837_parameters(mitsuba):
    params = raymitsuba.load(MIT, width=4, height=4).params
    assert float(np.array(params["mat1.ior"]).ravel()[0]) == pytest.approx(2.0)  # 1 / index
    assert "background.color" in params


def test_the_povray_export_reads_both_dialects():
    import os
    import sys

    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                    "benchmarks"))
    from povray import export

    from raymitsuba.format.parser import parse_text

    mit = export(parse_text(MIT), 12, 8)
    assert mit.count("mesh {") == 1 and mit.count("triangle {") == 1 and "sphere {" in mit
    # the vertical angle of the horizontal fov 30, turned back into POV-Ray's horizontal angle
    assert "angle 30 }" in mit
    comp = export(parse_text("fov 45\nsphere\nlight 1 1 1 ambient\n"), 12, 8)
    horizontal = 2 * math.degrees(math.atan(math.tan(math.radians(22.5)) * 12 / 8))
    assert f"angle {horizontal:.9g} }}" in comp


def test_render_options_reach_the_integrator():
    import raymitsuba

    loaded = raymitsuba.load("sphere\n", width=8, height=8, aa=0.03, memory_budget=1 << 25,
                             bailout=1e-3, time_limit=10)
    integrator = loaded.integrator
    assert integrator.aa == pytest.approx(0.03) and integrator.memory_budget == 1 << 25
    assert integrator.tracer.bailout == pytest.approx(1e-3) and integrator.time_limit == 10
    plain = raymitsuba.load("sphere\n", width=8, height=8).integrator
    assert plain.aa == 0 and plain.tracer.bailout is None and plain.time_limit == 3600
