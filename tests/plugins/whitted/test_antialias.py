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


def test_contrast_compares_each_pixels_centre_with_its_four_corners():
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted.antialias import contrast

    def contrast_mask(image, corners, threshold):
        return contrast(image, corners) > threshold

    image, corners = np.zeros((5, 6, 3), np.float32), np.zeros((6, 7, 3), np.float32)
    assert not contrast_mask(image, corners, 0.01).any()
    corners[:, 3:, 1] = 0.5  # a vertical step through column 2 (its right corners: green)
    image[:, 3:, 1] = 0.5
    mask = contrast_mask(image, corners, 0.01)
    assert mask[:, 2].all() and mask.sum() == 5  # only the column the step crosses
    assert not contrast_mask(image, corners, 0.5).any()  # not *more* than the threshold
    dot = np.zeros((6, 7, 3), np.float32)
    dot[2, 2] = 1.0  # one bright corner: the four pixels that share it
    mask = contrast_mask(np.zeros((5, 6, 3), np.float32), dot, 0.1)
    assert mask.sum() == 4 and mask[1:3, 1:3].all()
    centre = np.zeros((5, 6, 3), np.float32)
    centre[4, 5] = 1.0  # a bright centre: that pixel alone (its neighbours' samples agree)
    mask = contrast_mask(centre, np.zeros((6, 7, 3), np.float32), 0.1)
    assert mask.sum() == 1 and mask[4, 5]


def test_banded_comparison_matches_the_whole_image(monkeypatch):
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted import antialias

    rng = np.random.default_rng(3)
    image = (rng.uniform(size=(37, 11, 3)) > 0.9).astype(np.float32)
    corners = (rng.uniform(size=(38, 12, 3)) > 0.9).astype(np.float32)
    whole = antialias.contrast(image, corners)
    monkeypatch.setattr(antialias, "BAND", 4)
    assert np.array_equal(antialias.contrast(image, corners), whole)


def test_a_half_covered_pixel_converges_to_half_and_flat_pixels_stay_at_one_sample(mi):
    from raymitsuba.plugins.whitted import antialias
    from support import load_ray, render_ray

    width, height = 15, 9
    plain = render_ray(HALF, width, height)
    loaded = load_ray(HALF, width, height)
    loaded.integrator.aa = 0.02
    image = loaded.integrator.render_array(loaded.scene)
    centre = width // 2
    # the edge column: half its area covered, and the finest grid (its samples differ by
    # 1, the most) is even: it splits it exactly in two
    np.testing.assert_array_equal(image[:, centre], 0.5)
    # every other pixel is fully covered or not: its value is that of its pixel centre
    others = np.ones(width, bool)
    others[centre] = False
    np.testing.assert_array_equal(image[:, others], plain[:, others])
    np.testing.assert_array_equal(image[:, :centre], 1.0)
    np.testing.assert_array_equal(image[:, centre + 1:], 0.0)
    # refined: the edge column alone (its left corners are covered, its right ones not;
    # the other columns' centre and corners agree, and have 3 refined neighbours at most,
    # none opposite), with the finest grid
    (level,) = loaded.integrator.plan.levels
    assert level.n == antialias.GRIDS[-1][0] and level.n % 2 == 0
    assert np.array_equal(np.sort(level.pixels % width), [centre] * height)


def strip(width, height, cover):
    """A white ambient-lit vertical strip (over a black background) centred on the
    vertical line x = 0, the image's middle corner column at an even ``width``, ``cover``
    of a pixel wide: pixels are 2 * 5 tan(45 deg / 2) / height wide at z = 0, seen from
    the default camera (z = 5, a vertical field of view of 45 degrees)."""
    half = cover * 5 * np.tan(np.radians(22.5)) / height
    return ("light 1 1 1 ambient\n"
            "material 1 1 1  1 0 0 1  0 0 1\n"
            f"triangle {-half} -100 0  {half} -100 0  {half} 100 0\n"
            f"triangle {-half} -100 0  {half} 100 0  {-half} 100 0\n")


