"""Geometry of the shapes: silhouettes and normals of ellipsoids (scaled and sheared spheres),
cylinders, cones, planes and triangles against analytic float64 ray casts; the transform
stack's order; triangles' front side; texture coordinates of triangles."""

import numpy as np
import pytest

from support import (camera_rays, intersect_plane, intersect_sphere, intersect_triangle, lit_runs,
                      normalize,
                      normal_to_world, render_ray, rotation, scaling, stack, to_object,
                      translation)

# Silhouettes: the tessellated shapes are within 0.05 px of the true outline (translate.py
# picks the segment count for that). A pixel whose centre is farther than 0.1 px from the
# analytic outline must therefore be inside/outside exactly as the analytic cast says.
BAND = 0.1


# -- analytic ray casts in object space ----------------------------------------------------------
def _quadratic(a, b, c):
    disc = b * b - a * c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    with np.errstate(divide="ignore", invalid="ignore"):
        return (-b - root) / a, (-b + root) / a


def _nearest(candidates):
    """Per ray, the smallest positive t among (t, normal) candidates: (t, normal, index)."""
    ts = np.stack([np.where(t > 1e-9, t, np.inf) for t, _ in candidates])
    ts = np.where(np.isnan(ts), np.inf, ts)
    k = np.argmin(ts, axis=0)
    t = np.take_along_axis(ts, k[None], 0)[0]
    normals = np.stack([n for _, n in candidates])
    n = np.take_along_axis(normals, k[None, ..., None], 0)[0]
    return np.where(np.isinf(t), np.nan, t), n, np.where(np.isinf(t), -1, k)


def cast(kind, to_world, o, d):
    """(t, outward unit world normal, part) of rays with a unit primitive under ``to_world``.
    part: 0 the curved side (or the whole sphere), 1 the bottom cap, 2 the top cap; -1 miss."""
    oo, dd = to_object(to_world, o, d)
    ox, oy, oz = oo
    dx, dy, dz = dd[..., 0], dd[..., 1], dd[..., 2]
    cands = []
    if kind == "sphere":
        for t in _quadratic(np.sum(dd * dd, -1), np.sum(oo * dd, -1), oo @ oo - 1.0):
            p = oo + t[..., None] * dd
            cands.append((t, p))
    else:
        if kind == "cylinder":  # x^2 + z^2 = 1
            roots = _quadratic(dx * dx + dz * dz, ox * dx + oz * dz, ox * ox + oz * oz - 1.0)
        else:  # cone: x^2 + z^2 = (0.5 - y)^2, y <= 0.5
            ky, kdy = 0.5 - oy, -dy
            roots = _quadratic(dx * dx + dz * dz - kdy * kdy, ox * dx + oz * dz - ky * kdy,
                               ox * ox + oz * oz - ky * ky)
        for t in roots:
            p = oo + t[..., None] * dd
            on_side = np.abs(p[..., 1]) <= 0.5
            r = np.sqrt(p[..., 0] ** 2 + p[..., 2] ** 2)
            ny = np.zeros_like(r) if kind == "cylinder" else r
            n = np.stack([p[..., 0], ny, p[..., 2]], -1)
            cands.append((np.where(on_side, t, np.nan), n))
        caps = [(-0.5, -1.0)] + ([(0.5, 1.0)] if kind == "cylinder" else [])
        for y, ny in caps:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = (y - oy) / dy
            p = oo + t[..., None] * dd
            inside = p[..., 0] ** 2 + p[..., 2] ** 2 <= 1.0
            cands.append((np.where(inside, t, np.nan),
                          np.broadcast_to([0.0, ny, 0.0], p.shape)))
    t, n_obj, part = _nearest(cands)
    if kind == "sphere":
        part = np.where(part >= 0, 0, -1)
    elif kind == "cylinder" or kind == "cone":
        part = np.where(part >= 0, np.where(part < 2, 0, part - 1), -1)
    return t, normal_to_world(to_world, n_obj), part


