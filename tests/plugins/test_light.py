"""The ``raylight`` emitter and the contract's four kinds of light.

* ambient: I everywhere, unshadowed; several add up;
* point: I from a position, no distance falloff; its shadow ray stops at the light;
* directional: I from -(direction of travel), which need not be unit length;
* spotlight: I (cos a)^s where cos a > 0, a the angle between the axis and the
  direction from the light to the point; 0 where cos a <= 0.
"""

import math

import numpy as np
import pytest

from support import (camera_rays, intersect_plane, intersect_sphere, normalize, phong,
                      render_ray)

# float32 shading of values <= 1 (a normalisation, a dot product, a power): ~1e-6
# relative; 1e-5 leaves margin and is far below any semantic error.
TOL = 1e-5

# A plane z = 0 facing the camera (0, 0, 5): every pixel hits it with N = (0, 0, 1).
FACING_PLANE = "rotateX 90\nplane\n"


def _plane_points(width, height, eye=(0, 0, 5), fov=45.0):
    o, d = camera_rays(width, height, eye=eye, fov=fov)
    t = intersect_plane(o, d, (0, 0, 0), (0, 0, 1))
    return o + t[..., None] * d, d


# -- the plugin's illuminate(), directly ---------------------------------------------------------
@pytest.mark.parametrize("kind", ["point", "directional", "spotlight"])
def test_illuminate_returns_direction_distance_and_intensity(mitsuba, kind):
    mi = mitsuba
    props = {"type": "raylight", "kind": kind, "color": mi.ScalarColor3f(0.5, 1.0, 2.0)}
    if kind != "directional":
        props["position"] = mi.ScalarPoint3f(1.0, 2.0, 3.0)
    if kind != "point":
        props["direction"] = mi.ScalarVector3f(0.0, -3.0, 0.0)  # not unit length
    if kind == "spotlight":
        props["shape_coefficient"] = 3.0
    light = mi.load_dict(props)
    points = np.array([[1.0, 0.0, 3.0], [4.0, 1.0, -1.0], [1.0, 5.0, 3.0], [-2.0, 2.0, 3.0]])
    wi, dist, intensity = light.illuminate(mi.Point3f(*[np.ascontiguousarray(c, np.float32)
                                                        for c in points.T]))
    # (a directional light's values do not depend on the point: they may come back as width 1)
    wi, dist, intensity = (np.broadcast_to(np.array(a).T, shape) for a, shape in
                           ((wi, (4, 3)), (dist, (4,)), (intensity, (4, 3))))
    color = np.array([0.5, 1.0, 2.0])
    if kind == "directional":
        np.testing.assert_allclose(wi, np.tile([0.0, 1.0, 0.0], (4, 1)), atol=1e-7)
        assert np.all(np.isinf(dist))
        np.testing.assert_allclose(intensity, np.tile(color, (4, 1)), rtol=1e-7)
        return
    to_light = np.array([1.0, 2.0, 3.0]) - points
    np.testing.assert_allclose(wi, normalize(to_light), atol=1e-6)
    np.testing.assert_allclose(dist, np.linalg.norm(to_light, axis=1), rtol=1e-6)
    if kind == "point":  # no distance falloff: the same intensity at every distance
        np.testing.assert_allclose(intensity, np.tile(color, (4, 1)), rtol=1e-7)
    else:
        cos_a = normalize(-to_light) @ np.array([0.0, -1.0, 0.0])
        want = np.where(cos_a > 0, np.maximum(cos_a, 0) ** 3, 0.0)[:, None] * color
        assert cos_a[0] == pytest.approx(1.0) and cos_a[2] < 0  # on the axis, behind
        np.testing.assert_allclose(intensity, want, rtol=0, atol=1e-6)


# -- through the renderer ------------------------------------------------------------------------
def test_point_light_has_no_distance_falloff():
    # A point light 0.5 above the plane: kd C I N.L with N.L = 0.5 / |light - p| and no 1/r^2
    # (with falloff the corners, 2.5 units away, would be 25x darker than the centre).
    width = height = 32
    image = render_ray("light 0.9 0.8 0.7 point 0 0 0.5\n"
                       "material 0.5 1 0.25  0 0.8 0 1  0 0 1\n" + FACING_PLANE, width, height)
    p, d = _plane_points(width, height)
    l = normalize(np.array([0.0, 0.0, 0.5]) - p)
    want = 0.8 * np.array([0.5, 1.0, 0.25]) * np.array([0.9, 0.8, 0.7]) * l[..., 2:3]
    np.testing.assert_allclose(image, want, rtol=0, atol=TOL)
    # The same holds wherever the light is: straight under it, N.L = 1 and the pixel is kd C I.
    for height_above in (0.01, 1000.0):
        image = render_ray(f"light 0.9 0.8 0.7 point 0 0 {height_above}\n"
                           "material 0.5 1 0.25  0 0.8 0 1  0 0 1\n" + FACING_PLANE, 33, 33)
        np.testing.assert_allclose(image[16, 16], 0.8 * np.array([0.45, 0.8, 0.175]),
                                   rtol=0, atol=TOL)


