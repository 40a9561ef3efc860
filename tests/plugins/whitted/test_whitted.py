"""The ``raywhitted`` integrator: the contract's ray tree, number for number.

Every expectation is computed independently in float64 numpy (support.py's camera and
intersection helpers, reference_tracer.py), never read back from the renderer.
"""

import math
import os

import numpy as np
import pytest

import reference_tracer as rt
from support import (camera_ray, camera_rays, intersect_plane, intersect_sphere, intersect_triangle,
                      load_ray, normalize, render_ray)

# The renderer computes in float32: a shading value of order 1 built from a few products
# and a dot product of float32 unit vectors is within a few ulps (~1e-7 relative) of the
# float64 value, and an analytic sphere hit point is accurate to ~1e-6 relative. 1e-5
# leaves a 10x margin and is still far below any semantic error (which changes a value
# by a whole term, typically > 1e-2).
EXACT = 1e-5


def grazing(o, d, center, radius, margin=1e-4):
    """Rays that pass within ``margin`` (relative) of a sphere's silhouette: the float32
    renderer may decide those either way; tests skip them."""
    oc = np.asarray(o, float) - center
    b = np.sum(oc * d, axis=-1)
    closest = np.sqrt(np.maximum(np.sum(oc * oc, axis=-1) - b * b, 0.0))
    return np.abs(closest - radius) < margin * radius


# -- local shading through the integrator --------------------------------------------------------
def test_directional_light_at_the_sphere_centre_pixel():
    # 33 x 33: the centre pixel's ray is exactly the view axis, so it meets the unit sphere
    # at (0, 0, 1) with N = (0, 0, 1); the light travels along (-1, -1, -2), so
    # L = (1, 1, 2) / sqrt(6) and N.L = 2 / sqrt(6).
    image = render_ray("eye 0 0 5\n"
                       "light 0.9 0.6 0.3 directional -1 -1 -2\n"
                       "material 0.5 0.8 1  0 0.7 0 1  0 0 1\n"
                       "sphere\n", 33, 33)
    expected = 0.7 * np.array([0.5, 0.8, 1.0]) * np.array([0.9, 0.6, 0.3]) * 2 / math.sqrt(6)
    np.testing.assert_allclose(image[16, 16], expected, rtol=0, atol=EXACT)

    # ... and kd C I max(N.L, 0) at every pixel of the sphere, with the exact normal.
    o, d = camera_rays(33, 33)
    t = intersect_sphere(o, d)
    n = o + t[..., None] * d
    l = normalize([1.0, 1.0, 2.0])
    want = 0.7 * np.array([0.5, 0.8, 1.0]) * np.array([0.9, 0.6, 0.3]) \
        * np.maximum(n @ l, 0.0)[..., None]
    want = np.where(np.isnan(t)[..., None], 0.0, want)
    ok = ~grazing(o, d, 0.0, 1.0)
    assert np.isfinite(t).sum() > 200
    np.testing.assert_allclose(image[ok], want[ok], rtol=0, atol=EXACT)


def test_ambient_only_is_ka_times_sum_of_ambient_lights_times_color():
    # Two ambient lights add up; no other light: sphere pixels are ka * (A1 + A2) * C,
    # all others the background. Sums and products of a few floats: float32 rounding only.
    image = render_ray("background 0.05 0.06 0.07\n"
                       "light 0.2 0.3 0.4 ambient\n"
                       "light 0.1 0.1 0.2 ambient\n"
                       "material 1 0.5 0.25  0.5 1 1 10  0 0 1\n"
                       "sphere\n", 24, 24)
    o, d = camera_rays(24, 24)
    hit = np.isfinite(intersect_sphere(o, d))
    ok = ~grazing(o, d, 0.0, 1.0)
    want = np.where(hit[..., None], 0.5 * np.array([0.3, 0.4, 0.6]) * [1, 0.5, 0.25],
                    [0.05, 0.06, 0.07])
    np.testing.assert_allclose(image[ok], want[ok], rtol=0, atol=1e-7)


# -- shadows -------------------------------------------------------------------------------------
def _shadow_triangle():
    # A triangle around (-2, -1.2, 2), perpendicular to the light's travel (1, 0, -1),
    # circumscribing a disk of radius 0.4. Out of the camera's view, like the spheres.
    c = np.array([-2.0, -1.2, 2.0])
    e1, e2 = np.array([0.0, 1.0, 0.0]), normalize([1.0, 0.0, 1.0])
    return [c + 0.8 * (math.cos(a) * e1 + math.sin(a) * e2) for a in np.radians([90, 210, 330])]