def analytic_mask(kind, to_world, width, height, **camera):
    """(mask at pixel centres, ambiguous: the mask changes within BAND px of the centre)."""
    def mask(dx=0.0, dy=0.0):
        o, d = camera_rays(width, height, dx=dx, dy=dy, **camera)
        return np.isfinite(cast(kind, to_world, o, d)[0])

    centre = mask()
    ambiguous = np.zeros_like(centre)
    for dx, dy in ((BAND, 0), (-BAND, 0), (0, BAND), (0, -BAND)):
        ambiguous |= mask(dx, dy) != centre
    return centre, ambiguous


def _transform_text(steps):
    return "".join(f"{name} {' '.join(str(a) for a in args)}\n" for name, args in steps)


def _matrix(steps):
    make = {"translate": translation, "scale": scaling,
            "rotateX": lambda a: rotation("x", a), "rotateY": lambda a: rotation("y", a),
            "rotateZ": lambda a: rotation("z", a)}
    return stack(*[make[name](*args) for name, args in steps])


def _check_silhouette(image, kind, to_world, width, height, **camera):
    lit = image.max(axis=-1) > 0.25
    want, ambiguous = analytic_mask(kind, to_world, width, height, **camera)
    assert want.sum() > 100
    np.testing.assert_array_equal(lit[~ambiguous], want[~ambiguous])
    # Equivalently, along every row and column the first and last lit pixels are within a
    # pixel of the analytic outline's.
    for got_runs, want_runs in ((lit_runs(lit), lit_runs(want)), (lit_runs(lit.T), lit_runs(want.T))):
        for g, w in zip(got_runs, want_runs):
            if g is not None and w is not None:
                assert abs(g[0] - w[0]) <= 1 and abs(g[1] - w[1]) <= 1
            else:
                assert g is None or w is None


# -- spheres under affine transforms -------------------------------------------------------------
ELLIPSOIDS = {
    "non-uniform scale": [("scale", (1.6, 0.7, 1.0))],
    "sheared": [("scale", (1.5, 0.6, 1.0)), ("rotateZ", (35,)), ("scale", (1.0, 1.4, 0.8)),
                ("rotateX", (25,)), ("translate", (0.2, -0.1, 0.0))],
}


@pytest.mark.parametrize("name", list(ELLIPSOIDS))
def test_ellipsoid_silhouette_and_normals(name):
    """The image of a transformed sphere is the exact ellipse(oid) of the transform: its
    outline against the analytic projection, its shading against the analytic normal (the
    inverse transpose of the transform)."""
    steps = ELLIPSOIDS[name]
    width = height = 48
    text = ("eye 0 0 6\nlight 0.05 0.05 0.05 ambient\nlight 1 1 1 directional -1 -2 -3\n"
            "material 1 1 1  10 0.9 0 1  0 0 1\n" + _transform_text(steps) + "sphere\n")
    image = render_ray(text, width, height)
    m = _matrix(steps)
    # ambient 0.05 * ka 10 = 0.5: object pixels are >= 0.5, the background is 0
    _check_silhouette(image, "sphere", m, width, height, eye=(0, 0, 6))

    o, d = camera_rays(width, height, eye=(0, 0, 6))
    t, n, part = cast("sphere", m, o, d)
    _, ambiguous = analytic_mask("sphere", m, width, height, eye=(0, 0, 6))
    l = normalize([1.0, 2.0, 3.0])
    want = 0.5 + 0.9 * np.maximum(n @ l, 0.0)
    # The mesh interpolates exact vertex normals across facets spanning 2 pi / m radians
    # of the sphere (m >= 48); stretched by the transform, a facet spans up to (a / b) times
    # that in normal direction, and the facet hit point sits up to r (1 - cos(pi / m))
    # inside the true surface -- both grow where the view grazes the surface. Where
    # N.V > 0.5 the normal is within 1e-2 (observed: 5e-3); a wrong normal transform
    # (M instead of M^-T) is off by 0.4 here.
    facing = -np.sum(n * d, axis=-1) > 0.5
    check = (part == 0) & ~ambiguous & facing
    assert check.sum() > 200
    np.testing.assert_allclose(image[check][:, 0], want[check], rtol=0, atol=1e-2)


