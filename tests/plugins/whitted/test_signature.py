"""Path signatures (plugins/whitted/signature.py): the hash of what a sample's ray tree saw, and
what anti-aliasing does with it: a pixel crossed by a silhouette or a shadow's edge is refined,
one crossed only by the edges of a filtered checkerboard is not."""

import numpy as np
import pytest

from support import camera_rays, intersect_plane, intersect_sphere, normalize, render_ray


@pytest.fixture(scope="module")
def sig(mitsuba):
    from raymitsuba.plugins.whitted import signature

    return signature


def test_a_tree_without_children_keeps_its_own_signature(mitsuba, sig):
    own = mitsuba.UInt32([5, 5, sig.POINT_SAMPLED | 5])
    child = mitsuba.UInt32([9, 9, 9])
    none, some = mitsuba.Bool(False), mitsuba.Bool([False, True, True])
    # whether or not the batch traced any child at all (a chunk without children)
    assert sig.with_children(own, [(child, none), (child, none)]).numpy().tolist() == \
        own.numpy().tolist()
    mixed = sig.with_children(own, [(child, some), (child, none)]).numpy()
    assert mixed[0] == 5 and mixed[1] != 5  # a child that exists changes the hash
    assert mixed[2] & sig.POINT_SAMPLED  # the root's point sample stays
    # a reflected child is not a refracted one with the same signature
    assert sig.with_children(own, [(child, some), (child, none)]).numpy()[1] != \
        sig.with_children(own, [(child, none), (child, some)]).numpy()[1]


def test_a_childs_point_sample_and_grid_reach_the_root(mitsuba, sig):
    own = mitsuba.UInt32(7)
    grid = sig.grid_code(mitsuba.Float(2.5 * sig.FIRST_ORDER))  # a 3 x 3 grid
    child = mitsuba.UInt32([sig.POINT_SAMPLED | 3, 3 | grid.numpy()[0]])
    tree = sig.with_children(own, [(child, mitsuba.Bool(True))]).numpy()
    assert tree[0] & sig.POINT_SAMPLED and not tree[1] & sig.POINT_SAMPLED
    assert (tree[1] & sig.GRID_BITS) >> sig.GRID_SHIFT == 2


def test_the_grid_asks_for_samples_each_distorted_within_first_order(mitsuba, sig):
    distortion = mitsuba.Float(np.array([0.0, 1.0, 1.01, 2.0, 3.5, 100.0]) * sig.FIRST_ORDER)
    sides = (sig.grid_code(distortion).numpy() >> sig.GRID_SHIFT) + 1
    assert sides.tolist() == [1, 1, 2, 2, 4, sig.MAX_GRID]


def test_pixels_agree_where_their_samples_and_neighbours_share_one_path(sig):
    centre = np.full((3, 3), 1, np.uint32)
    corners = np.full((4, 4), 1, np.uint32)
    corners[0, 0] = 1 | (1 << sig.GRID_SHIFT)  # the same hash, another grid
    assert sig.agree(centre, corners).all()
    assert sig.grid_sides(centre, corners)[0].tolist() == [2, 1, 1]
    corners[3, 3] = 5  # another path at the last pixel's corner
    assert sig.agree(centre, corners).tolist() == [[True] * 3, [True] * 3, [True, True, False]]
    corners[3, 3] = 1
    centre[0, 1] = 7  # another path at a pixel's centre: it and its four neighbours differ
    assert sig.agree(centre, corners).tolist() == [[False, False, False], [True, False, True],
                                                   [True, True, True]]
    centre[0, 1] = 1 | sig.POINT_SAMPLED  # a texture read at a point: not the same path
    assert not sig.agree(centre, corners)[0].any()
    samples = np.array([[1, 1, 1], [1, 1, 1 | sig.POINT_SAMPLED]], np.uint32)
    assert sig.one_path(np.array([1, 1], np.uint32), samples).tolist() == [True, False]


