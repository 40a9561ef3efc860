"""Visibility edges (plugins/whitted/boundary/visibility.py): outlines against their closed
forms (exact for straight edges up to the quadrature of the edge over k rows per pixel:
measured < 0.5 %), silhouettes of spheres and ellipsoids against finite differences
(at k = 4, per-pixel relative L2 measured: silhouette 2.9 %, camera 2.1 %)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from support_edges import (FLAT, HORIZON, HORIZON_RATE, JUMP, PIXELS_PER_UNIT, SPHERE, H, W,
                           assert_matches_finite_differences, finite_difference, forward,
                           loaded, relative_l2, weights)


# a rectangle whose right edge (x = 0.1 in the world) crosses every row of the image
RECTANGLE = FLAT + "triangle -3 -3 0  0 -3 0  0 3 0\ntriangle -3 -3 0  0 3 0  -3 3 0\n"
# the same, turned by 25 degrees about the view axis (after the translate: it moves along
# the edge's normal)
SLANTED = FLAT + ("rotateZ 25\ntriangle -5 -5 0  0 -5 0  0 5 0\n"
                  "triangle -5 -5 0  0 5 0  -5 5 0\n")


@pytest.mark.parametrize("spp", [1, 4, 16])
def test_a_vertical_edge_moves_by_its_closed_form(mi, spp):
    # The edge x = 0.1 lies in pixel column 8 on every row: moving it right by dx fills
    # dx * PIXELS_PER_UNIT of that column's pixels with the rectangle's color.
    grad = forward(mi, RECTANGLE, "translate1.offset", (1, 0, 0), spp)
    expected = np.zeros((H, W))
    expected[:, 8] = JUMP * PIXELS_PER_UNIT
    np.testing.assert_allclose(grad[..., 0], expected, rtol=1e-3, atol=1e-4)


def test_a_slanted_edge_moves_by_its_closed_form(mi):
    # translate1 is applied before the rotation: the edge moves along its own normal, at
    # unit speed, and crosses all H rows: the image's sum changes by JUMP * (H / cos 25)
    # pixels of edge * PIXELS_PER_UNIT.
    grad = forward(mi, SLANTED, "translate1.offset", (1, 0, 0), 16)
    expected = JUMP * PIXELS_PER_UNIT * H / math.cos(math.radians(25))
    assert grad[..., 0].sum() == pytest.approx(expected, rel=0.01)


@pytest.mark.parametrize("spp", [1, 4, 16])
@pytest.mark.parametrize("key, sign", [("camera.lookat", 1.0), ("camera.eye", -1.0)])
def test_the_horizon_moves_with_the_camera_by_its_closed_form(mi, key, sign, spp):
    # The camera pitches down by b = atan((eye - look-at) / 5) in y; the horizon is at b
    # above the optical axis, at row H/2 - (H/2) tan b / tan 20 (5.67: in row 5), which
    # moves down by H / (10 tan 20) rows per unit the look-at point rises (up, as the eye
    # does), at any b: each pixel of row 5 turns from the floor (0.8 red) to the background
    # (0.2) at that rate. Two things made it wrong before: the edge functions took their
    # sign from the ray's direction, which flips where the plane's far ring is seen edge-on
    # (the derivative's sign came out wrong); and a ray's face's own edge stood for the
    # plane's outline, which is the horizon (at k = 1 the term fell in row 6, and it moved
    # with the eye).
    grad = forward(mi, HORIZON, key, (0, 1, 0), spp)
    expected = np.zeros((H, W))
    expected[5] = sign * HORIZON_RATE
    np.testing.assert_allclose(grad[..., 0], expected, rtol=1e-3, atol=1e-4)


# a cylinder seen from above and in front, lit from straight above: its cap is bright, its
# side (and the background, the same colour) only ambient
CYLINDER = """\
eye 0 3 4
lookat 0 0 0
fov 40
background 0.24 0.12 0.09
light 1 1 1 directional 0 -1 0
light 0.3 0.3 0.3 ambient
material 0.8 0.4 0.3 1 0.7 0 1 0 0 1
translate 0 0.2 0
scale 1.2 1.0 1.2
cylinder
"""


def test_a_cylinders_cap_moves_its_rim_across_the_side_and_the_background(mi):
    """The cap's outline: in front, a crease of the one smooth mesh (cap and side) across
    which the shading jumps; behind, against the background, where the side's back faces,
    grown against cracks, stand a sliver above the cap's rim. At k = 8 (measured: the
    weighted sum 0.7 % of the sum of sizes off, per-pixel relative L2 9.2 %; before the
    crease counted as an edge and the sliver was told from the cap: 40 % and 78 %)."""
    key, direction = "translate1.offset", (0.0, 1.0, 0.0)
    reference = finite_difference(mi, CYLINDER, key, direction, 0.02)
    grad = forward(mi, CYLINDER, key, direction, 64)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.03 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.12


def test_a_cylinders_cap_rim_is_followed_across_the_fan_at_a_coarse_lattice(mi):
    """The cap is a fan of thin triangles: a pair from a sample on the cap to one past its
    rim may leave the sample's face through a spoke, whose line is no edge; the pair is
    followed across the fan to the rim (Visibility.outline, by the tessellation's declared
    neighbours). The camera's fov at k = 4 (measured: the weighted sum 0.2 % of the sum of
    sizes off, per-pixel relative L2 1.8 %; with the spoke standing for the rim, 17.1 % and
    20.6 %). The reference's own spread (h against h / 2, and a 4 x 4 finer lattice): 1.2 %
    and 3.2 %; the bounds, 2 % and 6 %, are that spread with a margin."""
    key, direction = "camera.fov", (1.0,)
    reference = finite_difference(mi, CYLINDER, key, direction, 0.2)
    grad = forward(mi, CYLINDER, key, direction, 16)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.02 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.06


# a cone through a floor: the crease where they meet is the base's outline, and the cone's
# thin side faces, which go on under the floor, end there at edges of their own
CONE_THROUGH_FLOOR = """\
eye -1.6 1.6 2.4
lookat -0.5 -0.9 -0.9
fov 40
background 0.3 0.2 0.35
light 0.7 0.9 0.6 point -0.5 5 -1.5
light 0.15 0.15 0.3 ambient
material 0.6 0.9 0.7 0.2 0.7 0.0 10 0 0 1
translate 0 -1 0
plane
reset
material 0.7 0.3 1 0.3 0.8 0.4 30 0 0 1
translate -0.5 -0.4 -1
scale 0.6 1.2 0.6
cone
"""


@pytest.mark.parametrize("key, direction, h", [
    ("camera.fov", (1.0,), 0.2),
    ("camera.eye", (0.6, 0.0, -0.8), 0.02),
], ids=["fov", "eye"])
def test_a_cone_through_the_floor_moves_its_crease_with_the_camera(mi, key, direction, h):
    """The camera moving, the crease between a cone and the floor moves as itself, not as the
    outlines of the cone's side faces that end past it, under the floor (Visibility.
    crease_first). At k = 16 against the finite difference (its own spread, h against h /
    2 and a 4 x 4 finer lattice: within 1 % of the sum of sizes, 6.5 % per pixel), measured:
    the weighted sum 0.5 % (fov) and 1.2 % (eye) of the sum of sizes off, per-pixel relative
    L2 6.7 % and 7.1 % (with the cone's silhouette followed across its faces,
    Visibility.outline; before, 0.5 % and 2.2 %, 9.9 % and 9.3 %); with each side face's own
    edge standing for the crease, 2.0 % and 4.9 %, 13.8 % and 17.5 %. The bounds, 3 % and
    12 %, are the larger figure measured and the reference's own spread, which the old
    rule's per-pixel errors exceed."""
    reference = finite_difference(mi, CONE_THROUGH_FLOOR, key, direction, h)
    grad = forward(mi, CONE_THROUGH_FLOOR, key, direction, 256)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.03 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.12