def test_transform_stack_order_translate_then_scale():
    # "translate 2 0 0, then scale 2 2 2, then sphere gives a sphere of radius 2 centred at
    # (4, 0, 0)" -- earlier stack statements are applied first.
    width = height = 40
    image = render_ray("eye 2 0 12\nlookat 2 0 0\nlight 1 1 1 ambient\n"
                       "translate 2 0 0\nscale 2 2 2\nsphere\n", width, height)
    o, d = camera_rays(width, height, eye=(2, 0, 12), lookat=(2, 0, 0))
    t = intersect_sphere(o, d, (4, 0, 0), 2.0)
    b = np.sum((o - [4, 0, 0]) * d, axis=-1)
    closest = np.sqrt(np.maximum(np.sum((o - [4, 0, 0]) ** 2) - b * b, 0))
    safe = np.abs(closest - 2.0) > 1e-4
    np.testing.assert_array_equal(image[..., 0][safe] > 0.5, np.isfinite(t)[safe])
    # The other order (scale, then translate) would give a radius-2 sphere at (2, 0, 0):
    # a very different set of pixels.
    other = np.isfinite(intersect_sphere(o, d, (2, 0, 0), 2.0))
    assert np.sum(other != np.isfinite(t)) > 100


# -- cylinders and cones -------------------------------------------------------------------------
CAMERAS = {"above": dict(eye=(0.0, 3.0, 4.0)), "below": dict(eye=(0.0, -3.0, 4.0))}


@pytest.mark.parametrize("kind", ["cylinder", "cone"])
@pytest.mark.parametrize("view", ["above", "below"])
def test_cylinder_and_cone_outline_caps_and_side_normals(kind, view):
    """A light travelling down (-y) lights the top cap with N.L = 1 (exactly kd C), and the
    cone's side with N.L = n_y of its normal; a light travelling up lights the bottom cap
    with N.L = 1. The side normals are checked with a second light along -x (green)."""
    steps = [("scale", (1.2, 1.5, 1.2)), ("rotateY", (20,))]
    m = _matrix(steps)
    camera = CAMERAS[view]
    width = height = 40
    down = "1 0 0 directional 0 -1 0" if view == "above" else "1 0 0 directional 0 1 0"
    text = (f"eye {' '.join(map(str, camera['eye']))}\n"
            "light 0 0 0.5 ambient\n"  # blue: marks every pixel of the object
            f"light {down}\nlight 0 1 0 directional -1 0 0\n"
            "material 1 1 1  1 0.8 0 1  0 0 1\n" + _transform_text(steps) + kind + "\n")
    image = render_ray(text, width, height)
    lit = image[..., 2] > 0.25
    want_mask, ambiguous = analytic_mask(kind, m, width, height, **camera)
    np.testing.assert_array_equal(lit[~ambiguous], want_mask[~ambiguous])

    o, d = camera_rays(width, height, **camera)
    t, n, part = cast(kind, m, o, d)
    # Only where all four neighbours are on the same part (away from the rims).
    same = np.zeros_like(part, dtype=bool)
    same[1:-1, 1:-1] = np.logical_and.reduce([part[1:-1, 1:-1] == p for p in (
        part[:-2, 1:-1], part[2:, 1:-1], part[1:-1, :-2], part[1:-1, 2:])])
    cap = 2 if view == "above" else 1
    on_cap = same & (part == cap) & ~ambiguous
    on_side = same & (part == 0) & ~ambiguous
    # (a cone seen from above shows no cap; from below, little of its side)
    assert on_cap.sum() > 20 or (kind, view) == ("cone", "above")
    assert on_side.sum() > 20 or (kind, view) == ("cone", "below")
    # The caps are flat with normal +-y exactly: N.L = 1, so red = kd C = 0.8 (float32 exact).
    np.testing.assert_allclose(image[on_cap][:, 0], 0.8, rtol=0, atol=1e-6)
    np.testing.assert_allclose(image[on_cap][:, 1], 0.8 * np.maximum(n[on_cap] @ [1, 0, 0], 0),
                               rtol=0, atol=1e-6)
    # The sides: smooth normals interpolated across facets of 2 pi / m (m >= 48): within
    # ~(pi / m)^2 of the analytic normal, plus the renormalisation of a cone's tilted
    # normals; 5e-3 in N.L bounds both (observed: ~1e-3). A cap-like or unscaled normal is
    # off by > 0.05 on this scaled shape.
    light_y = np.array([0.0, 1.0, 0.0]) if view == "above" else np.array([0.0, -1.0, 0.0])
    for channel, l in ((0, light_y), (1, np.array([1.0, 0.0, 0.0]))):
        np.testing.assert_allclose(image[on_side][:, channel],
                                   0.8 * np.maximum(n[on_side] @ l, 0), rtol=0, atol=5e-3)


