"""The sphere set (raymitsuba/geometry/sphere_set.py): a scene's many opaque spheres (and ellipsoids)
as one Mitsuba ``ellipsoids`` shape, which must draw exactly what the spheres drawn one by one
do."""

import math

import numpy as np
import pytest

import reference_tracer as rt
from support import render_ray

SET_MIN = 256  # the option's default (RenderOptions.sphere_set)


def sphere_grid(n, glass_every=0, mirror_every=0, texture_every=0, texture=None,
                eye_inside=False, stretch_every=0):
    """.RAY text: n spheres of radius 0.4 under rotations, each with its own material (every
    ``glass_every``-th glass, every ``mirror_every``-th a mirror, every ``texture_every``-th
    with the image ``texture``, every ``stretch_every``-th an ellipsoid: scaled by 0.45, 0.25
    and 0.35 before its rotations), over a checkered floor, lit by an ambient, a point and a
    directional light. ``eye_inside``: one more big opaque sphere around the eye."""
    side = math.ceil(math.sqrt(n))
    lines = [f"eye 0 {-0.9 * side:g} {1.3 * side:g}", "lookat 0 0 0", "up 0 1 0", "fov 45",
             "background 0.2 0.3 0.5", "light 0.15 0.15 0.15 ambient",
             f"light 0.7 0.7 0.6 point {side:g} {side:g} {2 * side:g}",
             "light 0.3 0.3 0.35 directional -1 -0.5 -2"]
    for k in range(n):
        x, y = k % side - (side - 1) / 2, k // side - (side - 1) / 2
        kr, kt = (0.6, 0) if mirror_every and k % mirror_every == 1 else (0.1, 0)
        if glass_every and k % glass_every == 0:
            kr, kt = 0.1, 0.8
        lines.append(f"material {0.3 + 0.7 * (k % 7) / 6:.3g} {0.3 + 0.7 * (k % 5) / 4:.3g} "
                     f"{0.3 + 0.7 * (k % 3) / 2:.3g}  0.2 0.7 0.3 30  {kr} {kt} 1.4")
        textured = texture_every and k % texture_every == 2
        lines += [f"texture {texture}"] if textured else []
        stretched = stretch_every and k % stretch_every == 0
        lines += ["scale 0.45 0.25 0.35" if stretched else "scale 0.4 0.4 0.4",
                  f"rotateX {17 * k % 180}", f"rotateY {29 * k % 360}",
                  f"translate {x:g} {y:g} 0", "sphere", "pop", "pop", "pop", "pop"]
        lines += ["texture none"] if textured else []
    if eye_inside:
        lines += ["material 0.5 0.5 0.5  0.5 0.5 0 1  0 0 1",
                  f"scale 0.5 0.5 0.5\ntranslate 0 {-0.9 * side:g} {1.3 * side:g}\nsphere\npop\npop"]
    lines += ["material 0.9 0.9 0.8  0.2 0.8 0 1  0.2 0 1", "checkerboard 0.9",
              "translate 0 0 -0.4", "rotateX 90", "plane", "pop", "pop"]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def translate(mitsuba):
    from raymitsuba.format.parser import parse_text
    from raymitsuba.translate import Options, translate as run

    def go(text, **options):
        return run(parse_text(text), Options(**{"width": 16, "height": 16, **options}))

    return go


def random_similarities(n, seed):
    """n to-world transforms T(c) R S(r) (n, 4, 4): random rotations (QR of Gaussians, made
    proper), radii and centres."""
    rng = np.random.default_rng(seed)
    q, r = np.linalg.qr(rng.normal(size=(n, 3, 3)))
    q *= np.sign(np.diagonal(r, axis1=1, axis2=2))[:, None, :]
    q[np.linalg.det(q) < 0, :, 0] *= -1
    m = np.tile(np.eye(4), (n, 1, 1))
    m[:, :3, :3] = q * rng.uniform(0.01, 100, n)[:, None, None]
    m[:, :3, 3] = rng.uniform(-50, 50, (n, 3))
    return m


