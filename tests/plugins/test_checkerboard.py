"""The checkerboard: squares of side s in the plane's object space; the square containing
object-space (x, z) has the base color C when floor(x/s) + floor(z/s) is even and is black
when it is odd. Only planes declared after ``checkerboard s`` (s > 0) are checkered."""

import numpy as np
import pytest

from support import camera_rays, normalize, render_ray, rotation, scaling, stack, translation

EYE, LOOKAT = (0.0, 2.0, 5.0), (0.0, -1.0, 0.0)


def _floor_hits(width, height, to_world):
    """Object-space (x, z) of the pixel rays' hits on the plane (nan where they miss) and
    the distance of each hit from the camera."""
    o, d = camera_rays(width, height, eye=EYE, lookat=LOOKAT)
    inv = np.linalg.inv(to_world)
    o_obj = inv[:3, :3] @ np.asarray(o) + inv[:3, 3]
    d_obj = d @ inv[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -o_obj[1] / d_obj[..., 1]
    t = np.where(t > 0, t, np.nan)
    p = o_obj + t[..., None] * d_obj
    return p[..., 0], p[..., 2], t * np.linalg.norm(d_obj, axis=-1)


def _parity_image(x, z, size, color, background):
    even = (np.floor(x / size) + np.floor(z / size)) % 2 == 0
    return np.where(np.isnan(x)[..., None], background,
                    np.where(even[..., None], color, 0.0))


def _off_edges(x, z, size, distance):
    """Hits clearly inside a square: farther than 1e-4 (x (1 + distance)) from its edges,
    float32's resolution of the hit point with margin; and not near the horizon, where a
    pixel covers many squares."""
    def clear(u):
        return np.abs(u / size - np.round(u / size)) * size > 1e-4 * (1 + distance)
    return np.isnan(x) | (clear(x) & clear(z) & (distance < 50))


@pytest.mark.parametrize("size", [0.5, 1.3])
def test_checker_parity_on_a_translated_floor(size):
    # Ambient light only: each pixel is exactly C or black (or the background above the
    # horizon). The plane is moved by (0.3, -1, 0.2): squares follow its object space.
    width = height = 32
    color = np.array([0.9, 0.7, 0.2])
    image = render_ray(f"eye {EYE[0]} {EYE[1]} {EYE[2]}\nlookat 0 -1 0\n"
                       "background 0.1 0.2 0.3\nlight 1 1 1 ambient\n"
                       "material 0.9 0.7 0.2  1 0 0 1  0 0 1\n"
                       f"checkerboard {size}\ntranslate 0.3 -1 0.2\nplane\n", width, height)
    x, z, distance = _floor_hits(width, height, translation(0.3, -1, 0.2))
    want = _parity_image(x, z, size, color, [0.1, 0.2, 0.3])
    ok = _off_edges(x, z, size, distance)
    assert ok.mean() > 0.8
    both = (want[ok] == color).all(-1).sum(), (want[ok] == 0).all(-1).sum()
    assert min(both) > 50  # plenty of both kinds of square
    assert np.any(np.isfinite(x) & (x < 0)) and np.any(np.isfinite(z) & (z < 0))  # floor() < 0
    np.testing.assert_allclose(image[ok], want[ok], rtol=0, atol=1e-7)


def test_checker_lives_in_the_planes_object_space():
    # scale 2 1 1, rotateY 30, translate 0 -1 0: the squares are 2s x s in the world,
    # turned by 30 degrees.
    width = height = 32
    to_world = stack(scaling(2, 1, 1), rotation("y", 30), translation(0, -1, 0))
    image = render_ray(f"eye {EYE[0]} {EYE[1]} {EYE[2]}\nlookat 0 -1 0\n"
                       "light 1 1 1 ambient\nmaterial 1 1 1  1 0 0 1  0 0 1\n"
                       "checkerboard 0.5\nscale 2 1 1\nrotateY 30\ntranslate 0 -1 0\nplane\n",
                       width, height)
    x, z, distance = _floor_hits(width, height, to_world)
    want = _parity_image(x, z, 0.5, np.ones(3), 0.0)
    ok = _off_edges(x, z, 0.5, distance)
    assert ok.mean() > 0.75
    np.testing.assert_allclose(image[ok], want[ok], rtol=0, atol=1e-7)


def test_black_squares_keep_the_untinted_highlight():
    # The checker multiplies C only: a black square still gets ks (R.V)^n I (the highlight is
    # not tinted), and a colored square gets kd C N.L on top.
    width = height = 32
    light = np.array([0.0, 2.0, 0.0])
    image = render_ray(f"eye {EYE[0]} {EYE[1]} {EYE[2]}\nlookat 0 -1 0\n"
                       "light 1 1 1 point 0 2 0\nmaterial 1 0.5 0  0 0.5 0.5 3  0 0 1\n"
                       "checkerboard 0.5\ntranslate 0 -1 0\nplane\n", width, height)
    x, z, distance = _floor_hits(width, height, translation(0, -1, 0))
    p = np.stack([x, np.full_like(x, -1.0), z], -1)
    l = normalize(light - p)
    v = normalize(np.asarray(EYE) - p)
    n_dot_l = l[..., 1]
    r = 2 * n_dot_l[..., None] * np.array([0.0, 1.0, 0.0]) - l
    spec = np.maximum(np.sum(r * v, -1), 0.0) ** 3
    even = (np.floor(x / 0.5) + np.floor(z / 0.5)) % 2 == 0
    want = 0.5 * spec[..., None] + np.where(even[..., None], 0.5 * np.array([1, 0.5, 0]) *
                                            n_dot_l[..., None], 0.0)
    want = np.where(np.isnan(x)[..., None], 0.0, want)
    ok = _off_edges(x, z, 0.5, distance)
    odd_lit = ok & ~even & np.isfinite(x) & (spec > 0.05)
    assert odd_lit.sum() > 10  # highlights on black squares are in the image
    # float32 shading of values <= 1: 1e-5 (see test_phong.py)
    np.testing.assert_allclose(image[ok], want[ok], rtol=0, atol=1e-5)


def test_checkerboard_applies_to_planes_only_and_can_be_turned_off():
    # checkerboard on, then a sphere (not checkered), then `checkerboard -1` and a plane
    # (not checkered), then `checkerboard 0` (also off) and another plane.
    width = height = 24
    image = render_ray("light 1 1 1 ambient\nmaterial 1 1 1  1 0 0 1  0 0 1\n"
                       "checkerboard 0.1\nscale 0.5 0.5 0.5\ntranslate 0 0.5 0\nsphere\nreset\n"
                       "checkerboard -1\ntranslate 0 -1 0\nplane\nreset\n"
                       "checkerboard 0\nrotateX 90\ntranslate 0 0 -5\nplane\n", width, height)
    np.testing.assert_array_equal(image, np.ones(image.shape, np.float32))


@pytest.mark.parametrize("size", [0.5, 2.0])
def test_checker_texture_plugin(mitsuba, size):
    mi = mitsuba
    checker = mi.load_dict({"type": "raychecker", "size": size})
    uv = np.array([[0.1, 0.1], [0.6, 0.1], [-0.1, 0.1], [-0.1, -0.1], [0.99, 0.49],
                   [1.0, 0.0], [0.5, 0.5], [-1.2, 3.7], [100.3, -7.9]]) * size / 0.5
    si = mi.SurfaceInteraction3f()
    si.uv = mi.Point2f(np.ascontiguousarray(uv[:, 0], np.float32),
                       np.ascontiguousarray(uv[:, 1], np.float32))
    got = np.array(checker.eval(si)).T
    cells = np.floor(uv[:, 0] / size) + np.floor(uv[:, 1] / size)
    want = np.where(cells % 2 == 0, 1.0, 0.0)
    np.testing.assert_array_equal(got, np.repeat(want[:, None], 3, axis=1))
    assert want.tolist() == [1, 0, 0, 1, 0, 1, 1, 1, 1]  # (worked out by hand)


# -- the checkerboard averaged over a sample's footprint (anti-aliasing) -------------------------
def _dense_average(uv, a, b, size, n=300):
    """The point checkerboard averaged over the parallelogram uv + s a + t b, s, t in
    [-1/2, 1/2], by an n x n grid of points (an independent computation; its own error on
    an edge is about 1/n)."""
    g = (np.arange(n) + 0.5) / n - 0.5
    s, t = np.meshgrid(g, g)
    u, v = uv[0] + s * a[0] + t * b[0], uv[1] + s * a[1] + t * b[1]
    return (1.0 - (np.floor(u / size) + np.floor(v / size)) % 2).mean()


def _filtered(mi, uv, a, b, size):
    from raymitsuba.plugins.checkerboard import checker_filtered

    return checker_filtered(mi.Point2f(uv[:, 0], uv[:, 1]), size, mi.Vector2f(a[:, 0], a[:, 1]),
                            mi.Vector2f(b[:, 0], b[:, 1])).numpy()


def test_the_filtered_board_is_the_exact_average_over_an_axis_aligned_box(mitsuba):
    rng = np.random.default_rng(4)
    count, size = 100, 0.7
    uv = rng.uniform(-5, 5, (count, 2))
    widths = 10 ** rng.uniform(-2, 0.5, (count, 2))
    a, b = np.c_[widths[:, 0], np.zeros(count)], np.c_[np.zeros(count), widths[:, 1]]
    want = [_dense_average(uv[i], a[i], b[i], size) for i in range(count)]
    # exact in closed form: only the dense grid's own error remains (up to 1/300 for each
    # axis whose box an edge of the squares crosses)
    np.testing.assert_allclose(_filtered(mitsuba, uv, a, b, size), want, atol=2 / 300)


def test_the_filtered_board_of_a_zero_footprint_is_the_board(mitsuba):
    from raymitsuba.plugins.checkerboard import checker

    rng = np.random.default_rng(5)
    uv = rng.uniform(-5, 5, (1000, 2))
    zero = np.zeros((1000, 2))
    assert np.array_equal(_filtered(mitsuba, uv, zero, zero, 0.3),
                          checker(mitsuba.Point2f(uv[:, 0], uv[:, 1]), 0.3).numpy())


def test_the_filtered_board_approximates_slanted_footprints(mitsuba):
    """Parallelograms of any shape and size (0.01 to 3 squares a side): the pieces' boxes
    of equal variance are an approximation (plugins/checkerboard.py); measured mean error
    0.010 of the contrast, where a point sample is off by 0.3 on average."""
    rng = np.random.default_rng(0)
    count, size = 300, 0.7
    uv = rng.uniform(-5, 5, (count, 2))
    a = rng.normal(size=(count, 2)) * 10 ** rng.uniform(-2, 0.5, (count, 1))
    b = rng.normal(size=(count, 2)) * 10 ** rng.uniform(-2, 0.5, (count, 1))
    want = np.array([_dense_average(uv[i], a[i], b[i], size) for i in range(count)])
    error = np.abs(_filtered(mitsuba, uv, a, b, size) - want)
    assert error.mean() < 0.015 and np.median(error) < 0.005


def _dense_projective(uv, a, b, k, size, n=400):
    """The point checkerboard averaged over the sample's square (s, t) in [-1/2, 1/2]^2 mapped
    to uv + (s a + t b) / (1 + s kx + t ky), uniformly in (s, t): an n x n grid of points."""
    g = (np.arange(n) + 0.5) / n - 0.5
    s, t = np.meshgrid(g, g)
    den = 1.0 + s * k[0] + t * k[1]
    u, v = uv[0] + (s * a[0] + t * b[0]) / den, uv[1] + (s * a[1] + t * b[1]) / den
    return (1.0 - (np.floor(u / size) + np.floor(v / size)) % 2).mean()


def _random_footprints(seed, count, largest_distortion):
    rng = np.random.default_rng(seed)
    uv = rng.uniform(-5, 5, (count, 2))
    a = rng.normal(size=(count, 2)) * 10 ** rng.uniform(-1.5, 0.5, (count, 1))
    b = rng.normal(size=(count, 2)) * 10 ** rng.uniform(-1.5, 0.5, (count, 1))
    k = rng.uniform(-largest_distortion, largest_distortion, (count, 2))
    return uv, a, b, k


def test_the_filtered_board_follows_a_footprint_seen_in_perspective(mitsuba):
    """Footprints distorted by perspective (the far side longer: kx, ky up to 0.3) are
    averaged with the distortion: measured mean error 0.013 of the contrast (median 0.003),
    where taking them as parallelograms gives 0.020 (median 0.010)."""
    from raymitsuba.plugins.checkerboard import checker_filtered

    uv, a, b, k = _random_footprints(1, 300, 0.3)
    size = 0.7
    want = np.array([_dense_projective(uv[i], a[i], b[i], k[i], size) for i in range(len(uv))])

    def filtered(distortion):
        return checker_filtered(mitsuba.Point2f(uv[:, 0], uv[:, 1]), size,
                                mitsuba.Vector2f(a[:, 0], a[:, 1]),
                                mitsuba.Vector2f(b[:, 0], b[:, 1]), distortion).numpy()

    error = np.abs(filtered((mitsuba.Float(k[:, 0]), mitsuba.Float(k[:, 1]))) - want)
    flat = np.abs(filtered(None) - want)
    assert error.mean() < 0.016 and np.median(error) < 0.005
    assert np.median(error) < 0.5 * np.median(flat)


def test_a_perspective_edge_is_averaged_exactly(mitsuba):
    """One edge of the board across a footprint seen in perspective, the footprint's other
    axis along the edge (the rows of a receding floor): the pieces' product of averages is
    then exact along the edge, and the distortion's pieces leave an error of a few 1e-4
    (the dense grid's own is 1/400)."""
    from raymitsuba.plugins.checkerboard import checker_filtered

    rng = np.random.default_rng(2)
    count, size = 200, 1.0
    v = rng.uniform(0.3, 0.7, count)  # one square high: the edges at v = 0 and 1 are away
    u = rng.uniform(-0.45, 0.45, count)  # the edge u = 0 within the footprint
    a = np.c_[rng.uniform(0.5, 1.0, count), np.zeros(count)]
    b = np.c_[np.zeros(count), rng.uniform(0.01, 0.1, count)]
    k = np.c_[rng.uniform(-0.3, 0.3, count), np.zeros(count)]
    uv = np.c_[u, v]
    want = np.array([_dense_projective(uv[i], a[i], b[i], k[i], size) for i in range(count)])
    got = checker_filtered(mitsuba.Point2f(uv[:, 0], uv[:, 1]), size,
                           mitsuba.Vector2f(a[:, 0], a[:, 1]), mitsuba.Vector2f(b[:, 0], b[:, 1]),
                           (mitsuba.Float(k[:, 0]), mitsuba.Float(k[:, 1]))).numpy()
    assert np.abs(got - want).max() < 2 / 400 + 1e-3


def test_the_trapezoid_average_is_the_average_over_two_uniform_offsets(mitsuba):
    from raymitsuba.plugins.checkerboard import square_wave, trapezoid_average

    rng = np.random.default_rng(3)
    x = rng.uniform(-4, 4, 200)
    w1, w2 = 10 ** rng.uniform(-2.5, 0.5, (2, 200))
    g = (np.arange(600) + 0.5) / 600 * 2 - 1  # [-1, 1], 600 points
    want = [np.mean(1 - 2 * (np.floor(xi + w1i * g[:, None] + w2i * g[None, :]) % 2))
            for xi, w1i, w2i in zip(x, w1, w2)]
    got = trapezoid_average(mitsuba.Float(x), mitsuba.Float(w1), mitsuba.Float(w2)).numpy()
    # the dense grid's own error: 2/600 per crossing of an edge (an offset narrower than
    # TRAPEZOID_MIN is taken as the box of the same variance: its error there is smaller)
    np.testing.assert_allclose(got, want, atol=8 / 600)
    assert np.array_equal(trapezoid_average(mitsuba.Float(x), mitsuba.Float(0.0),
                                            mitsuba.Float(0.0)).numpy(),
                          square_wave(mitsuba.Float(x)).numpy())


def test_a_footprint_past_the_horizon_is_the_boards_mean_and_not_resolved(mitsuba):
    from raymitsuba.plugins.checkerboard import (MAX_DISTORTION, checker_filtered,
                                                 footprint_resolved)

    uv, a = mitsuba.Point2f([0.3, 0.3, 0.3], [0.2, 0.2, 0.2]), mitsuba.Vector2f([0.1, 1, 0], 0)
    b = mitsuba.Vector2f(0, [0.1, 1, 0])
    # a finite footprint, one whose offset ray met the plane behind it (k infinite), a point
    k = mitsuba.Float([0.1, float("inf"), 0.0])
    value = checker_filtered(uv, 1.0, a, b, (k, mitsuba.Float(0.0))).numpy()
    assert 0 < value[0] < 1 and value[1] == 0.5 and value[2] == 1.0
    assert footprint_resolved(a, b, (k, mitsuba.Float(0.0))).numpy().tolist() == \
        [True, False, False]
    too_far = mitsuba.Float(2 * MAX_DISTORTION + 0.01)
    assert not footprint_resolved(a, b, (too_far, mitsuba.Float(0.0))).numpy()[0]