# -- triangles -----------------------------------------------------------------------------------
def test_triangles_are_shaded_on_both_sides():
    # The same square, once wound toward the camera and once away from it: both sides are
    # shaded alike with the normal flipped toward the viewer -- lit by a light on the
    # camera's side, unlit (ambient only) by a light behind.
    front = "triangle -1 -1 0  1 -1 0  1 1 0\ntriangle -1 -1 0  1 1 0  -1 1 0\n"
    back = "triangle -1 -1 0  1 1 0  1 -1 0\ntriangle -1 -1 0  -1 1 0  1 1 0\n"
    for square in (front, back):
        image = render_ray("light 0.1 0.1 0.1 ambient\n"
                           "light 1 0 0 directional 0 -0.6 -0.8\n"   # from the camera's side
                           "light 0 1 0 directional 0 0.6 0.8\n"     # from behind
                           "material 1 1 1  1 0.5 0.5 4  0 0 1\n" + square, 16, 16)
        inner = image[5:11, 5:11].reshape(-1, 3)
        # red: ka A + kd N.L + ks (R.V)^4 > ka A; green: ambient only; blue: ambient only
        assert np.all(inner[:, 0] > 0.45)
        np.testing.assert_allclose(inner[:, 1:], 0.1, rtol=0, atol=1e-6)
        if square is front:
            first = image
        else:
            np.testing.assert_allclose(image, first, rtol=0, atol=1e-6)


def test_faces_closed_on_their_first_vertex_leave_no_hole():
    """A MIT 6.837 square written as two outlines closed on their first vertex (`f a b c a`,
    as cow.ray writes most faces) renders bit for bit as the same square written cleanly,
    and it covers its pixels: only the degenerate fan triangles (a c a) are skipped."""
    def square(*faces):
        return ("eye 0 0 10\nlight 1 1 1 ambient\nsurface 1 0 0  1 0 0 1  0 0 1\n"
                "triangles\nv -2 -2 0\nv 2 -2 0\nv 2 2 0\nv -2 2 0\n"
                + "".join(f + "\n" for f in faces) + "end\n")
    closed = render_ray(square("f 0 1 2 0", "f 0 2 3 0"), 16, 16, dialect="mit6837")
    clean = render_ray(square("f 0 1 2", "f 0 2 3"), 16, 16, dialect="mit6837")
    assert np.array_equal(closed, clean)
    # The square spans x, y in [-2, 2] at distance 10 with a horizontal fov of 30 degrees:
    # 4 / (2 tan 15 * 10) = 75 % of the 16 pixels, columns and rows 2..13. Its inner 8x8
    # pixels are ka * A * red = (1, 0, 0) exactly (no kd, ks, kr, kt).
    np.testing.assert_array_equal(closed[4:12, 4:12].reshape(-1, 3), [[1.0, 0.0, 0.0]] * 64)


@pytest.mark.parametrize("winding, mirrored, seen", [
    ("front", False, "refracted"), ("back", False, "reflected"), ("front", True, "refracted")])
