"""Adaptive anti-aliasing (plugins/whitted/antialias.py, driven by plugins/whitted/integrator.py): which pixels
are refined, what a refined pixel converges to, determinism, gradients."""

from __future__ import annotations

import numpy as np
import pytest

import test_gradients as tg

# A white ambient-lit triangle covering everything left of x = 0 (seen from z = 5), over a
# black background: at an odd width, x = 0 runs down the middle of the centre column.
HALF = ("light 1 1 1 ambient\n"
        "material 1 1 1  1 0 0 1  0 0 1\n"
        "triangle -100 -100 0  0 -100 0  0 100 0\n")


@pytest.fixture(scope="module")
def mi():
    from raymitsuba.backend import mitsuba

    return mitsuba()


def test_contrast_mask_marks_both_sides_of_a_step_and_nothing_in_flat_regions():
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted.antialias import contrast_mask

    image = np.zeros((5, 6, 3), np.float32)
    assert not contrast_mask(image, 0.01).any()
    image[:, 3:, 1] = 0.5  # a vertical step between columns 2 and 3 (green only)
    mask = contrast_mask(image, 0.01)
    assert mask[:, 2:4].all() and not mask[:, :2].any() and not mask[:, 4:].any()
    assert not contrast_mask(image, 0.5).any()  # not *more* than the threshold
    spot = np.zeros((5, 6, 3), np.float32)
    spot[2, 2] = 1.0  # one bright pixel: itself and its 8 neighbours
    mask = contrast_mask(spot, 0.1)
    assert mask.sum() == 9 and mask[1:4, 1:4].all()
    corner = np.zeros((5, 6, 3), np.float32)
    corner[0, 0] = 1.0  # at the border: no neighbour outside the image counts
    assert contrast_mask(corner, 0.1).sum() == 4


def test_banded_comparison_matches_the_whole_image(monkeypatch):
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted import antialias

    rng = np.random.default_rng(3)
    image = (rng.uniform(size=(37, 11, 3)) > 0.9).astype(np.float32)
    whole = antialias.contrast_mask(image, 0.5)
    monkeypatch.setattr(antialias, "BAND", 4)
    assert np.array_equal(antialias.contrast_mask(image, 0.5), whole)


def test_a_half_covered_pixel_converges_to_half_and_flat_pixels_stay_at_one_sample(mi):
    from support import load_ray, render_ray

    width, height = 15, 9
    plain = render_ray(HALF, width, height)
    loaded = load_ray(HALF, width, height)
    loaded.integrator.aa = 0.02
    image = loaded.integrator.render_array(loaded.scene)
    centre = width // 2
    # the edge column: half its area covered, and 4x4 / 8x8 grids split it exactly in two
    np.testing.assert_array_equal(image[:, centre], 0.5)
    # every other pixel is fully covered or not: its value is that of its pixel centre
    others = np.ones(width, bool)
    others[centre] = False
    np.testing.assert_array_equal(image[:, others], plain[:, others])
    np.testing.assert_array_equal(image[:, :centre], 1.0)
    np.testing.assert_array_equal(image[:, centre + 1:], 0.0)
    # refined: the two columns on either side of the step the first pass saw; again (8x8):
    # only the edge column, whose 4x4 samples still differ
    (first, n1), (second, n2) = loaded.integrator.plan.levels
    columns = np.unique(first % width).astype(int)
    assert len(first) == 2 * height and centre in columns and len(columns) == 2
    assert abs(columns[0] - columns[1]) == 1
    assert (n1, n2) == (4, 8) and np.array_equal(np.sort(second % width), [centre] * height)


def test_antialiasing_is_deterministic_and_independent_of_the_chunks(mi):
    import raymitsuba

    loaded = raymitsuba.load("scenes/whitted.ray", width=40, height=30, aa=0.02)
    first = loaded.integrator.render_array(loaded.scene)
    assert np.array_equal(loaded.integrator.render_array(loaded.scene), first)
    loaded.integrator.chunk_pixels = 13
    assert np.array_equal(loaded.integrator.render_array(loaded.scene), first)
    assert np.array_equal(np.array(raymitsuba.render(loaded)), first)  # the API's render
    # and it is not the plain image: edges were refined
    plain = raymitsuba.load("scenes/whitted.ray", width=40, height=30)
    assert not np.array_equal(plain.integrator.render_array(plain.scene), first)


@pytest.mark.parametrize("scene,key", [("phong", "mat1.color"), ("glass", "mat2.ior"),
                                       ("spot", "light1.direction")])
def test_gradients_with_antialiasing_match_finite_differences(mi, scene, key):
    import raymitsuba

    loaded = raymitsuba.load(tg.SCENES[scene], width=tg.SIZE, height=tg.SIZE, aa=0.02)
    loaded.integrator.chunk_pixels = 11
    finite, reverse, forward = tg.derivatives(mi, loaded, key, tg.seed_of(scene, key, "aa"))
    assert loaded.integrator.plan.levels, "nothing was refined: the test would be vacuous"
    assert abs(finite) > 0.1
    assert abs(reverse - finite) <= tg.REL_FD * abs(finite), (finite, reverse)
    assert abs(forward - finite) <= tg.REL_FD * abs(finite), (finite, forward)
    assert abs(reverse - forward) <= tg.REL_AD * abs(forward), (reverse, forward)


def test_the_refinement_counts_in_the_time_guard(mi):
    import raymitsuba
    from raymitsuba.plugins.whitted import guards

    loaded = raymitsuba.load("scenes/whitted.ray", width=64, height=48, aa=0.02)
    integrator = loaded.integrator
    integrator.render_array(loaded.scene)
    with_refinement = integrator.estimated_rays
    plain = raymitsuba.load("scenes/whitted.ray", width=64, height=48)
    plain.integrator.render_array(plain.scene)
    assert with_refinement > 2 * plain.integrator.estimated_rays
    # a limit between the two: the first pass is allowed, the refinement refused
    integrator.time_limit = 1.5 * plain.integrator.estimated_rays / guards.RAYS_PER_SECOND
    with pytest.raises(guards.BudgetError, match="--time-limit"):
        integrator.render_array(loaded.scene)