def test_shadows_opaque_glass_triangle_and_glass_sphere():
    """A plane facing the camera under a directional light travelling (1, 0, -1); three
    blockers out of view cast shadows on it: an opaque sphere (blocks: ambient only), a
    glass triangle kt = 0.5 (one crossing: kt) and a glass sphere kt = 0.5 (two crossings:
    kt^2). Every pixel is checked against the analytic transmittance."""
    tri = _shadow_triangle()
    corners = " ".join(f"{x:.17g}" for p in tri for x in p)
    text = ("eye 0 0 5\n"
            "light 0.5 0.5 0.5 ambient\n"
            "light 1 1 1 directional 1 0 -1\n"
            "material 0.8 0.6 0.4  0.2 1 0 1  0 0 1\n"
            "rotateX 90\nplane\nreset\n"                 # the plane z = 0, normal +z
            "material 1 1 1  0 0 0 1  0 0 1\n"           # opaque
            "scale 0.4 0.4 0.4\ntranslate -2 1.2 2\nsphere\nreset\n"
            "material 1 1 1  0 0 0 1  0 0.5 1.5\n"       # glass, kt = 0.5
            "scale 0.4 0.4 0.4\ntranslate -2 0 2\nsphere\nreset\n"
            f"triangle {corners}\n")
    width = height = 33
    image = render_ray(text, width, height)

    o, d = camera_rays(width, height)
    t = intersect_plane(o, d, (0, 0, 0), (0, 0, 1))
    p = o + t[..., None] * d
    wi = normalize([-1.0, 0.0, 1.0])
    trans = np.ones(t.shape)
    fragile = np.zeros(t.shape, bool)
    for center, kt in (((-2, 1.2, 2), 0.0), ((-2, 0, 2), 0.5)):
        crossed = np.isfinite(intersect_sphere(p, wi, center, 0.4))
        trans = np.where(crossed, trans * kt * kt, trans)
        fragile |= grazing(p, wi, np.array(center, float), 0.4, 1e-3)
    t_tri, u, v = intersect_triangle(p, np.broadcast_to(wi, p.shape), *tri)
    trans = np.where(np.isfinite(t_tri), trans * 0.5, trans)
    fragile |= np.minimum(np.minimum(np.abs(u), np.abs(v)), np.abs(1 - u - v)) < 1e-3
    color = np.array([0.8, 0.6, 0.4])
    want = 0.5 * 0.2 * color + trans[..., None] * color * wi[2]  # N.L = wi . (0, 0, 1)
    for value in (0.0, 0.25, 0.5, 1.0):  # each case is really in the image
        assert (np.isclose(trans, value) & ~fragile).sum() >= 3, value
    np.testing.assert_allclose(image[~fragile], want[~fragile], rtol=0, atol=EXACT)


def test_the_shaded_surface_does_not_count_as_a_crossing():
    # A transparent plane (kt = 0.5, eta = 1) facing the camera and the light: its own
    # surface does not attenuate its diffuse term; its refracted ray sees the black
    # background. So every pixel is exactly kd C N.L.
    image = render_ray("light 1 1 1 directional 0 -1 -1\n"
                       "material 0.8 0.6 0.4  0 1 0 1  0 0.5 1\n"
                       "rotateX 90\nplane\n", 16, 16)
    np.testing.assert_allclose(image, np.broadcast_to([0.8, 0.6, 0.4], image.shape)
                               * math.sqrt(0.5), rtol=0, atol=EXACT)


# -- reflection and refraction -------------------------------------------------------------------
def test_background_seen_in_a_mirror_is_kr_times_background():
    # A perfect mirror sphere (ka = kd = ks = 0, kr = 0.75): every reflected ray leaves the
    # convex sphere and hits nothing, so its pixels are exactly kr * background.
    image = render_ray("background 0.2 0.4 0.8\n"
                       "light 1 1 1 directional 0 0 -1\n"
                       "material 1 1 1  0 0 0 1  0.75 0 1\n"
                       "sphere\n", 24, 24)
    o, d = camera_rays(24, 24)
    hit = np.isfinite(intersect_sphere(o, d))
    ok = ~grazing(o, d, 0.0, 1.0)
    want = np.where(hit[..., None], 0.75 * np.array([0.2, 0.4, 0.8]), [0.2, 0.4, 0.8])
    assert hit.sum() > 50
    np.testing.assert_allclose(image[ok], want[ok], rtol=0, atol=1e-7)