def test_triangle_front_side_decides_entering_or_leaving(winding, mirrored, seen):
    """A glass square (eta 1.5, kt = 1) seen at 60 degrees incidence. Through its front
    side a ray enters (1 -> 1.5) and refracts toward a red wall behind; through its back
    side it leaves (1.5 -> 1): sin t = 1.5 sin 60 > 1, total internal reflection, and the
    kt share follows the mirror direction to the green background. A mirroring transform
    (scale -1 1 1) keeps the front side (normals go by the inverse transpose)."""
    # The square in the plane z = 0, turned 60 degrees about y, front (+z before turning)
    # toward the camera.
    corners = [(-3, -3), (3, -3), (3, 3), (-3, 3)]
    order = [(0, 1, 2), (0, 2, 3)] if winding == "front" else [(0, 2, 1), (0, 3, 2)]
    tris = "".join("triangle " + " ".join(f"{corners[i][0]} {corners[i][1]} 0" for i in o) + "\n"
                   for o in order)
    steps = ("scale -1 1 1\n" if mirrored else "") + "rotateY 60\n"
    # The refracted centre ray meets z = -20 at x ~ -9 (it turns 60 - 35.3 degrees toward
    # -x); the mirror direction (0.87, 0, -0.5) at x ~ +35: only the former sees the wall.
    image = render_ray("background 0 1 0\nlight 1 1 1 ambient\n"
                       "material 1 0 0  1 0 0 1  0 0 1\n"  # the red wall, far behind on the left
                       "triangle -40 -40 -20  -2 -40 -20  -2 40 -20\n"
                       "triangle -40 -40 -20  -2 40 -20  -40 40 -20\n"
                       "material 1 1 1  0 0 0 1  0 1 1.5\n" + steps + tris, 9, 9)
    centre = image[4, 4]
    want = [1.0, 0.0, 0.0] if seen == "refracted" else [0.0, 1.0, 0.0]
    np.testing.assert_allclose(centre, want, rtol=0, atol=1e-6)


def test_image_texture_on_a_triangle(tmp_path):
    """Texture coordinates (0, 0), (1, 0), (0, 1) at a triangle's corners as written: an
    8 x 8 PNG whose four 4 x 4 quadrants have different colors; pixels near each corner of
    the triangle see the quadrant of that corner's uv. v runs up the image (Mitsuba's bitmap
    convention: uv (0, 0) is the image's bottom-left corner), so a triangle with its corners
    at the bottom-left, bottom-right and top-left shows the image upright. The texel
    multiplies the base color C."""
    from PIL import Image

    quadrant = {(0, 0): (255, 0, 0), (1, 0): (0, 255, 0), (0, 1): (0, 0, 255),
                (1, 1): (255, 255, 255)}  # (u half, v half) -> 8-bit color
    pixels = np.zeros((8, 8, 3), np.uint8)
    for (u, v), color in quadrant.items():
        pixels[4 - 4 * v:8 - 4 * v, 4 * u:4 * u + 4] = color  # v = 0 is the bottom half
    Image.fromarray(pixels, "RGB").save(tmp_path / "quad.png")

    # Corners p0 (uv 0,0) bottom-left, p1 (uv 1,0) bottom-right, p2 (uv 0,1) top-left.
    p0, p1, p2 = np.array([-2.0, -2, 0]), np.array([2.0, -2, 0]), np.array([-2.0, 2, 0])
    width = height = 32
    image = render_ray(f"light 1 1 1 ambient\nmaterial 1 1 0.5  1 0 0 1  0 0 1\n"
                       f"texture {tmp_path / 'quad.png'}\n"
                       "triangle " + " ".join(f"{x:g}" for p in (p0, p1, p2) for x in p) + "\n",
                       width, height)
    o, d = camera_rays(width, height)
    t = intersect_plane(o, d, (0, 0, 0), (0, 0, 1))
    p = o + t[..., None] * d
    # barycentric (u, v): p = p0 + u (p1 - p0) + v (p2 - p0)
    u, v = (p[..., 0] + 2) / 4, (p[..., 1] + 2) / 4
    inside = (u > 0) & (v > 0) & (u + v < 1)
    # Bilinear filtering with 8 texels per unit: a sample whose texel coordinates are more
    # than one texel away from a quadrant border (including the wrapped border at 0 / 1)
    # reads only texels of its quadrant, so it is exactly that quadrant's color.
    def clear(a):
        x = a * 8 - 0.5  # texel space, texel centres at integers
        return (np.abs(x - 3.5) > 1) & (np.abs(x - (-0.5)) > 1) & (np.abs(x - 7.5) > 1)

    ok = inside & clear(u) & clear(v)
    seen = set()
    for (qu, qv), color in quadrant.items():
        sel = ok & ((u >= 0.5) == qu) & ((v >= 0.5) == qv)
        if sel.any():
            seen.add((qu, qv))
            want = np.array(color) / 255.0 * [1, 1, 0.5]
            np.testing.assert_allclose(image[sel], np.broadcast_to(want, image[sel].shape),
                                       rtol=0, atol=1e-6)
    assert seen == {(0, 0), (1, 0), (0, 1)}  # the three corners' quadrants
    assert np.all(image[~inside & ~(np.abs(u + v - 1) < 0.05)] == 0.0)


