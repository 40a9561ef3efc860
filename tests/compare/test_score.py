"""Tests of raymitsuba/compare/score.py: the figures of known images, counted by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from raymitsuba.compare.score import CompareError, TILES, score


def gradient(width=40, height=30):
    """A smooth test image with every value inside (0, 1)."""
    y, x = np.mgrid[0:height, 0:width]
    return np.stack([0.1 + 0.8 * x / width, 0.1 + 0.8 * y / height,
                     np.full(x.shape, 0.5)], -1).astype(np.float32)


def disc(width=40, height=30, cx=20.3, cy=14.6, r=9.2):
    """A white disc on black: a sharp edge all round."""
    y, x = np.mgrid[0:height, 0:width] + 0.5
    inside = (x - cx) ** 2 + (y - cy) ** 2 < r * r
    return np.repeat(inside[..., None], 3, -1).astype(np.float32)


def test_an_image_against_itself_scores_100_percent():
    image = gradient()
    s = score(image, image)
    assert (s.match, s.within_2, s.within_8, s.failed, s.left_out) == (100, 100, 100, 0, 0)
    assert s.mean_abs == 0 and math.isinf(s.psnr) and s.worst is None


def test_n_changed_pixels_are_counted_exactly():
    image = gradient()
    changed = image.copy()
    rng = np.random.default_rng(1)
    picks = rng.choice(image.shape[0] * image.shape[1], 12, replace=False)
    beyond, within = picks[:7], picks[7:]
    flat = changed.reshape(-1, 3)
    flat[beyond, 1] += 3 / 255  # beyond 2/255, within 8/255
    flat[within, 0] -= 2 / 255  # exactly 2/255: within
    s = score(changed, image)
    n = image.shape[0] * image.shape[1]
    assert s.failed == 7 and s.scored == n
    assert s.match == pytest.approx(100 * (n - 7) / n, abs=1e-12)
    assert s.within_2 == s.match and s.within_8 == 100
    # mean over every channel of every pixel: 7 x 3/255 + 5 x 2/255 (float32 rounding: 1e-9)
    assert s.mean_abs == pytest.approx((7 * 3 + 5 * 2) / 255 / (3 * n), rel=1e-5)
    mse = (7 * 9 + 5 * 4) / 255 ** 2 / (3 * n)
    assert s.psnr == pytest.approx(10 * math.log10(1 / mse), rel=1e-5)


def test_values_are_clamped_to_the_unit_range_before_comparing():
    image = gradient()
    brighter = image.copy()
    brighter[0, 0] = 1.0
    over = brighter.copy()
    over[0, 0] = 7.5  # what an 8-bit file of it would hold: 1
    assert score(over, brighter).match == 100


def test_an_image_shifted_by_a_pixel_fails_exactly_at_the_edges():
    image = disc()
    shifted = np.roll(image, 1, axis=1)
    edges = (image[..., 0] != shifted[..., 0])  # the pixels the shift changes: 0 <-> 1
    s = score(shifted, image)
    assert s.failed == edges.sum() > 0
    assert s.within_8 == s.match == pytest.approx(100 * (1 - edges.mean()))


def test_left_out_pixels_enter_no_figure():
    image = disc()
    shifted = np.roll(image, 1, axis=1)
    edges = image[..., 0] != shifted[..., 0]
    s = score(shifted, image, scored=~edges)
    assert (s.match, s.failed, s.left_out, s.scored) == (100, 0, edges.sum(), (~edges).sum())


def test_the_worst_region_is_the_tile_with_most_failures():
    image = gradient(64, 48)
    changed = image.copy()
    changed[30:33, 50:53] = 0  # 9 pixels in the tile x 48..55, y 30..35 (8 x 8 grid)
    changed[2, 2] = 0  # one elsewhere
    s = score(changed, image)
    assert TILES == 8 and s.worst == (48, 30, 56, 36) and s.worst_count == 9


def test_images_of_different_sizes_are_refused():
    with pytest.raises(CompareError, match="sizes differ: image 40x30, reference 30x40"):
        score(gradient(40, 30), gradient(30, 40))
    with pytest.raises(CompareError, match="RGB"):
        score(np.zeros((4, 4)), np.zeros((4, 4)))