def _box_triangles(linear, half):
    """The 12 triangles of the box [-h, h]^3 (h per axis) mapped by ``linear``, outward."""
    tris = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = (axis + 1) % 3, (axis + 2) % 3
            quad = []
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                q = np.zeros(3)
                q[axis], q[u], q[v] = sign * half[axis], a * half[u], b * half[v]
                quad.append(linear @ q)
            if sign < 0:
                quad = quad[::-1]  # e_u x e_v = e_axis: counter-clockwise seen from outside
            tris += [(quad[0], quad[1], quad[2]), (quad[0], quad[2], quad[3])]
    return tris


def _refract(d, n, ratio):
    """Snell refraction of unit direction d at unit normal n facing against d."""
    cos_i = -np.sum(d * n, axis=-1, keepdims=True)
    cos_t = np.sqrt(1.0 - ratio ** 2 * (1.0 - cos_i ** 2))
    return ratio * d + (ratio * cos_i - cos_t) * n


def test_glass_slab_offsets_rays_laterally():
    """A glass slab (eta 1.5, thickness 2, a closed box of 12 triangles) turned 30 degrees
    about y, in front of a white wall whose right edge is x = 0. A ray at incidence a leaves
    the slab parallel to itself, shifted by t sin(a - b) / cos(b), sin b = sin a / eta, so
    the wall's edge seen through the slab moves by several pixels; the rendered edge must
    be where the exactly traced rays put it, in every row."""
    angle = math.radians(30.0)
    rot = np.array([[math.cos(angle), 0, math.sin(angle)], [0, 1, 0],
                    [-math.sin(angle), 0, math.cos(angle)]])
    slab = _box_triangles(rot, (3.0, 3.0, 1.0))
    width, height = 40, 10
    # The view spans x in [-1.5, 1.5] at the wall (11 units away), well inside the slab's
    # faces: every camera ray crosses the front and the back face.
    fov = math.degrees(2 * math.atan(1.5 / 11 * height / width))
    lines = ["eye 0 0 8", f"fov {fov:.17g}", "light 1 1 1 ambient",
             "material 1 1 1  1 0 0 1  0 0 1",  # the wall: ambient white
             "triangle -10 -10 -3  0 -10 -3  0 10 -3",
             "triangle -10 -10 -3  0 10 -3  -10 10 -3",
             "material 1 1 1  0 0 0 1  0 1 1.5"]  # the slab: clear glass, kt = 1
    lines += ["triangle " + " ".join(f"{x:.17g}" for p in tri for x in p) for tri in slab]
    image = render_ray("\n".join(lines) + "\n", width, height)

    n = rot @ np.array([0.0, 0.0, 1.0])  # the front face: n.x = 1; the back face: n.x = -1

    def trace(o, d):
        """Exit point and direction of the rays through the slab, and x where they meet the wall."""
        p1 = o + ((1.0 - o @ n) / (d @ n))[..., None] * d
        d1 = _refract(d, n, 1 / 1.5)
        p2 = p1 + ((-1.0 - np.sum(p1 * n, axis=-1)) / (d1 @ n))[..., None] * d1
        d2 = _refract(d1, n, 1.5)
        return p2, d2, p2[..., 0] + (-3.0 - p2[..., 2]) / d2[..., 2] * d2[..., 0]

    # The view axis meets the slab at incidence a = 30 degrees: it leaves parallel to
    # itself, displaced by the formula's offset (this checks the exact trace below).
    eye, axis = np.array([0.0, 0.0, 8.0]), np.array([0.0, 0.0, -1.0])
    p2, d2, _ = trace(eye, axis)
    b = math.asin(math.sin(angle) / 1.5)
    offset = 2.0 * math.sin(angle - b) / math.cos(b)
    np.testing.assert_allclose(d2, axis, atol=1e-12)
    assert np.linalg.norm(np.cross(p2 - eye, axis)) == pytest.approx(offset, rel=1e-12)

    o, d = camera_rays(width, height, eye=(0, 0, 8), fov=fov)
    _, _, x_wall = trace(o, d)
    x_straight = o[0] + (-3.0 - o[2]) / d[..., 2] * d[..., 0]  # without the slab
    pixel = 3.0 / width  # pixel size on the wall
    white = image[..., 0] > 0.5
    # Every pixel is on the side of the edge the exact trace says (no pixel centre comes
    # within 1e-3 px of the edge, so no float32 tie-break is involved) ...
    assert np.min(np.abs(x_wall)) / pixel > 1e-3
    np.testing.assert_array_equal(white, x_wall < 0.0)
    np.testing.assert_allclose(image[white], 1.0, atol=1e-6)  # kt = 1: all of the wall's white
    np.testing.assert_allclose(image[~white], 0.0, atol=1e-6)
    # ... and that is several pixels away from where the edge is without the slab
    # (offset / cos a on the wall: 0.45 units, 6 pixels).
    for row in range(height):
        moved = np.flatnonzero(white[row])[-1] - np.flatnonzero(x_straight[row] < 0)[-1]
        assert abs(moved) >= 5, (row, moved)


