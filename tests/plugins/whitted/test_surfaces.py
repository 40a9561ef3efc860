"""The surface table (plugins/whitted/surfaces.py): slots, parameter arrays, base colors, gradients
attached only where enabled, the shadow crossings' kt derivative, the scene terms.

The scene: four spheres. Two share material A, one wears A through a ``raytextured`` surface
(a constant texture and a checkerboard), one has material B. So three distinct BSDFs (three
slots) and two materials."""

import numpy as np
import pytest

A = dict(color=(0.8, 0.4, 0.2), ambient_mix=0.5, diffuse_mix=0.7, specular_mix=0.3,
         phong_coeff=8.0, reflectivity=0.25, refractivity=0.5, ior=1.4)
B = dict(color=(0.1, 0.2, 0.3), ambient_mix=0.1, diffuse_mix=0.2, specular_mix=0.6,
         phong_coeff=30.0, reflectivity=0.0, refractivity=0.0, ior=1.0)
TEXEL = (0.5, 0.25, 1.0)


def material(mi, values):
    return {"type": "rayphong", **{k: (mi.ScalarColor3f(*v) if k == "color" else v)
                                   for k, v in values.items()}}


def sphere(x, bsdf):
    import mitsuba as mi

    return {"type": "sphere", "center": mi.ScalarPoint3f(x, 0, 0), "radius": 0.4, "bsdf": bsdf}


@pytest.fixture()
def scene(mitsuba):
    mi = mitsuba
    texture = {"type": "bitmap", "bitmap": mi.Bitmap(np.tile(np.float32(TEXEL), (2, 2, 1))),
               "raw": True, "filter_type": "nearest"}
    return mi.load_dict({
        "type": "scene", "matA": material(mi, A), "matB": material(mi, B),
        "surface0": {"type": "raytextured", "material": {"type": "ref", "id": "matA"},
                     "texture": texture, "checker": {"type": "raychecker", "size": 0.5}},
        "s0": sphere(0, {"type": "ref", "id": "matA"}),
        "s1": sphere(1, {"type": "ref", "id": "matA"}),
        "s2": sphere(2, {"type": "ref", "id": "surface0"}),
        "s3": sphere(3, {"type": "ref", "id": "matB"}),
        "light": {"type": "raylight", "kind": "point", "color": mi.ScalarColor3f(0.5),
                  "position": mi.ScalarPoint3f(0, 5, 5)},
        "ambient1": {"type": "raylight", "kind": "ambient", "color": mi.ScalarColor3f(0.1)},
        "ambient2": {"type": "raylight", "kind": "ambient", "color": mi.ScalarColor3f(0.2)},
        "background": {"type": "raybackground", "color": mi.ScalarColor3f(0.3, 0.6, 0.9)},
    })


def slots_of_shapes(mi, scene, surfaces):
    """The slot of each shape's BSDF, in scene.shapes() order (s0, s1, s2, s3)."""
    return np.array(surfaces.slot(scene.shapes_dr(), mi.UInt32(0), True)).ravel().tolist()


def test_one_slot_per_distinct_bsdf(mitsuba, scene):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    surfaces = Surfaces(scene)
    assert surfaces.layout.count == 3
    slots = slots_of_shapes(mitsuba, scene, surfaces)
    assert slots[0] == slots[1]  # s0 and s1 share the BSDF matA
    assert sorted(set(slots)) == [0, 1, 2]


@pytest.mark.parametrize("name", ["ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
                                  "reflectivity", "refractivity", "ior"])
def test_parameters_by_slot_are_the_materials(mitsuba, scene, name):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    surfaces = Surfaces(scene)
    by_shape = [A, A, A, B]  # the textured surface has A's parameters
    slots = slots_of_shapes(mitsuba, scene, surfaces)
    got = np.array(surfaces.get(name, mitsuba.UInt32(slots), True)).ravel()
    np.testing.assert_allclose(got, [m[name] for m in by_shape], rtol=1e-6)


def test_base_color_is_color_times_texture_times_checker(mitsuba, scene):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    mi = mitsuba
    surfaces = Surfaces(scene)
    slots = slots_of_shapes(mi, scene, surfaces)
    # Each shape at three texture coordinates: (0.1, 0.1) and (0.6, 0.6) lie on even
    # squares of side 0.5, (0.6, 0.1) on an odd one.
    u, v = [0.1, 0.6, 0.6] * 4, [0.1, 0.6, 0.1] * 4
    si = mi.SurfaceInteraction3f()
    si.uv = mi.Point2f(np.float32(u), np.float32(v))
    lane_slots = mi.UInt32(np.repeat(slots, 3).astype(np.uint32))
    got = np.array(surfaces.base_color(si, lane_slots, mi.Bool(True)).color).T.reshape(4, 3, 3)
    checker = np.array([1.0, 1.0, 0.0])[:, None]
    want = [np.tile(A["color"], (3, 1)), np.tile(A["color"], (3, 1)),
            checker * np.multiply(A["color"], TEXEL), np.tile(B["color"], (3, 1))]
    np.testing.assert_allclose(got, np.array(want), rtol=1e-6)


def test_a_new_value_is_read_at_the_next_build(mitsuba, scene):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    params = mitsuba.traverse(scene)
    params["matB.diffuse_mix"] = 0.9
    params.update()
    surfaces = Surfaces(scene)
    slot = slots_of_shapes(mitsuba, scene, surfaces)[3]
    assert np.array(surfaces.get("diffuse_mix", mitsuba.UInt32(slot), True))[0] == \
        pytest.approx(0.9)