def test_point_light_shadow_ray_stops_at_the_light():
    # A sphere on the far side of the light (along the line from plane points through it),
    # out of view: it must not shadow anything; and all of the plane is lit.
    width = height = 24
    text = ("eye 0 0 5\nfov 60\n"
            "light 1 1 1 point 0 0 1\n"
            "material 1 1 1  0 1 0 1  0 0 1\n" + FACING_PLANE +
            "reset\nscale 0.4 0.4 0.4\ntranslate 2.3 0 2\nsphere\n")
    image = render_ray(text, width, height)
    p, d = _plane_points(width, height, fov=60)
    to_light = np.array([0.0, 0.0, 1.0]) - p
    # The extended shadow rays of some pixels do run into the sphere, beyond the light.
    assert np.isfinite(intersect_sphere(p, normalize(to_light), (2.3, 0, 2), 0.4)).sum() >= 3
    want = normalize(to_light)[..., 2:3] * np.ones(3)
    np.testing.assert_allclose(image, want, rtol=0, atol=TOL)


@pytest.mark.parametrize("travel", [(1, 0, 0), (3, -4, -12)])
def test_directional_light_comes_from_minus_its_direction(travel):
    # "light ... directional x y z": the light travels along (x, y, z), so it comes from
    # -(x, y, z): travelling +x, it lights the sphere's left (-x) half. The vector need not
    # be unit length.
    width = height = 33
    image = render_ray("light 1 1 1 directional {} {} {}\n".format(*travel) +
                       "material 1 1 1  0 1 0 1  0 0 1\nsphere\n", width, height)
    o, d = camera_rays(width, height)
    t = intersect_sphere(o, d)
    n = o + t[..., None] * d
    l = normalize(-np.array(travel, float))
    want = np.where(np.isnan(t), 0.0, np.maximum(n @ l, 0.0))[..., None] * np.ones(3)
    b = np.sum(o * d, axis=-1)
    safe = np.abs(np.sqrt(np.maximum(o @ o - b * b, 0)) - 1.0) > 1e-4  # off the silhouette
    np.testing.assert_allclose(image[safe], want[safe], rtol=0, atol=TOL)
    if travel == (1, 0, 0):
        assert image[16, 10, 0] > 0.5 and image[16, 22, 0] == 0.0  # left lit, right dark


@pytest.mark.parametrize("exponent", [0.0, 4.0, 30.0])
def test_spotlight_exponent(exponent):
    # A spotlight 1 above the plane with its axis tilted toward +x; kd C I N.L (cos a)^s,
    # and 0 where cos a <= 0 (on the plane at x < -5 (1 - ...): the left part of the image).
    width = height = 32
    axis = np.array([1.0, 0.0, -0.2])
    image = render_ray("light 1 0.5 0.25 spotlight 0 0 1  1 0 -0.2  {}\n".format(exponent) +
                       "material 1 1 1  0 1 0 1  0 0 1\n" + FACING_PLANE, width, height)
    p, d = _plane_points(width, height)
    to_point = normalize(p - np.array([0.0, 0.0, 1.0]))
    cos_a = to_point @ normalize(axis)
    n_dot_l = -to_point[..., 2]
    falloff = np.where(cos_a > 0, np.maximum(cos_a, 0.0) ** exponent, 0.0)
    want = (n_dot_l * falloff)[..., None] * np.array([1.0, 0.5, 0.25])
    assert np.sum(cos_a < -0.01) > 20 and np.sum(cos_a > 0.01) > 20  # both sides in view
    steady = np.abs(cos_a) > 1e-5  # s = 0 is a step at cos a = 0
    np.testing.assert_allclose(image[steady], want[steady], rtol=0, atol=TOL)


def test_ambient_lights_add_up_and_cast_no_shadow():
    # A sphere in front of the plane and only ambient light: the plane is uniformly
    # ka (A1 + A2) C, even right behind the sphere.
    image = render_ray("light 0.25 0.5 0.125 ambient\nlight 0.25 0 0.125 ambient\n"
                       "material 1 0.5 1  0.5 1 1 1  0 0 1\n" + FACING_PLANE +
                       "reset\nmaterial 0 0 0  0 0 0 1  0 0 1\nscale 0.5 0.5 0.5\n"
                       "translate 0 0 1\nsphere\n", 24, 24)
    o, d = camera_rays(24, 24)
    sphere = np.isfinite(intersect_sphere(o, d, (0, 0, 1), 0.5))
    b = np.sum((o - [0, 0, 1]) * d, axis=-1)
    safe = np.abs(np.sqrt(np.maximum(np.sum((o - [0, 0, 1]) ** 2) - b * b, 0)) - 0.5) > 1e-4
    want = np.where(sphere[..., None], 0.0, 0.5 * np.array([0.5, 0.5, 0.25]) * [1, 0.5, 1])
    assert sphere.sum() > 20
    np.testing.assert_allclose(image[safe], want[safe], rtol=0, atol=1e-7)


def test_light_color_scales_each_channel_and_lights_add():
    # Two point lights of different colors at mirror positions: the sum of their terms.
    width = height = 24
    image = render_ray("light 1 0 0 point -1 0 1\nlight 0 0.5 1 point 1 0 1\n"
                       "material 1 1 1  0 1 0 1  0 0 1\n" + FACING_PLANE, width, height)
    p, d = _plane_points(width, height)
    want = np.zeros(image.shape)
    for pos, color in (((-1, 0, 1), (1, 0, 0)), ((1, 0, 1), (0, 0.5, 1))):
        l = normalize(np.array(pos, float) - p)
        want += phong(np.broadcast_to([0.0, 0, 1], p.shape), -d, l, (1, 1, 1), 1.0, 0.0, 1, color)
    np.testing.assert_allclose(image, want, rtol=0, atol=TOL)
    assert math.isclose(float(image[12, 4, 0]), float(want[12, 4, 0]), abs_tol=TOL)