def test_depth_limit_two_facing_mirrors():
    """The camera between two parallel mirrors, A (red, z = 0) and B (green, z = 10), each
    kr = 1/2 and locally ka C under an ambient white. A camera ray alternates A, B, A...:
    color = sum over bounces k <= max_depth of (1/2)^k C_k, so red collects the even k and
    green the odd k -- exactly the terms of the series up to max_depth, no more, no less."""
    text = ("light 1 1 1 ambient\n"
            "material 1 0 0  1 0 0 1  0.5 0 1\n"
            "rotateX 90\nplane\nreset\n"                        # A: z = 0, facing +z
            "material 0 1 0  1 0 0 1  0.5 0 1\n"
            "rotateX -90\ntranslate 0 0 10\nplane\n")           # B: z = 10, facing -z
    for depth in range(5):
        image = render_ray(text, 8, 8, max_depth=depth)
        red = sum(0.5 ** k for k in range(0, depth + 1, 2))
        green = sum(0.5 ** k for k in range(1, depth + 1, 2))
        # Sums of powers of two: exact in float32.
        np.testing.assert_array_equal(image, np.broadcast_to([red, green, 0.0], image.shape),
                                      err_msg=f"max_depth={depth}")


# -- sampling and reproducibility ----------------------------------------------------------------
def test_spp4_averages_samples_of_a_sharp_edge():
    """A triangle (color T) whose slanted edge crosses the image over a background B: with
    spp = 4 (one sample per quadrant of the pixel, box filter) every pixel is f T + (1 - f) B
    with f in {0, 1/4, 1/2, 3/4, 1}; f is 0 or 1 wherever the pixel lies on one side of the
    edge, and strictly between somewhere along it."""
    # The edge runs through (-2, -1.3, 0) and (2, 1.5, 0) (35 degrees, so that pixels see
    # it cut off one or three of their quadrants); the triangle is above it.
    text = ("background 0 0.25 1\n"
            "light 1 1 1 ambient\n"
            "material 1 0.5 0.25  1 0 0 1  0 0 1\n"
            "triangle -14 -9.7 0  14 9.9 0  -20 20 0\n")
    width = height = 16
    image = render_ray(text, width, height, spp=4)
    f = image[..., 0]  # red: T = 1, B = 0
    np.testing.assert_allclose(image[..., 1], 0.5 * f + 0.25 * (1 - f), atol=1e-6)
    np.testing.assert_allclose(image[..., 2], 0.25 * f + (1 - f), atol=1e-6)
    quarters = np.round(f * 4)
    np.testing.assert_allclose(f, quarters / 4, atol=1e-6)  # a multiple of 1/4, exactly
    assert set(np.unique(quarters)) <= {0, 1, 2, 3, 4}

    # Which side of the edge each pixel's corners are on (above the edge: inside).
    def inside(x, y):
        o, d = camera_ray(x, y, width, height)
        p = o + (-o[2] / d[..., 2])[..., None] * d  # on the plane z = 0
        return 4.0 * (p[..., 1] + 1.3) - 2.8 * (p[..., 0] + 2.0) > 0  # (Q - P) x (p - P) > 0

    cols, rows = np.meshgrid(np.arange(width), np.arange(height))
    corners = [inside(cols + dx, rows + dy) for dx in (0, 1) for dy in (0, 1)]
    all_in = np.logical_and.reduce(corners)
    all_out = ~np.logical_or.reduce(corners)
    assert np.all(quarters[all_in] == 4) and np.all(quarters[all_out] == 0)
    straddling = ~all_in & ~all_out
    assert straddling.sum() >= height  # the edge crosses every row
    assert np.any((quarters[straddling] > 0) & (quarters[straddling] < 4))
    assert np.any(np.isin(quarters[straddling], (1, 3)))  # a quarter, not only halves


