"""Edges seen along the specular chain (plugins/whitted/boundary/chain.py): a shadow seen
in a mirror against finite differences (at k = 4, per-pixel relative L2 measured 6.1 %),
and chains that reach the last bounce followed."""

from __future__ import annotations

import numpy as np
import pytest

from support_edges import (MIRRORED_SHADOW, assert_matches_finite_differences, finite_difference,
                           forward, pairs_of_a_step, weights)


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


MIRROR_BALL = """\
eye 0 1.5 6
lookat 0 -0.2 0
fov 40
background 0.2 0.3 0.5
light 0.2 0.2 0.2 ambient
surface 0.8 0.6 0.4 0.3 0.7 0 1 0 0 1
triangles
v -6 -1 -6
v 6 -1 -6
v 6 -1 6
v -6 -1 6
f 0 1 2
f 0 2 3
end
surface 0.7 0.7 0.7 0.2 0.3 0.3 20 0.7 0 1
sphere 0 0 0 0.9
"""


def test_an_edge_seen_in_a_mirror_balls_rim_keeps_its_jump(mi):
    """A mirror ball's radius (MIT): the floor's far edge, seen in the ball, crowds towards
    its rim, where g (replayed along the chain) is far from linear over a lattice unit; the
    colors traced either side of its crossing both saw the same side of the reflected
    edge, and such terms were lost at every k (k = 8: weighted sum 19 % of the sum of sizes
    off). Where the chain's key at the traced sides is not L's and R's, the jump is traced
    where it switches, found by bisection (``Terms.jump``): measured 8.3 %. The rest is the
    reflection compressed at the rim (finer than the lattice, docs/gradients.md)."""
    reference = finite_difference(mi, MIRROR_BALL, "sphere1.radius", (1.0,), 0.03)
    grad = forward(mi, MIRROR_BALL, "sphere1.radius", (1.0,), 64)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.12 * np.sum(np.abs(w * reference))