def test_unpacking_gives_the_centre_the_radius_and_the_inverse_transform():
    from raymitsuba.geometry import sphere_set

    m = random_similarities(500, seed=3)
    center, radius, to_object, ellipsoid = sphere_set.unpack(sphere_set.pack(m))
    # float32 storage: centres and radii to 1e-7 relative, the inverse to 1e-6
    np.testing.assert_allclose(center, m[:, :3, 3], rtol=1e-6, atol=1e-5)
    np.testing.assert_allclose(radius, np.linalg.norm(m[:, :3, 0], axis=1), rtol=1e-6)
    inverse = np.linalg.inv(m)[:, :3, :]
    scale = np.abs(inverse).max(axis=(1, 2))[:, None, None]
    np.testing.assert_allclose(to_object / scale, inverse / scale, atol=2e-6)
    assert not ellipsoid.any()


def test_an_ellipsoids_data_maps_its_surface_onto_the_unit_sphere():
    """Any invertible affine transform (shear and mirroring included) packs as an ellipsoid
    whose world-to-object transform maps the transformed unit sphere back onto the unit
    sphere -- the same surface, in the set's own object space -- to float32 storage's
    rounding (6e-8 relative per number) times the transform's condition number, with a
    margin of 16."""
    from raymitsuba.geometry import sphere_set

    rng = np.random.default_rng(5)
    m = np.tile(np.eye(4), (400, 1, 1))
    m[:, :3, :3] = rng.normal(size=(400, 3, 3)) * rng.uniform(0.1, 10, (400, 1, 1))
    m[:, :3, 3] = rng.uniform(-20, 20, (400, 3))
    center, _, to_object, ellipsoid = sphere_set.unpack(sphere_set.pack(m))
    assert ellipsoid.all()
    np.testing.assert_allclose(center, m[:, :3, 3], rtol=1e-6, atol=1e-5)
    x = rng.normal(size=(400, 3))
    x /= np.linalg.norm(x, axis=1, keepdims=True)  # points of the unit sphere
    world = np.einsum("nij,nj->ni", m[:, :3, :3], x) + m[:, :3, 3]
    local = np.einsum("nij,nj->ni", to_object[:, :, :3], world) + to_object[:, :, 3]
    error = np.abs(np.linalg.norm(local, axis=1) - 1.0)
    assert (error <= 1e-6 * np.linalg.cond(m[:, :3, :3])).all(), error.max()


def test_quaternions_of_the_axis_rotations_are_the_textbook_ones():
    from raymitsuba.geometry import sphere_set

    half = math.sqrt(0.5)
    r = np.array([np.eye(3), [[1, 0, 0], [0, 0, -1], [0, 1, 0]], [[-1, 0, 0], [0, -1, 0], [0, 0, 1]]])
    q = sphere_set.quaternion(r)
    np.testing.assert_allclose(np.abs(q), [[0, 0, 0, 1], [half, 0, 0, half], [0, 0, 1, 0]],
                               atol=1e-12)
    np.testing.assert_allclose(sphere_set.rotation(q), r, atol=1e-12)


def test_a_scene_with_enough_opaque_spheres_draws_them_as_one_shape(translate):
    d = translate(sphere_grid(SET_MIN + 40, glass_every=10))
    spheres = [k for k, v in d.items() if isinstance(v, dict) and v.get("type") == "sphere"]
    shape = d["spheres"]
    assert shape["type"] == "ellipsoids" and shape["extent"] == 1.0
    members = len(np.asarray(shape["data"])) // 10
    # the 30 glass spheres stay Mitsuba spheres; the others are the set, each with its surface
    assert (len(spheres), members) == (30, SET_MIN + 40 - 30)
    # each member has a material of its own: all of them rows of the set's table, with their
    # keys' numbers (material 1 is glass), and no rayphong of their own
    surfaces = shape["bsdf"]
    assert surfaces["type"] == "raysurfaceset" and "surface_0" not in surfaces
    np.testing.assert_array_equal(np.asarray(surfaces["surface_of"]), np.arange(members))
    ids = np.asarray(surfaces["material_ids"])
    assert len(ids) == members and ids[0] == 2 and 11 not in ids  # (mat11: glass)
    assert "mat2" not in d and "mat11" in d and "mat0" in d
    assert np.asarray(surfaces["materials"]).reshape(-1, 10)[0, 3:].tolist() == \
        pytest.approx([0.2, 0.7, 0.3, 30, 0.1, 0, 1.4])


def test_few_spheres_a_sphere_around_the_eye_and_sphere_set_0_stay_single_spheres(translate):
    assert "spheres" not in translate(sphere_grid(SET_MIN - 1))
    assert "spheres" not in translate(sphere_grid(SET_MIN + 5), sphere_set=0)
    d = translate(sphere_grid(SET_MIN + 5, eye_inside=True))
    assert len(np.asarray(d["spheres"]["data"])) // 10 == SET_MIN + 5
    assert sum(v.get("type") == "sphere" for v in d.values() if isinstance(v, dict)) == 1


