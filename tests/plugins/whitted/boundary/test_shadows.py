"""Shadow edges and the terminator (plugins/whitted/boundary/shadows.py) against finite
differences (at k = 4, per-pixel relative L2 measured: shadow 5.4 %, terminator 2.7 %)."""

from __future__ import annotations

import numpy as np
import pytest

from support_edges import (SHADOW, TERMINATOR, assert_matches_finite_differences,
                           finite_difference, forward, relative_l2, weights)


@pytest.mark.parametrize("text, key, direction, h", [
    (SHADOW, "light1.position", (0.6, 0.0, -0.8), 0.05),  # a shadow edge and shading
    (TERMINATOR, "light1.position", (0.0, 0.6, 0.8), 0.05),  # the terminator, N.L = 0
], ids=["shadow", "terminator"])
def test_a_moving_lights_shadow_edge_and_terminator_match_finite_differences(
        mi, text, key, direction, h):
    """A point light moved: a sphere's shadow on a plane (and the shading), and a
    shiny sphere's terminator (N.L = 0)."""
    assert_matches_finite_differences(mi, text, key, direction, h)


# Two MIT 6.837 spheres lit from near the camera: the front one's shadow on the one behind
# runs a fraction of a pixel beside its silhouette, a shadow edge on a sphere seen obliquely
SHADOW_ON_A_SPHERE = """\
eye 0.3 0.5 8 fov 30
background 0.2 0.3 0.4
light 1 1 1 point 2 3 7
surface 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
sphere 0.4 -0.2 0 1.3
surface 0.3 0.8 0.3 0.3 0.7 0.3 10 0 0 1
sphere -1.5 0.6 -1 0.9
"""


def test_a_shadow_on_a_sphere_keeps_every_jump_at_k_16(mi, monkeypatch):
    """g of a shadow pair is the blocker's inside function on the shadow ray from where the
    tracer starts it (off the surface, Tracer.shadow_ray): its zero is the image's edge, so
    the two rays the jump traces LIMIT lattice units either side of it are one lit and one
    in shadow (where they still are not, Terms.jump bisects for the switch). From the hit point itself it lay up to 0.03 lattice units off at k = 16 (the
    ray epsilon's offset, about 2e-4 here, is a fortieth of a lattice unit): a third of
    these pairs got a zero jump, their terms lost, and the error grew with k (light
    position: 0.8 % at k = 8, 5.7 % at k = 16 per-pixel relative L2; now 0.8 %, 0.5 %)."""
    import support_edges as S
    from raymitsuba.plugins.whitted.boundary import SHADOW as SHADOW_KIND
    from raymitsuba.plugins.whitted.boundary import terms as T

    seen = []
    jump = T.Terms.jump

    def recorded(self, ends, axis, w, kind, *edge):
        df = jump(self, ends, axis, w, kind, *edge)
        seen.append((kind, df, self.colors_at(ends.L) - self.colors_at(ends.R)))
        return df

    monkeypatch.setattr(T.Terms, "jump", recorded)
    scene = S.loaded(mi, SHADOW_ON_A_SPHERE, 256, width=32, height=24)
    S.tangent_derivative(scene, {"light1.position": (1.0, 1.0, 0.0)})
    kind, df, lr = (np.concatenate(a) for a in zip(*seen))
    shadow = (kind == SHADOW_KIND) & (np.abs(lr.sum(-1)) > 0.1)  # a visible shadow edge
    assert shadow.sum() > 100
    # the jump is the one-sided colors' difference just either side of the edge: within a
    # few percent of L's and R's (the shading changes little over a lattice unit)
    ratio = df[shadow].sum(-1) / lr[shadow].sum(-1)
    assert ratio.min() > 0.8 and ratio.max() < 1.2, np.sort(ratio)[:5]


def test_a_long_shadows_edge_is_where_the_renderers_shadow_rays_switch(mi):
    """A point light low over the floor (below the sphere's centre): the shadow is long, and
    the ray epsilon that lifts the renderer's shadow rays off the floor moves its edge by
    several hundredths of a lattice unit at k = 16 -- more than the 0.02 units either side
    of the crossing at which the jump is traced. g's shadow rays start where the renderer's
    do (``Tracer.shadow_ray``); from the hit point itself, the jump was traced on one side
    of the edge and the terms were lost as k grew (k = 16: weighted sum 8.3 % of the sum of
    sizes off, per-pixel 36 %; now 0.02 % and 0.7 %)."""
    text = SHADOW.replace("point 1.5 4 1", "point 4 -0.2 -1")
    direction = (0.0, 0.6, -0.8)
    reference = finite_difference(mi, text, "light1.position", direction, 0.02)
    grad = forward(mi, text, "light1.position", direction, 16 * 16)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.01 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.03


