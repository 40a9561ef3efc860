"""The boundary terms on random scenes (tests/random_scenes.py, the scenes of
benchmarks/random_edges.py): for each kind of key, the first seed whose finite difference
the benchmark found valid (not flagged: its FD stable at k_FD / 2 and h / 2, no kink; the
seeds are not chosen for their AD), AD in forward mode against the pixel-integrated finite
difference of the 64 x 64 lattice, the weighted sum's error relative to the sum of the terms'
sizes Sum |w FD| (the benchmark's "vs sum abs(wFD)"; a derivative of both signs may nearly
cancel in the sum itself). The tolerance is 3 % (the issue's target for k = 4, there
relative to |FD|); each case's measured error is beside it. No
seed of the benchmark's 50 has a valid FD for mat.ior (eta's FD through glass balls moves
at h / 2 and k_FD / 2), one for rotate.angle (seed 42): those kinds are pinned by their own
modules' scenes too (test_visibility.py; test_tir.py, test_terms.py)."""

from __future__ import annotations

import numpy as np
import pytest

from random_scenes import generate, lattice_difference, step, weights_for
from support_edges import forward

SIZE, FD_K = (32, 24), 64
# (kind, seed, k): measured error at that k, relative to Sum |w FD|
CASES = [
    ("camera.eye", 1, 4),  # 0.3 % (0.5 % before a mesh's outline was followed)
    ("camera.lookat", 1, 4),  # 0.2 %
    # 2.9 %: a mirror ball's shadow seen in it near its rim (4.6 % while the edge's normal
    # was taken from L's and R's neighbours, Terms.slope_across; an xfail until then)
    ("camera.fov", 5, 4),
    ("translate.offset", 6, 8),  # 2.0 % at k = 4, 0.3 % at k = 8
    ("rotate.angle", 42, 16),  # 7.9 % at k = 4, 2.2 % at k = 8, 0.7 % at k = 16
    ("scale.factors", 4, 4),  # 0.4 %
    # 2.8 % (1.9 % with the normal from L's and R's neighbours: the tip of a triangle's
    # shadow seen through a glass box, a wedge thinner than a lattice unit that one row pair
    # meets, docs/gradients.md)
    ("triangle.v", 6, 4),
    ("sphere.center", 1, 4),  # 0.4 %
    # (seed 11, the first valid: a sphere 0.007 above the floor, which the FD's step of
    # 0.066 pushes through it -- a crease the derivative at the key's value has not; 15 %
    # at k = 4, 3.1 % at k = 16, falling to the FD's share of it)
    ("sphere.radius", 33, 4),  # 0.4 %
    ("v.position", 27, 8),  # 12 % at k = 4, 1.4 % at k = 8
    ("light.position", 1, 4),  # 0.55 %
    ("light.direction", 2, 4),  # 1.7 % (1.5 % at the previous stop)
]


def derivative_and_reference(mi, seed, kind, k):
    """(AD in forward mode on the k x k lattice, the 64 x 64 lattice's finite difference) of
    ``kind``'s key of random scene ``seed``, (H, W, 3) each."""
    scene = generate(seed, SIZE)
    key, direction, scale = scene.keys[kind]
    reference = lattice_difference(mi, scene.text, key, direction, step(scale), FD_K, SIZE)
    return forward(mi, scene.text, key, direction, k * k, width=SIZE[0], height=SIZE[1]), \
        reference


def weighted_error(grad, reference):
    """The weighted sum's error relative to the sum of the terms' sizes, Sum |w FD|."""
    w = weights_for(SIZE)
    return abs(np.sum(w * (grad - reference))) / np.sum(np.abs(w * reference))


@pytest.mark.parametrize("kind, seed, k", CASES)
def test_a_random_scenes_key_matches_the_pixel_integrated_finite_difference(mi, kind, seed,
                                                                             k):
    error = weighted_error(*derivative_and_reference(mi, seed, kind, k))
    assert error < 0.03, error


def test_a_diffuse_balls_radius_near_its_terminator_converges_with_k(mi):
    """Seed 25's sphere1, diffuse (kr = kt = 0), its radius at k = 16: where a near side's
    traced ray differs from its sample only in the lights that reach the ball itself (its
    terminator between the rim and the sample), the squeezed-edge rule (Terms.jump) does not
    apply: such an edge is foreshortened, not squeezed, and k resolves it. Measured 0.09 % of
    Sum |w FD| (3.7 / 1.4 / 0.09 % at k = 4 / 8 / 16); 0.83 % when the rule took the
    sample's color there too (6.4 / 2.7 / 0.83 %). The tolerance, 0.4 %, lies between."""
    error = weighted_error(*derivative_and_reference(mi, 25, "sphere.radius", 16))
    assert error < 0.004, error


def test_a_pair_whose_g_is_not_monotone_between_its_samples_adds_no_term(mi):
    """Seed 5's sphere1.center (a mirror ball beside another, over a floor mesh) at k = 16:
    one chain pair (the floor's outline seen in the other ball, near its rim) has g = 2.4
    and -3.3 at its samples, but 5.4 and 36.9 at the two points beside its crossing: g is
    not monotone between the samples (it leaves their range), so neither the crossing nor
    its rate is known at the lattice's resolution, and its term (the derivative of g where
    it is 36.9) put -4.9 into one pixel whose finite difference is +1.3. Such a pair now
    adds no term (Terms.surrogates). Measured per-pixel relative L2 against the finite
    difference: 0.153 (0.896 with the term; 0.176 and 0.111 at k = 8 and 32, 0.201 and
    0.111 before); allowed 0.3."""
    from support_edges import relative_l2

    assert relative_l2(*derivative_and_reference(mi, 5, "sphere.center", 16)) < 0.3


