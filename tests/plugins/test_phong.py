"""The ``rayphong`` material model: the contract's local shading, term by term.

    L_local = sum_ambient A ka C + sum_lights [N.L > 0] I (kd C (N.L) + ks (R.V)^n)
    R = 2 (N.L) N - L, (R.V)^n taken as 0 where R.V <= 0; the highlight is not tinted by C.

First the model's function (phong_local, on directions chosen in numpy) and the BSDF's
surface interface, then through whole rendered images of a sphere, every pixel against the
formula in float64.
"""

import numpy as np
import pytest

from support import camera_rays, intersect_sphere, normalize, phong, render_ray

# float32 evaluation of a few products, a dot product and a power of a value in (0, 1]:
# relative error ~1e-6 (x n for the power); the values here are <= 2, so 2e-5 absolute
# covers n up to 20 with margin, while any wrong term changes a value by > 1e-2.
TOL = 2e-5


# -- the BSDF plugin on its own -----------------------------------------------------------------
@pytest.fixture(scope="module")
def phong_bsdf(mitsuba):
    return mitsuba.load_dict({"type": "rayphong", "color": mitsuba.ScalarColor3f(0.9, 0.5, 0.2),
                              "ambient_mix": 0.3, "diffuse_mix": 0.7, "specular_mix": 0.4,
                              "phong_coeff": 5.0, "reflectivity": 0.25, "refractivity": 0.5,
                              "ior": 1.33})


def _vectors(mi, a):
    return mi.Vector3f(*[np.ascontiguousarray(a[:, k], np.float32) for k in range(3)])


def test_phong_local_is_the_per_light_term(mitsuba):
    # phong_local, the one implementation the integrator shades with, against the formula
    # in float64, on random directions (N facing V).
    from raymitsuba.plugins.phong import phong_local

    mi = mitsuba
    rng = np.random.default_rng(5)
    v = normalize(rng.normal(size=(400, 3)))
    l = normalize(rng.normal(size=(400, 3)))
    n = normalize(rng.normal(size=(400, 3)))
    n = np.where(np.sum(n * v, axis=-1, keepdims=True) < 0, -n, n)
    want = phong(n, v, l, (0.9, 0.5, 0.2), 0.7, 0.4, 5.0)
    got = np.array(phong_local(_vectors(mi, n), _vectors(mi, v), _vectors(mi, l),
                               mi.Color3f(0.9, 0.5, 0.2), 0.7, 0.4, 5.0)).T  # (N, 3)
    assert np.sum(want.sum(-1) == 0) > 100 and np.sum(want.sum(-1) > 0) > 100  # both cases
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL)


def test_bsdf_is_a_surface_of_its_own_material(mitsuba, phong_bsdf):
    # The surface interface (plugins/whitted/protocol.py): its own material, no textures.
    from raymitsuba.plugins.whitted import protocol

    assert protocol.check_surface(phong_bsdf) is phong_bsdf
    assert phong_bsdf.material is phong_bsdf
    assert phong_bsdf.checker_size == 0.0 and phong_bsdf.image_textures == ()
    np.testing.assert_allclose(np.array(phong_bsdf.color).ravel(), [0.9, 0.5, 0.2], rtol=1e-6)
    for name, value in (("ambient_mix", 0.3), ("diffuse_mix", 0.7), ("specular_mix", 0.4),
                        ("phong_coeff", 5.0), ("reflectivity", 0.25), ("refractivity", 0.5),
                        ("ior", 1.33)):
        assert np.array(getattr(phong_bsdf, name)).ravel() == pytest.approx([value], rel=1e-6), name


def test_bsdf_parameters_are_traversable(mitsuba, phong_bsdf):
    params = mitsuba.traverse(phong_bsdf)
    for name in ("color", "ambient_mix", "diffuse_mix", "specular_mix", "phong_coeff",
                 "reflectivity", "refractivity", "ior"):
        assert name in params, name
    assert np.array(params["specular_mix"]).ravel() == pytest.approx([0.4])


# -- through the renderer ------------------------------------------------------------------------
def _sphere_image(material, lights, width=33, height=33, eye=(0, 0, 5)):
    text = f"eye {eye[0]} {eye[1]} {eye[2]}\n" + "".join(f"light {l}\n" for l in lights) \
        + f"material {material}\nsphere\n"
    return render_ray(text, width, height)


def _sphere_geometry(width=33, height=33, eye=(0, 0, 5)):
    o, d = camera_rays(width, height, eye=eye)
    t = intersect_sphere(o, d)
    p = o + t[..., None] * d
    # The float32 renderer may decide pixels within 1e-4 of the silhouette either way.
    oc_b = np.sum(o * d, axis=-1)
    closest = np.sqrt(np.maximum(o @ o - oc_b ** 2, 0.0))
    safe = np.abs(closest - 1.0) > 1e-4
    return o, d, t, p, safe


