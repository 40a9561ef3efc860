"""Adaptive anti-aliasing: which pixels get more samples (decided on the host, detached).

1. A first pass traces every pixel at the render's sampling (one sample: the centre).
2. A pixel that differs from one of its 8 neighbours by more than the threshold (in
   some channel, linear values) is *refined*: it is traced again with a stratified
   n x n set of samples (``LEVELS[0]``, the centres of an n x n grid of strata).
3. A refined pixel whose n x n samples still differ from each other by more than
   ``AGAIN`` times the threshold is refined again with the next level's grid (and so
   on, if there are more levels). The samples of a pixel on an edge always differ;
   ``AGAIN`` keeps the finer grid for edges of high contrast, where it shows.

Each pixel's value is the box-filtered average of its samples at the last level it
reached. The choice depends only on the image's values, so it is the same on every
run; it is a detached decision: gradients flow through the values of the samples,
never through which pixels were refined.
"""

from __future__ import annotations

import numpy as np

LEVELS = (4, 8)  # n of the n x n grids of the successive refinements
AGAIN = 5.0  # a refined pixel is refined again where its samples differ by AGAIN x threshold
BAND = 1024  # rows compared at a time (bounded host memory on huge images)


def contrast_mask(image, threshold):
    """(H, W) bool: the pixels of ``image`` (H, W, 3) that differ from one of their 8
    neighbours by more than ``threshold`` in some channel."""
    height, width = image.shape[:2]
    mask = np.zeros((height, width), bool)
    for top in range(0, height, BAND):
        bottom = min(top + BAND, height)
        lo, hi = max(top - 1, 0), min(bottom + 1, height)
        # edges repeated: a pixel outside the image is its neighbour inside, no difference
        padded = np.pad(image[lo:hi], ((1, 1), (1, 1), (0, 0)), mode="edge")
        r0 = top - lo + 1
        centre = padded[r0:r0 + bottom - top, 1:width + 1]
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                if dy or dx:
                    nb = padded[r0 + dy:r0 + dy + bottom - top, 1 + dx:width + 1 + dx]
                    mask[top:bottom] |= (np.abs(centre - nb) > threshold).any(axis=-1)
    return mask
