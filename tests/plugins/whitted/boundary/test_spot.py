"""A spot's cone edge (plugins/whitted/boundary/spot.py) against finite differences (at
k = 4, per-pixel relative L2 measured: 2.8 % moved, 5.8 % turned)."""

from __future__ import annotations

import pytest

from support_edges import SPOT, assert_matches_finite_differences


@pytest.mark.parametrize("text, key, direction, h", [
    (SPOT, "light1.position", (0.6, 0.0, 0.8), 0.02),  # a spot's cone edge
    (SPOT, "light1.direction", (0.0, 0.0, 1.0), 0.02),  # the same, turned
], ids=['spot-moved', 'spot-turned'])
def test_a_spots_cone_edge_moved_or_turned_matches_finite_differences(mi, text, key, direction, h):
    """A spot of coefficient 0 on a floor: the edge of its cone (cos a = 0) as the spot
    moves and turns."""
    assert_matches_finite_differences(mi, text, key, direction, h)