def test_gradients_attach_only_where_enabled(mitsuba, scene):
    import drjit as dr
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    mi = mitsuba
    assert not dr.grad_enabled(Surfaces(scene).diffuse_mix)
    params = mi.traverse(scene)
    kd, color = params["matA.diffuse_mix"], params["matA.color"]
    dr.enable_grad(kd, color)
    surfaces = Surfaces(scene)
    assert dr.grad_enabled(surfaces.diffuse_mix) and dr.grad_enabled(surfaces.color)
    assert not dr.grad_enabled(surfaces.specular_mix)
    # d/dkd_A of the sum over all four shapes' kd: three of them (s0, s1, s2) have A's.
    slots = mi.UInt32(slots_of_shapes(mi, scene, surfaces))
    loss = dr.sum(surfaces.get("diffuse_mix", slots, True)) \
        + dr.sum(dr.gather(mi.Color3f, surfaces.color, slots).y)
    dr.backward(loss)
    assert dr.grad(kd)[0] == pytest.approx(3.0)
    np.testing.assert_allclose(np.array(dr.grad(color)).ravel(), [0, 3, 0])
    # and the values are those of the materials
    got = np.array(surfaces.get("diffuse_mix", slots, True)).ravel()
    np.testing.assert_allclose(got, [0.7, 0.7, 0.7, 0.2], rtol=1e-6)


def test_kt_derivative_from_the_record_of_crossed_slots(mitsuba, scene):
    # T = kt_A^2 (two crossings of A, the rest of the record unused): the value stays T,
    # the derivative is dT/dkt_A = 2 kt_A.
    import drjit as dr
    from raymitsuba.plugins.whitted.surfaces import NO_SLOT, Surfaces, with_kt_derivative

    mi = mitsuba
    kt = mi.traverse(scene)["matA.refractivity"]
    dr.enable_grad(kt)
    surfaces = Surfaces(scene)
    slot_a = slots_of_shapes(mi, scene, surfaces)[0]
    record = (mi.UInt32(slot_a), mi.UInt32(slot_a)) + (mi.UInt32(NO_SLOT),) * 14
    transmittance = with_kt_derivative(surfaces, mi.Float(0.25), record)
    assert transmittance[0] == 0.25  # exactly
    dr.backward(transmittance)
    assert dr.grad(kt)[0] == pytest.approx(2 * 0.25 / 0.5, rel=1e-6)
    assert with_kt_derivative(surfaces, mi.Float(0.25), None)[0] == 0.25


def test_transparency_is_known_from_the_values(mitsuba, scene):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    assert Surfaces(scene).any_transparent  # A has kt = 0.5
    params = mitsuba.traverse(scene)
    params["matA.refractivity"] = 0.0
    params.update()
    assert not Surfaces(scene).any_transparent


def test_scene_terms_sum_the_ambient_lights_and_keep_the_others(mitsuba, scene):
    from raymitsuba.plugins.whitted.surfaces import SceneTerms

    terms = SceneTerms(scene)
    np.testing.assert_allclose(np.array(terms.ambient).ravel(), [0.3] * 3, rtol=1e-6)
    assert [light.kind for light in terms.direct] == ["point"]
    np.testing.assert_allclose(np.array(terms.background).ravel(), [0.3, 0.6, 0.9], rtol=1e-6)


def test_a_scene_without_objects_has_slots_of_zeros(mitsuba):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    surfaces = Surfaces(mitsuba.load_dict({"type": "scene"}))
    assert surfaces.layout.count == 0 and not surfaces.any_transparent
    assert not np.any(np.array(surfaces.diffuse_mix))


def test_a_later_table_of_the_same_shapes_keeps_the_layout_and_reads_the_values_anew(
        mitsuba, scene):
    """The slots, materials and textures are read from the plugins once per scene (a render
    reuses the previous render's layout); the parameter values are read at every render, as
    the materials keep them (``host_values``, current after SceneParameters.update)."""
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    first = Surfaces(scene)
    params = mitsuba.traverse(scene)
    params["matB.color"] = mitsuba.Color3f(0.9, 0.8, 0.7)
    params["matA.ior"] = 2.5
    params.update()
    later = Surfaces(scene, first)
    assert later.layout.slot_of_shape is first.layout.slot_of_shape \
        and later.layout.materials is first.layout.materials
    slot_b = slots_of_shapes(mitsuba, scene, later)[3]
    slot_a = slots_of_shapes(mitsuba, scene, later)[0]
    np.testing.assert_allclose(later.host["color"][slot_b], [0.9, 0.8, 0.7], rtol=1e-6)
    assert later.host["ior"][slot_a] == pytest.approx(2.5)
    np.testing.assert_allclose(np.array(later.color)[:, slot_b], [0.9, 0.8, 0.7], rtol=1e-6)
    assert first.host["ior"][slot_a] == pytest.approx(A["ior"])  # the first table kept its own


def test_a_table_of_other_shapes_builds_its_own_layout(mitsuba, scene):
    from raymitsuba.plugins.whitted.surfaces import Surfaces

    other = mitsuba.load_dict({"type": "scene", "m": material(mitsuba, B),
                               "s": sphere(0, {"type": "ref", "id": "m"})})
    table = Surfaces(other, Surfaces(scene))
    assert table.layout.count == 1 and table.host["diffuse_mix"][0] == pytest.approx(B["diffuse_mix"])
