"""Total internal reflection switching along the specular chain
(plugins/whitted/boundary/tir.py) against finite differences (at k = 4, per-pixel relative
L2 measured 2.5 %)."""

from __future__ import annotations

import pytest

from support_edges import SNELL, assert_matches_finite_differences


@pytest.mark.parametrize("text, key, direction, h", [
    (SNELL, "mat1.ior", (1.0,), 0.002),  # total internal reflection switching
], ids=["tir"])
def test_snells_window_moves_with_eta_as_finite_differences(mi, text, key, direction, h):
    """Looking up from under a glass surface: total internal reflection switches on at
    the critical angle, which eta moves."""
    assert_matches_finite_differences(mi, text, key, direction, h)