def test_render_is_deterministic():
    import raymitsuba

    text = REFERENCE_TEXT
    loaded = load_ray(text, 24, 24, spp=2)
    first = np.array(raymitsuba.render(loaded))
    again = np.array(raymitsuba.render(loaded))
    reloaded = np.array(raymitsuba.render(load_ray(text, 24, 24, spp=2)))
    assert first.tobytes() == again.tobytes()
    assert first.tobytes() == reloaded.tobytes()


# -- an independent tracer for a whole image -----------------------------------------------------
MIRROR = rt.Material((0.9, 0.9, 0.9), 0.1, 0.2, 0.5, 30, 0.7, 0.0, 1.0)
GLASS = rt.Material((0.8, 1.0, 0.9), 0.05, 0.1, 0.6, 40, 0.1, 0.8, 1.5)
FLOOR = rt.Material((1.0, 0.8, 0.5), 0.3, 0.8, 0.0, 1, 0.0, 0.0, 1.0)
REFERENCE_SCENE = rt.Scene(
    eye=(0, 1.6, 6), lookat=(0, 0.2, 0), fov=45, background=(0.2, 0.3, 0.5),
    objects=[rt.Sphere((-1.1, 0.5, -0.3), 1.0, MIRROR), rt.Sphere((1.1, 0.3, 0.9), 0.8, GLASS),
             rt.Plane(-0.5, FLOOR, checker=0.7, offset=(0.3, 0.1))],
    lights=[rt.Light("ambient", (0.1, 0.1, 0.1)), rt.Light("point", (0.8, 0.8, 0.7), (3, 5, 4)),
            rt.Light("directional", (0.3, 0.3, 0.4), (-1, -2, -1))])
REFERENCE_TEXT = """\
eye 0 1.6 6
lookat 0 0.2 0
fov 45
background 0.2 0.3 0.5
light 0.1 0.1 0.1 ambient
light 0.8 0.8 0.7 point 3 5 4
light 0.3 0.3 0.4 directional -1 -2 -1
material 0.9 0.9 0.9  0.1 0.2 0.5 30  0.7 0 1
translate -1.1 0.5 -0.3
sphere
reset
material 0.8 1 0.9  0.05 0.1 0.6 40  0.1 0.8 1.5
scale 0.8 0.8 0.8
translate 1.1 0.3 0.9
sphere
reset
material 1 0.8 0.5  0.3 0.8 0 1  0 0 1
checkerboard 0.7
translate 0.3 -0.5 0.1
plane
"""


def test_whole_image_matches_an_independent_numpy_whitted_tracer():
    """A mirror sphere, a glass sphere (kr and kt), a checkered plane, an ambient, a point
    and a directional light, depth 3, 24 x 24: reference_tracer.py (float64) and the
    renderer (float32) must agree to 1e-4 at every pixel whose ray tree stays clear of
    discontinuities (observed: ~3e-6, float32 rounding along up to four bounces).

    The reference marks as fragile the pixels whose ray tree passes within 1e-3 (relative)
    of a silhouette, a checker edge, a shadow edge, the onset of total internal reflection
    or runs to the horizon: there a float32 renderer may legitimately choose the other side
    of the discontinuity. They may differ, but must stay a small fraction (< 10%) of the
    image; so must the pixels that differ at all."""
    width = height = 24
    want, fragile = rt.render(REFERENCE_SCENE, width, height, max_depth=3)
    image = render_ray(REFERENCE_TEXT, width, height, max_depth=3)
    error = np.abs(image - want).max(axis=-1)
    assert fragile.mean() < 0.10
    assert (error > 1e-4).mean() < 0.05
    worst = np.unravel_index(np.argmax(np.where(fragile, 0, error)), error.shape)
    assert error[~fragile].max() < 1e-4, (worst, image[worst], want[worst])
    # The scene really exercises every branch: reflections, refractions, checker, shadows.
    assert (want == REFERENCE_SCENE.background).all(axis=-1).sum() > 20
    assert np.ptp(want[..., 0]) > 0.5


def test_ray_offset_scale_moves_secondary_rays_off_the_surface_as_spawn_ray_does():
    """``ray_offset_scale`` (the option ``raymitsuba compare`` sets to 100 to find pixels that
    hang on the offset) replaces ``si.spawn_ray`` by the tracer's own spawn: at a scale a
    hair from 1 its image is Mitsuba's within float32 rounding (1e-6); at 100 it differs
    only where a ray passes near a discontinuity (reflections of edges through the glass
    sphere, shadow edges): a few percent of the pixels."""
    from raymitsuba import api

    def image(**options):
        loaded = api.load(REFERENCE_TEXT, width=24, height=24, max_depth=3, **options)
        return loaded.integrator.render_array(loaded.scene)

    default = image()
    assert np.abs(image(ray_offset_scale=1 + 1e-6) - default).max() < 1e-6
    moved = np.abs(image(ray_offset_scale=100) - default).max(axis=-1) > 2 / 255
    assert 0 < moved.mean() < 0.1