def test_a_tessellated_cones_shadow_edge_keeps_its_jump_as_k_grows(mi):
    """A cone (a smooth mesh of thin faces) casting a shadow: g is the blocking face's edge
    function, and where several thin faces lie between two samples' shadow rays the edge of
    that face that flips is an inner one, not the silhouette; the colors traced either side
    of its crossing were both in the shadow, and the term was lost at every k (k = 16: 3.9 %
    of the sum of sizes, per-pixel 48 %). Such a pair's jump is traced where the renderer's
    shadow rays switch, found by bisection (``Terms.jump``): 0.4 % and 9 % at k = 16, the
    crossing's place and rate still the inner edge's. Now the pair's segment of shadow
    rays is followed across the cone's faces to its silhouette (Visibility.outline),
    whose edge function g then is: measured 0.3 % and 3.1 % (k = 4: 0.9 % and 7.7 %, from
    0.1 % and 30 %). The reference's own spread (h against h / 2, a 4 x 4 finer lattice):
    0.2 % and 2.4 %; the bounds, 1 % and 6 %, lie above both."""
    text = SHADOW.replace("scale 0.8 0.8 0.8\nsphere", "scale 0.6 1.2 0.6\ncone") \
        .replace("point 1.5 4 1", "point 2.5 3 1")
    direction = (0.6, 0.0, -0.8)
    reference = finite_difference(mi, text, "light1.position", direction, 0.05)
    grad = forward(mi, text, "light1.position", direction, 16 * 16)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.01 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.06


# A clear pane (kt 0.8) between a point light and the floor, and an opaque ball above the pane:
# the ball's shadow lies inside the pane's, where the light is blocked at both sides of its edge
# (by the pane first; the ball stops it on one side only)
BALL_ABOVE_A_PANE = """\
eye 0 0.2 5
lookat 0 -0.8 0
fov 40
background 0.2 0.3 0.4
light 1 1 1 point 0 6 0.5
light 0.2 0.2 0.2 ambient
material 0.8 0.8 0.8 0.2 0.8 0 1 0 0 1
translate 0 -1 0
plane
reset
material 0.9 0.9 0.9 0 0 0 1 0 0.8 1
triangle -2 0.5 -2  -2 0.5 2  2 0.5 2
triangle -2 0.5 -2  2 0.5 2  2 0.5 -2
material 0.8 0.3 0.2 0.3 0.7 0 1 0 0 1
translate 0.2 3 0
scale 0.5 0.5 0.5
sphere
"""


@pytest.mark.parametrize("key, direction, h", [
    ("translate2.offset", (1.0, 0.0, 0.0), 0.02),  # the ball moved
    ("light1.position", (0.6, 0.0, -0.8), 0.05),  # the light moved
], ids=["ball", "light"])
def test_a_shadow_inside_a_glass_panes_shadow_matches_finite_differences(mi, key, direction, h):
    """An opaque ball's shadow inside a clear pane's: the pane blocks the light first on both
    sides of the edge, the ball stops it on one (shadows.py: the stopper). Until 2026-12-07
    only the first blocker was a key and the edge had no term: the ball's derivative was zero
    (per-pixel relative L2 100 %), the light's 86 %. At k = 8 (the ball's shadow is a fraction
    of a pixel tall at its tips: at k = 4 a pair there may straddle both its edges) measured:
    weighted sum 1.1 % (ball) and 4.4 % (light) of the sum of sizes off, per-pixel L2 4.3 and
    6.4 %; allowed 8 % and 12 %."""
    reference = finite_difference(mi, BALL_ABOVE_A_PANE, key, direction, h)
    grad = forward(mi, BALL_ABOVE_A_PANE, key, direction, 64)
    w = weights()
    assert abs(np.sum(w * (grad - reference))) < 0.08 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.12