@pytest.mark.parametrize("text, key, direction, h", [
    (SPHERE, "translate1.offset", (0.6, -0.8, 0.0), 0.03),  # a silhouette
    (SPHERE, "camera.eye", (0.6, 0.0, -0.8), 0.03),  # the same, from the camera
], ids=["silhouette", "camera"])
def test_a_silhouette_moved_or_seen_by_a_moving_camera_matches_finite_differences(
        mi, text, key, direction, h):
    """A sphere's silhouette, the sphere moved or the camera."""
    assert_matches_finite_differences(mi, text, key, direction, h)


def test_an_ellipsoid_of_the_sphere_set_moves_its_silhouette_with_the_camera(mi):
    """A sphere under a non-uniform scale, drawn as an exact ellipsoid of the sphere set
    (``sphere_set=1``): its silhouette's inside function is taken in its object space
    (hits.py ``sphere_frame``); the same tolerances as the sphere's."""
    text = FLAT + "rotateZ 30\nscale 1.2 0.7 0.9\nsphere\n"
    key, direction, h = "camera.eye", (0.6, 0.0, -0.8), 0.03
    assert "spheres" in loaded(mi, text, 1, sphere_set=1).scene_dict
    reference = finite_difference(mi, text, key, direction, h, sphere_set=1)
    w = weights()
    grad = forward(mi, text, key, direction, 16, sphere_set=1)
    assert abs(np.sum(w * (grad - reference))) < 0.05 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.15