def test_smooth_mesh_does_not_shadow_itself_at_the_terminator():
    """The contract: the surface being shaded does not count as a crossing, and a convex
    object never shadows itself where N.L > 0. A tessellated cylinder lit from the side
    (light along -x) must show kd C N.L right up to the terminator, also where N.L is
    small: there the shading normal says "lit" while the flat facet under the hit point
    faces slightly away from the light, so a shadow ray leaving the facet runs into the
    mesh's own far side unless the integrator takes care (plugins/whitted/lift.py).
    The facet phase matters: this orientation (rotateY 20) showed the artifact."""
    steps = [("scale", (1.2, 1.5, 1.2)), ("rotateY", (20,))]
    m = _matrix(steps)
    width = height = 40
    image = render_ray("eye 0 3 4\nlight 1 1 1 directional -1 0 0\n"
                       "material 1 1 1  0 0.8 0 1  0 0 1\n" + _transform_text(steps) +
                       "cylinder\n", width, height)
    o, d = camera_rays(width, height, eye=(0, 3, 4))
    t, n, part = cast("cylinder", m, o, d)
    _, ambiguous = analytic_mask("cylinder", m, width, height, eye=(0, 3, 4))
    n_dot_l = n @ np.array([1.0, 0.0, 0.0])
    band = (part == 0) & ~ambiguous & (n_dot_l > 0.005) & (n_dot_l < 0.1)
    assert band.sum() > 5
    # (interpolated normals: within 5e-3, see test_cylinder_and_cone_outline_...)
    np.testing.assert_allclose(image[band][:, 0], 0.8 * n_dot_l[band], rtol=0, atol=5e-3)


# -- many objects: every code path of the translator at once --------------------------------------
def _cast_triangle(corners, o, d):
    """(t, unit normal facing the ray) of rays with one triangle (both sides are fronts)."""
    a, b, c = corners
    t, u, v = intersect_triangle(o, d, a, b, c)
    n = normalize(np.cross(b - a, c - a))
    n = np.where((d @ n < 0)[..., None], n, -n)
    return t, np.broadcast_to(n, d.shape)