# support_edges.SHADOW under two point lights, over a fine checkered floor: the ball's two
# shadows cross checker lines and each other, so many pairs of samples have a shadow edge
# and a checker line, or two lights' shadow edges, between them
SHADOWS_ON_A_CHECKER = SHADOW.replace(
    "light 1 1 1 point 1.5 4 1\n",
    "light 0.7 0.7 0.7 point 1.5 4 1\nlight 0.6 0.5 0.4 point -1 5 0.5\n").replace(
    "translate 0 -1 0\nplane\n", "translate 0 -1 0\ncheckerboard 0.35\nplane\n")


# the same seen through a clear pane (kt 1, ior 1, no local term) in front of the camera:
# the floor's edges are the specular chain's, at its first bounce
THROUGH_A_PANE = SHADOWS_ON_A_CHECKER + """reset
material 0 0 0 0 0 0 1 0 1 1
triangle -6 -2 4.5  6 -2 4.5  0 8 4.5
"""


@pytest.mark.parametrize("text", [SHADOWS_ON_A_CHECKER, THROUGH_A_PANE],
                         ids=["seen", "through a pane"])
def test_a_pair_across_a_shadow_edge_and_a_checker_line_has_a_term_for_each(mi, text):
    """Pairs.classify: a pair of samples with edges of several kinds, or several lights',
    between them on one surface gets an entry for each, each its own crossing with its own
    jump; so too at a bounce of the specular chain. They were left out until 2026-12-07, a
    share of the shadow's pairs that falls as 1/k but, on a checker this fine, did not at
    k = 8. The ball moved, 32 x 24, k = 8, against the 64 x 64 lattice's finite
    difference, the weighted sum's error (of the sum of sizes) and the per-pixel relative
    L2: seen, 1.8 % and 10.6 % (left out: 5.9 % and 17.9 %; at k = 16 0.1 % and 7.4 %, left
    out 3.0 % and 10.3 %); through the pane, 1.9 % and 11.0 % (left out: 6.1 % and 18.1 %;
    at k = 16 0.3 % and 8.5 %, left out 2.6 % and 10.4 %). Allowed 3 % and 14 %."""
    size = dict(width=32, height=24)
    reference = finite_difference(mi, text, "translate2.offset", (1.0, 0.0, 0.3), 0.02, **size)
    grad = forward(mi, text, "translate2.offset", (1.0, 0.0, 0.3), 64, **size)
    w = weights(24, 32)
    assert abs(np.sum(w * (grad - reference))) < 0.03 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.14


# support_edges.SHADOW over a fine checkered mirror floor (kr 0.8): the ball's outline seen in
# the floor crosses its checker lines, so many pairs of samples have a checker line on the
# floor and the reflected outline between them
A_BALL_IN_A_CHECKERED_MIRROR = SHADOW.replace(
    "translate 0 -1 0\nplane\n", "translate 0 -1 0\ncheckerboard 0.2\nplane\n").replace(
    "material 0.9 0.9 0.8 0.3 0.7 0 1 0 0 1", "material 0.9 0.9 0.8 0.1 0.2 0 1 0.8 0 1")


def test_a_pair_across_an_edge_on_a_mirror_and_an_edge_seen_in_it_has_a_term_for_each(mi):
    """Pairs.classify: a pair of samples with an edge on the surface seen (a checker line, a
    shadow edge) and another seen along the specular chain (an outline in its reflection)
    between them gets an entry for each, as a pair across several edges on one surface does.
    The chain's edge was left out until 2026-12-07. The ball moved, 32 x 24, k = 8, against
    the 64 x 64 lattice's finite difference: the weighted sum's error (of the sum of sizes)
    0.71 % and the per-pixel relative L2 6.6 % (left out: 2.1 % and 8.8 %; at k = 4 0.8 % and
    13.4 %, left out 1.8 % and 18.1 %; at k = 16 0.45 % and 3.7 %, left out 1.1 % and 4.6 %).
    Allowed 1.2 % and 7.5 %, between the two."""
    text = A_BALL_IN_A_CHECKERED_MIRROR
    assert "0.8 0 1" in text and "checkerboard" in text  # (the replacements took)
    size = dict(width=32, height=24)
    key, direction = "translate2.offset", (1.0, 0.0, 0.3)
    reference = finite_difference(mi, text, key, direction, 0.02, **size)
    grad = forward(mi, text, key, direction, 64, **size)
    w = weights(24, 32)
    assert abs(np.sum(w * (grad - reference))) < 0.012 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.075