def test_an_outline_seen_in_a_mirror_takes_its_samples_color_where_its_path_past_it_differs(mi):
    """Seed 4's camera.lookat (COMP 575: a glass ellipsoid and a green ball seen in a mirror
    floor, under a spot and a directional light) at k = 8: the ellipsoid's outline seen in the
    floor is a visibility edge along the specular chain, and the rays traced either side of
    its crossing (at the switch, where the renderer's rays change surface) see, on the
    ellipsoid's side, what its rim refracts, squeezed into a band thinner than the lattice.
    Its near side now takes its sample's color where its path past the bounce differs, as an
    outline of the surface seen does (Terms.jump). Measured: 0.06 % of Sum |w FD| (2.1 %
    before; 0.24 % with this rule alone, without the chain entries of pairs across a shadow
    edge on the floor, Pairs.classify); allowed 1 %, the issue's target at k = 8."""
    error = weighted_error(*derivative_and_reference(mi, 4, "camera.lookat", 8))
    assert error < 0.01, error


def test_an_outline_seen_in_a_mirror_ball_takes_its_samples_color_where_its_light_differs(mi):
    """Seed 30's translate.offset (a mirror ball moved, a cone behind it, under a spot and a
    directional light) at k = 32: near the ball's rim it reflects the cone's outline, and
    the cone's terminator with it, squeezed into a band a few lattice units wide. The jump's
    side traced at the outline sees the cone's unlit side; the sample beyond it, the lit
    one. The near side of an outline seen along the chain at bounce d, past a curved
    surface, now takes its sample's color where the lights at bounce d differ too, not only
    the shapes past it (Terms.jump, Terms.curved_before). Measured against this module's
    reference: 0.09 % of Sum |w FD| (3.8 % before, growing with k: 0.4 / 2.1 / 3.8 % at
    k = 8 / 16 / 32; now 2.2 / 1.1 / 0.09 %: worse at k = 8, where one lattice unit holds the
    band); allowed 1 %."""
    error = weighted_error(*derivative_and_reference(mi, 30, "translate.offset", 32))
    assert error < 0.01, error


def test_an_outline_seen_in_a_flat_mirror_keeps_its_sides_color_where_its_light_differs(mi):
    """Seed 28's camera.lookat (a mirror floor reflecting a box, a cone and a cylinder under a
    spotlight) at k = 8: a flat mirror does not squeeze what it reflects, so a terminator near
    an outline seen in it is foreshortened, as on a surface seen directly, and the rule above
    applies only past a curved surface (Terms.curved_before). Measured against this
    module's reference: 2.6 % of Sum |w FD|; 5.6 % with the lights at the outline's bounce
    counted past any mirror; allowed 4 %."""
    error = weighted_error(*derivative_and_reference(mi, 28, "camera.lookat", 8))
    assert error < 0.04, error


def test_an_edges_normal_is_gs_gradient_at_its_crossing(mi):
    """Seed 5's camera.fov (mirror balls over a floor mesh) at k = 16: the balls' shadows
    seen in them crowd towards their rims, where g's gradient changes within a lattice unit.
    The edge's normal, which weighs each pair's term between the rows' and the columns'
    estimates, is g's gradient at the crossing (Terms.slope_across: g either side of it
    across the axis, at the scale the slope along the axis is measured); it was taken from
    centred differences at L's and R's neighbours, two lattice units wide. (A change of fov
    moves each point of the image at a velocity known in closed form: those pairs' rates
    along their axes came out 0.09 times what it gives along the normals so found, at the
    median; 0.99 with g's gradient.) Measured per-pixel relative L2 against the finite difference:
    3.7 % (7.3 % before; 6.3 % and 7.3 % at k = 8); allowed 5.5 %."""
    from support_edges import relative_l2

    assert relative_l2(*derivative_and_reference(mi, 5, "camera.fov", 16)) < 0.055


def test_the_extrapolated_reference_cancels_the_steps_error_at_a_shaded_balls_rim(mi):
    """The extrapolated reference, 2 FD(h / 2) - FD(h) (``random_scenes.compare``): seed 11
    with its point light, its other ball and its floor taken out (the ball, a mirror
    tetrahedron beside it, the directional and ambient lights), the ball's radius. Its colour near the rim changes like the square root of the distance
    to it, so the central difference's error is proportional to its step: Sum w FD = -5.98 /
    -5.83 at h and h / 2, while AD converges to -5.665 (k = 16, 32, 64: -5.671, -5.666,
    -5.665). The benchmark flags the case (its h and h / 2 differ by more than its 0.3 % of
    Sum |w FD|) and counts none of it. Measured at k = 16: 2.8 % of |Sum w FD| off the
    reference at h / 2 and 0.2 % off the extrapolated one; asserted above 2 % and within
    0.5 % (the lattice's own noise in the extrapolation: about twice the h / 2
    reference's)."""
    import types

    from random_scenes import compare

    scene = generate(11, SIZE)
    text = scene.text
    for line in ("light 0.2522 0.4638 0.2568 point", "sphere -1.305 -0.007216 0.407 0.7659",
                 "f 0 1 2\nf 0 2 3"):
        assert line in text
        text = text.replace(line, "#" if not line.startswith("f") else "")
    alone = types.SimpleNamespace(seed=11, text=text, keys=scene.keys)
    case = compare(mi, alone, "sphere.radius", SIZE, 96, [16])
    # (the benchmark flags it: h and h / 2 differ by 0.8 % of Sum |w FD|, the validation's
    # limit 0.3 %)
    assert case.get("flag", "").startswith("FD unstable")
    assert case["errors"][16]["rel"] > 0.02
    assert case["errors_extrapolated"][16]["rel"] < 0.005