def test_untextured_opaque_ellipsoids_join_the_set_the_others_stay_tessellated(translate,
                                                                              tmp_path):
    from PIL import Image

    Image.fromarray(np.zeros((4, 4, 3), np.uint8)).save(tmp_path / "t.png")
    # 300 spheres, every 3rd stretched; glass ones (every 10th) stay out of the set, textured
    # ones (every 7th, 2 mod 7) join it as spheres but stay tessellated as ellipsoids
    text = sphere_grid(300, glass_every=10, stretch_every=3, texture_every=7,
                       texture=tmp_path / "t.png")
    d = translate(text)
    members = len(np.asarray(d["spheres"]["data"])) // 10
    single = sum(v.get("type") == "sphere" for v in d.values() if isinstance(v, dict))
    k = np.arange(300)
    stretched, glass, textured = k % 3 == 0, k % 10 == 0, k % 7 == 2
    assert single == np.count_nonzero(~stretched & glass)
    assert members == np.count_nonzero(~glass & ~(stretched & textured))
    # the set's ellipsoids are the stretched ones; no sphere is tessellated twice or lost
    from raymitsuba.geometry import sphere_set

    assert np.count_nonzero(sphere_set.unpack(np.asarray(d["spheres"]["data"]))[3]) == \
        np.count_nonzero(stretched & ~glass & ~textured)
    assert any(name.startswith("quadrics_") for name in d)  # the glass and textured ellipsoids
    assert "quadrics_0" not in translate(sphere_grid(300, stretch_every=3))  # all joined


def independent_error(text, width=40, height=30, **options):
    """(The largest error per pixel of the render of ``text`` at depth 3 against
    reference_tracer.py's, which pixels that tracer marks fragile) -- as test_whitted's
    whole-image test."""
    from raymitsuba.format.parser import parse_text

    want, fragile = rt.render(rt.from_model(parse_text(text), width, height), width, height,
                              max_depth=3)
    image = render_ray(text, width, height, max_depth=3, **options)
    return np.abs(image - want).max(axis=-1), fragile


def test_ellipsoids_of_the_set_match_the_independent_tracer(mitsuba):
    """Exact ellipsoids (a third of 260 spheres, under non-uniform scales and rotations, some
    mirrors) against reference_tracer.py's exact ellipsoids: 1e-4 away from the pixels it
    marks fragile, as the spheres' test; with --sphere-set 0 they are tessellated and differ
    by more (the 8-segment silhouettes and normals of the budget)."""
    text = sphere_grid(SET_MIN + 4, mirror_every=4, stretch_every=3)
    error, fragile = independent_error(text)
    assert fragile.mean() < 0.3
    assert error[~fragile].max() < 1e-4
    assert independent_error(text, sphere_set=0)[0][~fragile].max() > 1e-2


def test_the_set_draws_what_single_spheres_draw_but_for_grazing_rays(mitsuba, tmp_path):
    """Textured (uv), mirror and glass spheres, depth 4: both representations solve the hit
    from the same table (hits.py), so pixels agree to float32 rounding (the set's uv come
    from its quaternions: observed 7e-6 at most), except where a ray grazes a sphere (hit by
    one ray tracer, missed by the other: none observed here; at most 1% allowed)."""
    from PIL import Image

    rng = np.random.default_rng(1)
    Image.fromarray(rng.integers(0, 256, (16, 32, 3), dtype=np.uint8)).save(tmp_path / "noise.png")
    text = sphere_grid(300, glass_every=9, mirror_every=4, texture_every=5,
                       texture=tmp_path / "noise.png")
    one = render_ray(text, 96, 72, max_depth=4)
    single = render_ray(text, 96, 72, max_depth=4, sphere_set=0)
    differs = np.abs(one - single).max(axis=-1) > 1e-5
    assert differs.mean() < 0.01, differs.sum()
    assert np.ptp(one) > 0.5


def test_a_set_scene_matches_the_independent_tracer(mitsuba):
    """The set (with glass and mirror spheres beside it) against reference_tracer.py, as
    test_whitted's whole-image test: 1e-4 away from the pixels it marks fragile."""
    error, fragile = independent_error(sphere_grid(SET_MIN + 4, glass_every=9, mirror_every=4))
    assert fragile.mean() < 0.3
    assert error[~fragile].max() < 1e-4


