"""Shadow edges and the terminator (plugins/whitted/boundary/shadows.py) against finite
differences (at k = 4, per-pixel relative L2 measured: shadow 5.4 %, terminator 2.7 %)."""

from __future__ import annotations

import pytest

from support_edges import SHADOW, TERMINATOR, assert_matches_finite_differences


@pytest.mark.parametrize("text, key, direction, h", [
    (SHADOW, "light1.position", (0.6, 0.0, -0.8), 0.05),  # a shadow edge and shading
    (TERMINATOR, "light1.position", (0.0, 0.6, 0.8), 0.05),  # the terminator, N.L = 0
], ids=["shadow", "terminator"])
def test_a_moving_lights_shadow_edge_and_terminator_match_finite_differences(
        mi, text, key, direction, h):
    """A point light moved: a sphere's shadow on a plane (and the shading), and a
    shiny sphere's terminator (N.L = 0)."""
    assert_matches_finite_differences(mi, text, key, direction, h)
