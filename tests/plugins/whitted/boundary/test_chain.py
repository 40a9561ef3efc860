"""Edges seen along the specular chain (plugins/whitted/boundary/chain.py): a shadow seen
in a mirror against finite differences (at k = 4, per-pixel relative L2 measured 6.1 %),
and chains that reach the last bounce followed."""

from __future__ import annotations

import pytest

from support_edges import MIRRORED_SHADOW, assert_matches_finite_differences, pairs_of_a_step


@pytest.mark.parametrize("text, key, direction, h", [
    (MIRRORED_SHADOW, "light1.position", (0.6, 0.0, -0.8), 0.05),  # a shadow in a mirror
], ids=["mirrored-shadow"])
def test_a_shadow_seen_in_a_mirror_matches_finite_differences(mi, text, key, direction, h):
    """A sphere's shadow on a wall, seen directly and in a mirror floor, the light moved."""
    assert_matches_finite_differences(mi, text, key, direction, h)


# two parallel mirrors (a floor and a ceiling) and a sphere between: chains that bounce to
# the last bounce followed (CHAIN_DEPTH)
MIRROR_CORRIDOR = """\
eye 0 0 5
lookat 0 -0.3 0
fov 50
background 0.2 0.3 0.4
light 1 1 1 point 0 0.5 4
light 0.2 0.2 0.2 ambient
material 0.6 0.6 0.6 0.2 0.3 0 1 0.8 0 1
translate 0 -1 0
checkerboard 0.5
plane
reset
translate 0 1 0
plane
reset
material 0.8 0.3 0.2 0.3 0.7 0 1 0 0 1
scale 0.5 0.5 0.5
sphere
"""


def test_chains_that_reach_the_last_bounce_followed_form_their_pairs(mi, monkeypatch):
    """Every bounce of the chain reached by some sample: the pairs are formed at each (the
    classification once failed there, finding no bounce that no chain reaches)."""
    import drjit as dr
    import numpy as np

    from raymitsuba.plugins.whitted import boundary

    scene, edges, found = pairs_of_a_step(mi, monkeypatch, MIRROR_CORRIDOR)
    assert edges.chain_bounces() == boundary.CHAIN_DEPTH
    assert set(found["depth"].tolist()) >= set(range(boundary.CHAIN_DEPTH))
    assert np.all(np.isfinite(dr.grad(scene.params["camera.eye"]).numpy()))