def test_a_set_material_made_transparent_is_refused_with_the_reason(mitsuba):
    import raymitsuba

    loaded = raymitsuba.load(sphere_grid(SET_MIN), width=8, height=6)
    from raymitsuba.plugins.whitted.surfaces import OpaqueSetError

    loaded.params["mat3.refractivity"] = 0.5
    loaded.params.update()
    with pytest.raises(Exception) as raised:  # (Dr.Jit's custom operation wraps it)
        raymitsuba.render(loaded)
    cause = raised.value if isinstance(raised.value, OpaqueSetError) else raised.value.__cause__
    assert isinstance(cause, OpaqueSetError)
    assert "sphere set" in str(cause) and "sphere_set=0" in str(cause)


def test_moving_a_set_sphere_is_refused_but_the_camera_moves(mitsuba):
    import drjit as dr
    import raymitsuba
    from raymitsuba.format.writeback import ParameterError

    loaded = raymitsuba.load(sphere_grid(SET_MIN), width=8, height=6)
    with pytest.raises(ParameterError, match="sphere set"):
        dr.enable_grad(loaded.params["translate5.offset"])
        loaded.params.update()
    before = np.array(raymitsuba.render(raymitsuba.load(sphere_grid(SET_MIN), width=8, height=6)))
    loaded = raymitsuba.load(sphere_grid(SET_MIN), width=8, height=6)
    loaded.params["camera.eye"] = loaded.params["camera.eye"] + mitsuba.Point3f(0.5, 0, 0)
    loaded.params.update()
    assert np.abs(np.array(raymitsuba.render(loaded)) - before).max() > 0.05


@pytest.fixture(scope="module")
def crowd(mitsuba):
    """A sphere set whose spheres' materials are rows of its table (and a glass sphere and
    the floor beside it, with rayphong materials)."""
    import raymitsuba

    loaded = raymitsuba.load(sphere_grid(SET_MIN + 4, glass_every=200, mirror_every=4),
                             width=96, height=72)  # (a sphere spans about 3 pixels)
    assert "spheres" in loaded.scene_dict and "mat130" not in loaded.scene_dict
    return loaded


@pytest.mark.parametrize("key", ["mat130.color", "mat130.diffuse_mix", "mat126.reflectivity"])
def test_a_table_materials_gradient_matches_finite_differences(mitsuba, crowd, key):
    """Keys of the table's rows (sphere 129 near the centre; 125 a mirror) are parameters as
    a rayphong's are: FD within 1% (as test_gradients), forward and reverse alike."""
    from test_gradients import derivatives

    finite, reverse, forward = derivatives(mitsuba, crowd, key, seed=5)
    assert abs(finite) > 1e-3
    assert reverse == pytest.approx(finite, rel=1e-2)
    assert forward == pytest.approx(reverse, rel=1e-5, abs=1e-6)


def test_a_fit_of_a_table_material_recovers_it(mitsuba):
    import raymitsuba
    from raymitsuba import fit as F

    text = sphere_grid(SET_MIN)
    target = np.array(raymitsuba.render(raymitsuba.load(text, width=96, height=72)))
    lines = text.splitlines()
    where = [n for n, line in enumerate(lines) if line.startswith("material")][129]  # mat130
    lines[where] = lines[where].replace(" 0.2 0.7 ", " 0.2 0.4 ")
    loaded = raymitsuba.load("\n".join(lines) + "\n", width=96, height=72)
    assert "spheres" in loaded.scene_dict and "mat130" not in loaded.scene_dict
    result = F.fit(loaded, target, ["mat130.diffuse_mix"], iters=60, lr=0.05)
    assert result.fitted["mat130.diffuse_mix"] == pytest.approx(0.7, abs=5e-3)


def test_kernels_do_not_depend_on_the_number_of_spheres_in_the_set(mitsuba):
    """As tests/test_scale.py for single spheres: 300 then 1,200 spheres in the set, each
    with its own material, render with the same kernels, all of the second from the cache."""
    from test_scale import kernels_of_a_render

    few = kernels_of_a_render(sphere_grid(300, mirror_every=4))
    many = kernels_of_a_render(sphere_grid(1200, mirror_every=4))
    assert [ops for ops, _ in many] == [ops for ops, _ in few]
    assert all(hit for _, hit in many)