# A white sphere on a checkered floor, lit by a directional light that casts its shadow on the
# floor in front of it; every surface is flat-coloured where lit (ambient and diffuse only)
SCENE = """\
eye 0 1.6 5
lookat 0 0.4 0
fov 40
background 0 0 0
light 0.4 0.4 0.4 ambient
light 0.6 0.6 0.6 directional 0.4 -1 0.6
material 1 1 1  1 1 0 1  0 0 1
checkerboard 0.5
plane
checkerboard -1
material 0.9 0.9 0.9  1 1 0 1  0 0 1
scale 0.7 0.7 0.7
translate 0 0.7 0
sphere
"""
EYE, LOOKAT, FOV = (0, 1.6, 5), (0, 0.4, 0), 40
CENTRE, RADIUS = (0, 0.7, 0), 0.7
LIGHT = normalize(np.array([-0.4, 1.0, -0.6]))  # towards the light


def _coverage(width, height, n=8):
    """(sphere, shadow): per pixel, the share of an n x n grid of its points that sees the
    sphere, and that sees the floor in the sphere's shadow (float64, independent of the
    renderer)."""
    sphere = np.zeros((height, width))
    shadow = np.zeros((height, width))
    for i in range(n):
        for j in range(n):
            o, d = camera_rays(width, height, EYE, LOOKAT, fov=FOV,
                               dx=(i + 0.5) / n - 0.5, dy=(j + 0.5) / n - 0.5)
            t_sphere = intersect_sphere(o, d, CENTRE, RADIUS)
            t_floor = intersect_plane(o, d, (0, 0, 0), (0, 1, 0))
            on_sphere = np.isfinite(t_sphere)
            on_floor = ~on_sphere & np.isfinite(t_floor)
            p = np.asarray(o) + np.nan_to_num(t_floor)[..., None] * d
            shaded = np.isfinite(intersect_sphere(p, np.broadcast_to(LIGHT, p.shape),
                                                  CENTRE, RADIUS))
            sphere += on_sphere
            shadow += on_floor & shaded
    return sphere / n ** 2, shadow / n ** 2


def test_silhouettes_and_shadows_are_refined_and_the_boards_edges_are_not(mitsuba):
    """Every pixel a silhouette or a shadow's edge crosses (a tenth to nine tenths of the
    pixel each side: 64) is refined; of the floor's pixels near the camera that only the
    board's edges cross (867), none is refined but where a corner of the board is in its
    footprint (a 2 x 2 grid: 87 of them): the first pass's footprint averaged the rest."""
    import raymitsuba

    width, height = 64, 48
    loaded = raymitsuba.load(SCENE, width=width, height=height, aa=0.02)
    image = np.array(loaded.integrator.render_array(loaded.scene))
    side = np.zeros(width * height, int)
    for level in loaded.integrator.plan.levels:
        side[level.pixels] = level.n
    side = side.reshape(height, width)
    sphere, shadow = _coverage(width, height)
    edge = ((sphere > 0.1) & (sphere < 0.9)) | ((sphere == 0) & (shadow > 0.1) & (shadow < 0.9))
    assert edge.sum() > 50
    assert (side[edge] > 0).all()
    # the lower third's pixels whose 3 x 3 neighbourhood neither a silhouette nor a shadow
    # crosses
    pure = (sphere == 0) & ((shadow == 0) | (shadow == 1))
    for axis in (0, 1):
        for shift in (-1, 1):
            pure &= np.roll(sphere == 0, shift, axis) & np.roll((shadow == 0) | (shadow == 1),
                                                               shift, axis)
    pure[: 2 * height // 3] = False
    pure[:, [0, -1]] = False
    assert pure.sum() > 300
    assert np.isin(side[pure], (0, 2)).all() and (side[pure] == 2).mean() < 0.2
    # and their values are the pixels' averages: measured against 1024 samples, 0.41 / 255
    # on average, 2.43 / 255 at most, which is the reference's own error: a 32 x 32 grid
    # resolves an edge parallel to its rows to 1/32 of a pixel (up to 1.6 % of the edge's
    # contrast of 0.85: 3.4 / 255)
    reference = render_ray(SCENE, width, height, spp=1024)
    error = np.abs(image - reference).max(axis=-1)[pure]
    assert error.mean() < 1 / 255 and error.max() < 3.4 / 255
