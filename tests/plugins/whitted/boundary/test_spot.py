"""A spot's cone edge (plugins/whitted/boundary/spot.py): g across it, and the derivative
against finite differences (at k = 4, per-pixel relative L2 measured: 2.8 % moved, 5.8 %
turned)."""

from __future__ import annotations

import pytest

from support_edges import SPOT, assert_matches_finite_differences


@pytest.mark.parametrize("text, key, direction, h", [
    (SPOT, "light1.position", (0.6, 0.0, 0.8), 0.02),  # a spot's cone edge
    (SPOT, "light1.direction", (0.0, 0.0, 1.0), 0.02),  # the same, turned
], ids=["spot-moved", "spot-turned"])
def test_a_spots_cone_edge_moved_or_turned_matches_finite_differences(
        mi, text, key, direction, h):
    """A spot of coefficient 0 on a floor: the edge of its cone (cos a = 0) as the spot
    moves and turns."""
    assert_matches_finite_differences(mi, text, key, direction, h)


def test_a_spots_cone_is_g_only_where_cos_a_changes_sign_between_l_and_r(mi):
    """cone_crossing: for a spot, g is its cos a at the pairs whose samples lie either side
    of its cone (cos a's signs differ between L and R), elsewhere N.L (the terminator's);
    a light without a cone leaves N.L, and no pair crosses a cone."""
    from types import SimpleNamespace

    from raymitsuba.plugins.whitted.boundary.spot import cone_crossing

    spot = SimpleNamespace(kind="spotlight", direction=mi.Vector3f(0, 0, 1))
    # two pairs stacked (L of both, then R of both): cos a = -wi.z = 1, 1 at L; -1, 1 at R
    wi = mi.Vector3f(mi.Float(0.0), mi.Float(0.0), mi.Float([-1.0, -1.0, 1.0, -1.0]))
    facing = mi.Float([0.5, 0.25, 0.75, 0.125])
    g, crosses = cone_crossing(spot, wi, facing, None, 2, 4)
    assert crosses.numpy().tolist() == [True, False]
    assert g.numpy().tolist() == [1.0, 0.25, -1.0, 0.125]
    # the choice made once is kept: given it, the same g
    again, kept = cone_crossing(spot, wi, facing, (crosses,), 2, 4)
    assert again.numpy().tolist() == g.numpy().tolist() and kept is crosses
    point = SimpleNamespace(kind="point", direction=None)
    g, crosses = cone_crossing(point, wi, facing, None, 2, 4)
    assert crosses is None and g.numpy().tolist() == facing.numpy().tolist()