def test_point_light_diffuse_plus_specular_every_pixel():
    # A point light off to the side, an ambient light; kd C N.L + ks (R.V)^20 + ka A C.
    image = _sphere_image("1 0.2 0.4  0.1 0.5 0.6 20  0 0 1",
                          ["0.9 0.8 0.7 point 2 3 4", "0.2 0.2 0.2 ambient"])
    o, d, t, p, safe = _sphere_geometry()
    n = p  # unit sphere at the origin; the camera is outside, so N faces V
    l = normalize(np.array([2.0, 3.0, 4.0]) - p)
    want = phong(n, -d, l, (1, 0.2, 0.4), 0.5, 0.6, 20, (0.9, 0.8, 0.7)) \
        + 0.1 * 0.2 * np.array([1, 0.2, 0.4])
    want = np.where(np.isnan(t)[..., None], 0.0, want)
    spec = phong(n, -d, l, (0, 0, 0), 0.0, 1.0, 20)[..., 0]
    assert np.nanmax(spec) > 0.9  # the highlight's peak is in the image
    np.testing.assert_allclose(image[safe], want[safe], rtol=0, atol=TOL)


def test_specular_peak_is_ks_times_intensity_untinted():
    # The point light sits at the eye; at the centre pixel (33 x 33: exactly the view axis)
    # N = L = V, so R = V and (R.V)^n = 1 for any n: the pixel is ks I, whatever C is
    # (the highlight is not tinted by C; kd = ka = 0).
    for exponent in (1, 50, 1000):
        image = _sphere_image(f"1 0 0  0 0 0.75 {exponent}  0 0 1",
                              ["0.8 0.6 0.4 point 0 0 5"])
        np.testing.assert_allclose(image[16, 16], 0.75 * np.array([0.8, 0.6, 0.4]),
                                   rtol=0, atol=1e-6)
        assert image[16, 16, 1] > 0.4  # green, although C = (1, 0, 0)


def test_exponent_zero_and_lights_behind_the_surface():
    # n = 0 makes the lobe a step: 1 where R.V > 0, 0 elsewhere (then it is not 0^0 = 1
    # everywhere). A light behind the surface (N.L <= 0) adds nothing, neither diffuse nor
    # specular -- with n = 0, any leak of the specular term would show as a whole ks.
    # Light A (red) comes from the camera's side and the left: lit points with R.V > 0 and,
    # near the left limb, with R.V < 0. Light B (green) comes from behind on the right:
    # on the front, where it is behind the surface, R.V > 0 in places.
    image = _sphere_image("0.5 0.5 0.5  0 0.4 0.3 0  0 0 1",
                          ["1 0 0 directional 1 0 -1", "0 1 0 directional -1 0 1"])
    o, d, t, p, safe = _sphere_geometry()
    want = np.zeros(image.shape)
    steady = safe.copy()
    for travel, color in (((1, 0, -1), (1, 0, 0)), ((-1, 0, 1), (0, 1, 0))):
        l = normalize(-np.array(travel, float))
        want += phong(p, -d, l, (0.5, 0.5, 0.5), 0.4, 0.3, 0, color)
        n_dot_l = np.sum(p * l, axis=-1)
        r_dot_v = np.sum((2 * n_dot_l[..., None] * p - l) * -d, axis=-1)
        hit = np.isfinite(t) & safe
        if color[0]:
            assert np.sum(hit & (n_dot_l > 0.01) & (r_dot_v > 0.01)) > 5
            assert np.sum(hit & (n_dot_l > 0.01) & (r_dot_v < -0.01)) > 5
        else:
            assert np.sum(hit & (n_dot_l < -0.01) & (r_dot_v > 0.01)) > 5
        # Pixels where N.L or R.V is within 1e-5 of 0 sit on a step of the lobe; skip them.
        steady &= ~(np.abs(n_dot_l) < 1e-5) & ~(np.abs(r_dot_v) < 1e-5)
    want = np.where(np.isnan(t)[..., None], 0.0, want)
    np.testing.assert_allclose(image[steady], want[steady], rtol=0, atol=TOL)


def test_specular_is_seen_from_inside_a_closed_object():
    # The eye inside a big sphere (radius 1 around it: eye at the centre); N is flipped to
    # face V, so the inner surface is lit by a point light inside and has a highlight where
    # the light sits at the eye (R = V at every pixel: the sphere is centred on the eye).
    image = render_ray("eye 0 0 0\nlookat 0 0 -1\n"
                       "light 1 1 1 point 0 0 0\n"
                       "material 0.5 0.5 0.5  0 0.4 0.3 7  0 0 1\nsphere\n", 9, 9)
    # Every ray hits the inside at normal incidence: N.L = 1, R.V = 1.
    np.testing.assert_allclose(image, np.full(image.shape, 0.4 * 0.5 + 0.3), rtol=0, atol=1e-5)