def test_a_strip_thinner_than_a_pixel_between_the_centres_is_found_by_the_corners(mi):
    from support import load_ray, render_ray

    from raymitsuba.plugins.whitted import antialias, camera

    width, height = 16, 9
    # two thirds of a pixel wide, on the corners of column 8: x in [-1/3, 1/3] pixel, which
    # holds the corners' samples (moved by at most CORNER_JITTER) and not the centres
    assert camera.CORNER_JITTER < 1 / 3
    scene = strip(width, height, 2 / 3)
    assert not render_ray(scene, width, height).any()  # the centres miss it: all black
    loaded = load_ray(scene, width, height)
    loaded.integrator.aa = 0.02
    image = loaded.integrator.render_array(loaded.scene)
    # closed form: the strip covers a third of each of the two pixels on either side of the
    # corner column; an n x n grid with n a multiple of 6 splits that exactly (of a 6 x 6
    # grid's columns of samples, at 1/12, 3/12, 5/12 of a pixel from the line, two are
    # inside), so the average is 1/3 up to float32 rounding (the sum of n^2 samples times
    # 1 / n^2: a few ulps)
    (level,) = loaded.integrator.plan.levels
    assert level.n % 6 == 0 and np.array_equal(np.unique(level.pixels % width),
                                               [width // 2 - 1, width // 2])
    middle = width // 2
    np.testing.assert_allclose(image[:, middle - 1:middle + 1], 1 / 3, rtol=1e-6)
    others = np.ones(width, bool)
    others[middle - 1:middle + 1] = False
    np.testing.assert_array_equal(image[:, others], 0.0)


def test_a_pixel_between_two_refined_ones_is_refined():
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted import antialias

    mask = np.zeros((5, 7), bool)
    mask[:, 3] = True  # an edge's column: no pixel beside it has refined opposite neighbours
    assert not (antialias.between(mask) & ~mask).any()
    staircase = np.eye(6, dtype=bool) | np.eye(6, k=1, dtype=bool)  # a diagonal edge
    assert not (antialias.between(staircase) & ~staircase).any()
    mask[2, 3] = False  # a gap in a thin line: above and below it are refined
    assert np.array_equal(np.argwhere(antialias.between(mask) & ~mask), [[2, 3]])
    dots = np.zeros((5, 7), bool)
    dots[1, 1] = dots[3, 3] = True  # across a diagonal
    assert np.array_equal(np.argwhere(antialias.between(dots)), [[2, 2]])
    corner = np.ones((3, 3), bool)
    corner[0, 0] = False  # at the border: its opposite neighbours are outside the image
    assert not antialias.between(corner)[0, 0]


def test_a_probe_that_sees_faint_detail_between_two_refined_pixels_gives_its_value(mi):
    """A pixel refined for its neighbours whose probe's samples differ by a contrast that
    asks for a grid no finer than the probe's (GRIDS) takes the probe's value: a faint
    piece (0.1, five times the threshold 0.02: a 4 x 4 grid) inside a gap of a thin strip,
    missed by the gap row's centres and corners, is seen by some of the probe's samples.
    (It used to get the finest grid.)"""
    from raymitsuba.plugins.whitted import antialias, camera
    from support import load_ray

    width, height = 16, 9
    side = 2 * 5 * np.tan(np.radians(22.5)) / height  # a pixel's side at z = 0 (see strip)
    half = side / 3  # a strip two thirds of a pixel wide on the middle corner column

    def rect(y0, y1):
        return (f"triangle {-half} {y0} 0  {half} {y0} 0  {half} {y1} 0\n"
                f"triangle {-half} {y0} 0  {half} {y1} 0  {-half} {y1} 0\n")

    # the gap: the middle row (y in [-side / 2, side / 2]); the strip stops a quarter of a
    # pixel short of its corners (moved by at most CORNER_JITTER), and the piece lies 0.3 to
    # 0.45 of a pixel from its top, across the third of each of the two pixels beside the
    # middle column that is nearer to it
    assert camera.CORNER_JITTER < 0.25
    scene = ("light 0.1 0.1 0.1 ambient\nmaterial 1 1 1  1 0 0 1  0 0 1\n"
             + rect(0.75 * side, 100) + rect(-100, -0.75 * side)
             + rect(0.05 * side, 0.2 * side))
    loaded = load_ray(scene, width, height)
    loaded.integrator.aa = 0.02
    image = loaded.integrator.render_array(loaded.scene)
    middle, gap = width // 2, height // 2
    gap_pixels = gap * width + np.array([middle - 1, middle])
    n = antialias.PROBE
    probed = {int(pixel) for level in loaded.integrator.plan.levels
              if level.n == n for pixel in level.pixels}
    assert set(gap_pixels.tolist()) <= probed

    def on_the_piece(n):
        """The share of an n x n grid's samples (at (i + 1/2) / n) on the piece: (columns
        within 1/3 of the middle line, in either pixel) x (rows 0.3 to 0.45 from the top;
        the same from the bottom, the grid being symmetric)."""
        offsets = (np.arange(n) + 0.5) / n
        return np.sum(offsets >= 2 / 3) * np.sum((offsets >= 0.3) & (offsets <= 0.45)) / n**2

    assert on_the_piece(n) > 0 and on_the_piece(n) != on_the_piece(antialias.GRIDS[-1][0])
    np.testing.assert_allclose(image[gap, middle - 1:middle + 1], 0.1 * on_the_piece(n),
                               rtol=1e-5)


def test_the_grid_follows_the_contrast():
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted.antialias import GRIDS, grid_of

    # just above each entry's contrast (in multiples of the threshold 0.02): that entry
    spread = np.array([max(times, 1.0) * 0.02 * 1.01 for _, times in GRIDS], np.float32)
    assert list(grid_of(spread, 0.02)) == list(range(len(GRIDS)))
    assert grid_of(np.float32([GRIDS[-1][1] * 0.02 * 0.99]), 0.02)[0] == len(GRIDS) - 2
    sides = [n for n, _ in GRIDS]
    assert sides == sorted(sides)  # finer with the contrast


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


# The glass scene's sphere fills the frame, and the spot scene's board is filtered: one path
# throughout, which anti-aliasing does not refine (signature.py). A triangle in front gives
# each pixels to refine, along edges that neither key moves: dark and opaque in front of the
# glass, clear (kt 1, ior 1: no shadow) over the board.
IN_FRONT = {"glass": "material 0.2 0.2 0.2  1 0 0 1  0 0 1\n"
                     "triangle -1 -1 2  0.9 -1 2  -1 0.9 2\n",
            "spot": "material 0.9 0.2 0.2  0.3 0.6 0 1  0 1 1\n"
                    "triangle -1 0.3 -1  1 0.3 -0.5  -0.5 0.3 1\n"}


@pytest.mark.parametrize("scene,key", [("phong", "mat1.color"), ("glass", "mat2.ior"),
                                       ("spot", "light1.direction")])
def test_gradients_with_antialiasing_match_finite_differences(mi, scene, key):
    import raymitsuba

    loaded = raymitsuba.load(tg.SCENES[scene] + IN_FRONT.get(scene, ""), width=tg.SIZE,
                             height=tg.SIZE, aa=0.02)
    loaded.integrator.chunk_pixels = 11
    finite, reverse, forward = tg.derivatives(mi, loaded, key, tg.seed_of(scene, key, "aa"),
                                              same_refinement=True)
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
    # (at the scene's rate, measured by its first render and kept for the next)
    rate = integrator.stats.estimate.rays_per_second
    integrator.time_limit = 1.5 * plain.integrator.estimated_rays / rate
    with pytest.raises(guards.BudgetError, match="--time-limit"):
        integrator.render_array(loaded.scene)



RECEDING = """\
eye 0 1.2 4
lookat 0 0.6 -10
fov 45
background 0.4 0.6 0.9
light 1 1 1 directional -1 -2 -1
light 0.2 0.2 0.2 ambient
material 0.9 0.9 0.9  0.2 0.8 0 1  0 0 1
checkerboard 0.5
plane
"""


def test_a_receding_checkerboard_is_averaged_over_each_samples_footprint(mi):
    """A checkered floor to the horizon, where squares shrink below a pixel: with --aa each
    camera sample sees the board averaged over its footprint (checker_filtered, the
    footprint from ray differentials), so the image is closer to a 4096-sample render than
    uniform 256 samples are (measured: mean error 0.47/255 against 1.21/255; 99.8 % of the
    pixels within 8/255 against 97.3 %)."""
    import raymitsuba
    from support import render_ray

    width, height = 64, 48
    q = lambda image: np.clip(image, 0.0, 1.0)  # noqa: E731 (as an 8-bit image would)
    reference = q(render_ray(RECEDING, width, height, spp=4096))
    aa = q(np.array(raymitsuba.render(raymitsuba.load(RECEDING, width=width, height=height,
                                                         aa=0.02))))
    dense = q(render_ray(RECEDING, width, height, spp=256))
    error, dense_error = np.abs(aa - reference), np.abs(dense - reference)
    assert error.mean() < 0.5 * dense_error.mean()
    assert (error.max(axis=-1) <= 8 / 255).mean() >= 0.995


def test_bands_and_chunks_of_a_scene_of_mirrors_glass_and_a_board_are_the_whole_image(mi):
    """Path signatures (a pixel's decision reads its neighbours' centres: MARGIN rows) and
    footprints carried through mirrors and glass: bands of 7 rows and chunks of 37 pixels
    give the whole image's values, bit for bit."""
    import raymitsuba

    loaded = raymitsuba.load("scenes/aa_showcase.ray", width=64, height=48, aa=0.02)
    integrator = loaded.integrator
    whole = integrator.render_array(loaded.scene)
    assert integrator.plan.levels  # (refined: not vacuous)
    bands = [integrator.render_array(loaded.scene, rows=(top, min(top + 7, 48)))
             for top in range(0, 48, 7)]
    assert np.array_equal(np.concatenate(bands), whole)
    integrator.chunk_pixels = 37
    assert np.array_equal(integrator.render_array(loaded.scene), whole)


# Levels of every grid (antialias.GRIDS), a few pixels each, spread over a 29 x 17 image
GRADED = ((2, [3, 40, 41]), (3, [100, 7]), (6, [250]), (4, [0, 492]), (8, [77]), (12, [300, 301]))


def graded_levels(coherent):
    from raymitsuba.plugins.whitted.antialias import Level
    from raymitsuba.plugins.whitted.chunks import fills_packets

    return [Level(np.array(pixels, np.uint32), n) for n, pixels in GRADED
            if fills_packets(n * n) == coherent]


def test_graded_rays_are_each_grids_camera_rays_bit_for_bit(mi):
    from raymitsuba.plugins.whitted.camera import camera_rays, graded_rays
    import raymitsuba

    loaded = raymitsuba.load("scenes/whitted.ray", width=29, height=17)
    sensor = loaded.scene.sensors()[0]
    pixels = np.array([p for _, level in GRADED for p in level], np.uint32)
    sides = np.array([n for n, level in GRADED for _ in level], np.uint32)
    for footprint in (False, True):
        rays = graded_rays(sensor, 29, 17, pixels, sides, footprint)
        want = [camera_rays(sensor, 29, 17, int(n) ** 2, pixels=mi.UInt32([p]),
                            footprint=footprint) for p, n in zip(pixels, sides)]
        fields = ["o", "d"] + (["o_x", "o_y", "d_x", "d_y"] if footprint else [])
        for field in fields:
            got = np.array(getattr(rays, field))
            assert np.array_equal(got, np.concatenate(
                [np.array(getattr(ray, field)) for ray in want], axis=-1)), field


def test_a_graded_job_counts_each_pixels_own_samples():
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted.antialias import Graded

    job = Graded(29, 17, graded_levels(coherent=False))  # 2 x 2 (3 pixels), 3 x 3 (2), 6 x 6
    assert job.count == 6 and not job.coherent
    assert job.samples(0, 6) == 3 * 4 + 2 * 9 + 36 and job.samples(2, 2) == 4 + 9
    assert job.fitting(0, 12) == 3 and job.fitting(0, 20) == 3  # whole pixels only ...
    assert job.fitting(3, 5) == 1  # ... yet at least one, larger than the lanes
    assert job.packet_margins(0, 6) == (0, 0)
    assert Graded(29, 17, graded_levels(coherent=True)).coherent


def test_levels_that_would_trace_in_packets_and_levels_that_would_not_are_refused_together():
    from raymitsuba.backend import mitsuba

    mitsuba()
    from raymitsuba.plugins.whitted.antialias import Graded, Level

    with pytest.raises(ValueError, match="whole packets"):
        Graded(29, 17, [Level(np.uint32([1]), 4), Level(np.uint32([2]), 3)])


@pytest.mark.parametrize("coherent", [True, False])
@pytest.mark.parametrize("cut", [dict(max_pixels=2), dict(lanes=50)])
def test_a_graded_job_gives_each_level_its_own_jobs_values_bit_for_bit(mi, coherent, cut):
    """Traced together (and cut into chunks, across the levels: of 2 pixels, or of at most
    50 camera rays, refine's cap), each level's pixels get the values their own job
    (chunks.Job) gives them."""
    import raymitsuba
    from raymitsuba.plugins.whitted.antialias import Graded, trace_graded
    from raymitsuba.plugins.whitted.camera import pixel_means
    from raymitsuba.plugins.whitted.chunks import Chunker, Job

    loaded = raymitsuba.load("scenes/benchmark_glass.ray", width=29, height=17)
    integrator, scene = loaded.integrator, loaded.scene
    chunker = Chunker(integrator.tracer, scene, scene.sensors()[0], integrator.memory_budget,
                      max_pixels=cut.get("max_pixels"))
    levels = graded_levels(coherent)
    values = np.full((29 * 17, 3), np.nan, np.float32)  # (a pixel not written stays NaN)
    trace_graded(chunker, Graded(29, 17, levels), values, lanes=cut.get("lanes"))
    chunks = chunker.chunks_done
    for level in levels:
        spp = level.n * level.n
        want = []
        chunker.run(Job(29, 17, spp, pixels=level.pixels),
                    lambda start, count, color: want.append(
                        np.array(pixel_means(color, count, spp)).T.reshape(-1, 3)))
        assert np.array_equal(values[level.pixels], np.concatenate(want)), level.n
    assert chunks >= 2  # (it was cut)
