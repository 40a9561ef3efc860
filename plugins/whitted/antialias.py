"""Adaptive anti-aliasing (the integrator's ``aa`` > 0): which pixels get more samples
(decided on the host, detached), and how they are traced.

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
never through which pixels were refined. :func:`refine` runs steps 2 and 3 after the
integrator's first pass and returns the :class:`Plan`, the primal render's decisions;
the adjoint passes re-trace each pixel with the samples its value came from
(:meth:`Plan.adjoint_jobs`).

When to use which: ``spp`` 1 (the default) is the exact pixel-centre image that numeric
tests and fits against such a target want; ``aa`` (e.g. 0.02) gives clean edges at a
fraction of the cost of uniform supersampling, for images to look at; uniform ``spp``
n^2 treats every pixel alike (a fit to a supersampled target, or a reference).
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import numpy as np

from .camera import pixel_means, pixel_spread
from .chunks import Job

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


class Level(NamedTuple):
    """One refinement: ``pixels`` traced again with an ``n`` x ``n`` grid of samples."""

    pixels: np.ndarray  # uint32: the image's pixel numbers, in the order traced
    n: int  # the grid's side (LEVELS)


class Plan:
    """The anti-aliasing decisions of a primal render: its refinement ``levels``, in order,
    for the image of ``sensor`` (width x height, ``spp`` samples per pixel in the first
    pass) at the contrast ``threshold``."""

    def __init__(self, sensor, width, height, spp, threshold, levels):
        # What the plan is of. The sensor, held, stands for the scene: it cannot be freed and
        # another take its place meanwhile; the scene itself owns the integrator that keeps
        # this plan, so holding it would make a cycle that keeps every scene alive.
        self.sensor = sensor
        self.width, self.height = width, height  # the image
        self.spp = spp  # the first pass's samples per pixel
        self.threshold = threshold  # the contrast that marks a pixel for refinement
        self.levels = levels  # the Levels, in order: a pixel's value is from its last one

    def is_for(self, sensor, width, height, spp, threshold):
        """Whether this is the plan of a render of these."""
        return (self.sensor is sensor and (self.width, self.height, self.spp, self.threshold)
                == (width, height, spp, threshold))

    def adjoint_jobs(self):
        """The jobs that re-trace every pixel with the samples its value came from: a list of
        (job, weights), weights (float32 by pixel) 1 on the pixels whose value is the job's
        and 0 on the others, or None: every pixel of the job."""
        size = self.width * self.height
        if not self.levels:
            return [(Job(self.width, self.height, self.spp), None)]
        refined = np.zeros(size, bool)
        refined[self.levels[0].pixels] = True
        jobs = [(Job(self.width, self.height, self.spp), (~refined).astype(np.float32))]
        for k, level in enumerate(self.levels):
            later = np.zeros(size, bool)  # the level's pixels refined again
            if k + 1 < len(self.levels):
                later[self.levels[k + 1].pixels] = True
            final = level.pixels[~later[level.pixels]]
            if len(final):
                jobs.append((Job(self.width, self.height, level.n * level.n, pixels=final), None))
        return jobs


def refine(image, spp, threshold, chunker, estimate, height=None, first_row=0, rows=None):
    """Refine the first pass ``image`` ((H, W, 3) float32, C-contiguous, traced at ``spp``
    samples per pixel) at the contrast ``threshold``: every level's pixels are traced by
    ``chunker`` (each level first admitted by the guards' ``estimate``, its pixels being
    known) and their values written into ``image``, in place. Returns the :class:`Plan`.

    A band: ``image`` holds the rows ``first_row`` .. ``first_row`` + H - 1 of an image of
    ``height`` rows (default: H, the whole image), and only the pixels of ``rows`` (top,
    bottom) are refined (default: all of them). A band's rows need their neighbours' rows
    above and below (where the image has them) for the contrast test: the decisions, and
    so the values, are then those of the whole image's render."""
    band_height, width = image.shape[:2]
    height = height or band_height
    top, bottom = rows or (first_row, first_row + band_height)
    values = image.reshape(-1, 3)
    mask = contrast_mask(image, threshold)[top - first_row:bottom - first_row]
    candidates = (np.flatnonzero(mask) + top * width).astype(np.uint32)
    offset = first_row * width  # the pixel number of values[0]
    levels = []
    for n in LEVELS:
        if len(candidates) == 0:
            break
        estimate.admit(len(candidates), n * n)
        spread = trace_level(chunker, Job(width, height, n * n, pixels=candidates), values,
                             offset)
        levels.append(Level(candidates, n))
        candidates = candidates[spread > AGAIN * threshold]
    return Plan(chunker.sensor, width, height, spp, threshold, levels)


def trace_level(chunker, job, values, offset=0):
    """Trace ``job``'s pixels through ``chunker``, each one's box-filtered value written into
    ``values`` ((H * W, 3), by pixel number less ``offset``); returns the spread of each pixel's samples
    (their largest difference in one channel; float32, in job order)."""
    spread = np.empty(job.count, np.float32)

    def visit(start, count, color):
        means, spreads = pixel_means(color, count, job.spp), pixel_spread(color, count, job.spp)
        values[job.pixels[start:start + count] - offset] = dr.ravel(means).numpy().reshape(-1, 3)
        spread[start:start + count] = spreads.numpy()

    chunker.run(job, visit)
    return spread