def test_a_shadow_ray_through_glass_stops_at_the_light():
    """The floor point (0, 0, 0) under a glass sphere (kt 0.5, crossed twice) lit from
    (0, 3, 0) straight above: T = 0.5^2, so L = kd C (N.L) T = 0.25 (ka = ks = 0). An opaque
    ceiling above the light must not count: the walk through the glass ends at the light.
    (It once did: ``mi.Ray3f(o, d, maxt)`` takes its third argument as the time, and the
    walk ran on with an infinite maxt into the ceiling: 0.)"""
    text = """eye 0 0.3 4
lookat 0 0 0
light 1 1 1 point 0 3 0
material 1 1 1 0 1 0 1 0 0 1
plane
material 0 0 0 0 0 0 1 0 0.5 1
scale 0.5 0.5 0.5
translate 0 1 0
sphere
reset
material 0 0 0 1 0 0 1 0 0 1
rotateX 180
translate 0 5 0
plane
"""
    image = render_ray(text, 9, 9)
    assert np.allclose(image[4, 4], 0.25, atol=1e-6)  # float32 rounding of the walk


def panes_over_the_floor(panes, kt=0.9):
    """.RAY text: the floor point (0, 0, 0) lit from (0, 3, 0) straight above through
    ``panes`` clear horizontal triangles (kt ``kt``, ior 1) between y = 0.5 and 2.5, out of
    the camera's sight of that point; ka = ks = 0."""
    lines = ["eye 0 0.3 4", "lookat 0 0 0", "light 1 1 1 point 0 3 0",
             "material 1 1 1 0 1 0 1 0 0 1", "plane",
             f"material 0 0 0 0 0 0 1 0 {kt} 1"]
    for i in range(panes):
        y = 0.5 + 2.0 * i / max(panes, 1)
        # (the vertical through the origin crosses each one inside, off its edges)
        lines.append(f"triangle -0.3 {y} -0.3  0.5 {y} -0.3  -0.3 {y} 0.5")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("panes", [15, 16, 17])
def test_a_shadow_ray_is_blocked_past_max_shadow_crossings(panes):
    """docs/format.md: a shadow ray that crosses more than 16 transparent surfaces (the
    default max_shadow_crossings) counts as blocked. The floor point under 15 and 16 clear
    panes (kt 0.9) is lit with T = 0.9^n, so L = kd C (N.L) T = 0.9^n; under 17 it is
    black. (Until 2026-12-07 the 16th crossing already blocked it.) A product of 16 float32
    factors is within a few ulps of the float64 value."""
    image = render_ray(panes_over_the_floor(panes), 9, 9)
    expected = 0.9 ** panes if panes <= 16 else 0.0
    assert image[4, 4] == pytest.approx(np.full(3, expected), rel=1e-5, abs=1e-7)


@pytest.mark.parametrize("aa", [None, 0.02], ids=["1 spp", "--aa"])
def test_a_scene_without_glass_renders_the_same_whether_or_not_refracted_rays_are_computed(aa):
    """Tracer.step computes no refracted ray where every kt is 0 and none carries a
    derivative (the refracted child's weight is kt = 0: no lane has one); with a kt's
    gradient enabled it computes them (each lane's refracted ray, and with --aa its
    footprint's offset rays), as it did for every scene until 2026-12-07. The reflective
    benchmark scene (mirrors, no glass) gives the same image both ways, bit for bit, and
    the derivative with respect to kt at 0 is 0: a child of weight 0 is not traced
    (docs/gradients.md, "What is not covered")."""
    import drjit as dr
    import raymitsuba

    scene = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "scenes",
                         "benchmark_reflective.ray")
    loaded = raymitsuba.load(scene, width=48, height=36, aa=aa)
    fast = np.array(raymitsuba.render(loaded))
    params = loaded.params
    dr.enable_grad(params["mat0.refractivity"])
    params.update()
    image = raymitsuba.render(loaded)
    assert np.array_equal(np.array(image), fast)
    dr.set_grad(params["mat0.refractivity"], 1.0)
    dr.forward_to(image)
    assert not np.any(dr.grad(image).numpy())