def test_a_few_hundred_objects_through_every_path():
    """225 objects on a grid, rendered at 128x128: analytic spheres each with its own material;
    then ellipsoids (some mirrored), cylinders, cones and triangles sharing two materials (the
    translator merges each material's curved objects into one mesh and its triangles into
    another). Every pixel away from an outline is the closed form ambient + kd C N.L of the
    object the analytic cast hits first, with its own color and its exact normal."""
    width = height = 128
    eye = (0.0, 0.0, 20.0)
    l = np.array([0.0, 0.0, 1.0])  # the light travels along -z
    rng = np.random.default_rng(7)
    cells = [(x - 7.0, y - 7.0) for y in range(15) for x in range(15)]
    lines = [f"eye {eye[0]} {eye[1]} {eye[2]}\nlight 0.2 0.2 0.2 ambient\n"
             "light 1 1 1 directional 0 0 -1\n"]
    objects = []  # (kind, to_world, color) or ("triangle", corners, color)
    shared = {"A": (0.9, 0.5, 0.2), "B": (0.3, 0.6, 0.9)}
    for k, (x, y) in enumerate(cells[0::5]):  # analytic spheres, own materials
        color = tuple(np.round(rng.uniform(0.2, 1.0, 3), 2))
        lines.append(f"material {color[0]} {color[1]} {color[2]}  1 0.8 0 1  0 0 1\n"
                     f"scale 0.35 0.35 0.35\ntranslate {x} {y} 0\nsphere\npop\npop\n")
        objects.append(("sphere", stack(scaling(0.35, 0.35, 0.35), translation(x, y, 0)), color))
    groups = (("A", ("sphere", "cylinder"), cells[1::5] + cells[2::5]),
              ("B", ("cone", "triangle"), cells[3::5] + cells[4::5]))
    for name, kinds, at in groups:
        c = shared[name]
        lines.append(f"material {c[0]} {c[1]} {c[2]}  1 0.8 0 1  0 0 1\n")
        for k, (x, y) in enumerate(at):
            kind = kinds[k % 2]
            mirror = -1 if k % 3 == 0 else 1
            steps = [("scale", (0.4 * mirror, 0.25, 0.3)), ("rotateX", (25 + 7 * k % 40,)),
                     ("rotateY", (11 * k % 60,)), ("translate", (x, y, 0))]
            lines.append(_transform_text(steps))
            if kind == "triangle":
                lines.append("triangle -1 -1 0  1 -1 0.5  0 1 0\n")
                m = _matrix(steps)
                corners = np.array([[-1, -1, 0, 1], [1, -1, 0.5, 1], [0, 1, 0, 1]]) @ m.T
                objects.append(("triangle", corners[:, :3], c))
            else:
                lines.append(kind + "\n")
                objects.append((kind, _matrix(steps), c))
            lines.append("pop\n" * len(steps))
    image = render_ray("".join(lines), width, height)

    o, d = camera_rays(width, height, eye=eye)
    best_t = np.full((height, width), np.inf)
    want = np.zeros((height, width, 3))
    ambiguous = np.zeros((height, width), bool)
    grazing = np.zeros((height, width), bool)
    for kind, where, color in objects:
        if kind == "triangle":
            t, n = _cast_triangle(where, o, d)
            for dx, dy in ((BAND, 0), (-BAND, 0), (0, BAND), (0, -BAND)):
                so, sd = camera_rays(width, height, eye=eye, dx=dx, dy=dy)
                ambiguous |= np.isfinite(_cast_triangle(where, so, sd)[0]) != np.isfinite(t)
        else:  # ambiguous also where the part hit (side, cap) changes: the rims
            t, n, part = cast(kind, where, o, d)
            for dx, dy in ((BAND, 0), (-BAND, 0), (0, BAND), (0, -BAND)):
                ambiguous |= cast(kind, where, *camera_rays(width, height, eye=eye, dx=dx, dy=dy))[2] != part
        nearer = np.isfinite(t) & (t < best_t)
        best_t = np.where(nearer, t, best_t)
        grazing = np.where(nearer, -np.sum(n * d, axis=-1) < 0.5, grazing)
        shade = 0.2 + 0.8 * np.maximum(n @ l, 0.0)
        want = np.where(nearer[..., None], shade[..., None] * np.array(color), want)
    hit = np.isfinite(best_t)
    # Smooth normals are interpolated: within 1e-2 where N.V > 0.5 (see
    # test_ellipsoid_silhouette_and_normals); flat faces and analytic spheres are exact.
    check = ~ambiguous & ~grazing
    assert check.sum() > 12000 and (hit & check).sum() > 1500
    np.testing.assert_allclose(image[check], want[check], rtol=0, atol=1e-2)
    # Each object's own color: analytic spheres differ one from the next.
    assert len({tuple(np.round(image[p], 3)) for p in zip(*np.nonzero(hit & check))}) > 100
