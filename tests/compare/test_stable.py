"""Tests of raymitsuba/compare/stable.py: the unstable pixels of scenes with and without
edges, and the cost (4 renders)."""

from __future__ import annotations

import numpy as np

from raymitsuba.compare import Settings, compare_scene
from raymitsuba.compare.stable import RENDERS, reference, scene_scale
from raymitsuba.format.parser import parse_text

TOL = 2 / 255

# A plane filling the view, lit evenly: no edge anywhere, nothing can be unstable.
FLAT = """eye 0 5 0
lookat 0 0 0
up 0 0 -1
light 0.3 0.3 0.3 ambient
light 0.6 0.6 0.6 directional 0 -1 0
material 0.8 0.6 0.4 1 1 0 1 0 0 1
plane
"""

# A triangle with a vertical edge on x = 0: with an odd width the centre column's rays pass
# exactly through the edge (their x is exactly 0), so float rounding decides those pixels.
EDGE = """eye 0 0 5
lookat 0 0 0
up 0 1 0
light 1 1 1 ambient
material 1 1 1 1 0 0 1 0 0 1
triangle 0 -1 0  2 -1 0  0 1 0
"""


def test_a_scene_without_edges_has_no_unstable_pixel():
    ref = reference(parse_text(FLAT), 21, 15, TOL)
    assert ref.renders == RENDERS == 4
    assert not ref.unstable.any()
    # one flat color: (ambient 0.3 + directional 0.6 at N.L = 1) x (0.8, 0.6, 0.4)
    assert np.allclose(ref.image, [0.72, 0.54, 0.36], atol=1e-6)


def test_an_edge_through_pixel_centres_is_left_out_and_nothing_else():
    width = height = 21
    ref = reference(parse_text(EDGE), width, height, TOL)
    centre = width // 2
    rows = np.flatnonzero(ref.unstable.any(axis=1))
    # only the centre column, and along most of the edge's span (the triangle's edge runs
    # from y = -1 to 1: at distance 5 with fov 45, 2 / (2 * 5 * tan 22.5) = 48 % of the rows)
    assert set(np.flatnonzero(ref.unstable.any(axis=0))) == {centre}
    assert len(rows) >= 8
    # the pixels next to the edge are stable: inside white, outside black
    inner = rows[1:-1]  # (the ends meet the hypotenuse and the bottom edge)
    assert (ref.image[inner, centre + 1] == 1).all() and (ref.image[inner, centre - 1] == 0).all()


def test_compare_leaves_the_unstable_pixels_out_of_the_score():
    width = height = 21
    ref = reference(parse_text(EDGE), width, height, TOL)
    flipped = ref.image.copy()
    flipped[ref.unstable] = 1 - flipped[ref.unstable]  # the other side of the edge
    result = compare_scene(flipped, parse_text(EDGE))
    assert result.status == "pass" and result.renders == 4
    assert (result.score.match, result.score.left_out) == (100, ref.unstable.sum())
    every = compare_scene(flipped, parse_text(EDGE), Settings(stable=False))
    assert every.renders == 1 and every.status == "fail"
    assert every.score.failed == ref.unstable.sum()


def test_a_scene_reference_costs_four_renders(monkeypatch):
    """Counted on the integrator itself: every image it traces is one call of render_array."""
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted.integrator import Whitted

    calls = []
    original = Whitted.render_array

    def counted(self, *args, **kwargs):
        calls.append(1)
        return original(self, *args, **kwargs)

    monkeypatch.setattr(Whitted, "render_array", counted)
    result = compare_scene(np.zeros((9, 11, 3)), parse_text(EDGE))
    assert len(calls) == result.renders == 4


def test_the_scene_scale_is_its_box_or_the_view_distance():
    assert scene_scale(parse_text(FLAT)) == 5  # the plane has no box
    assert scene_scale(parse_text("eye 0 0 1\nscale 10 10 10\nsphere\n")) == \
        np.linalg.norm([20, 20, 20])
