"""Adaptive anti-aliasing (the integrator's ``aa`` > 0): which pixels get more samples
(decided on the host, detached), and how they are traced.

1. A first pass traces every pixel at the render's sampling (one sample: the centre),
   the plain image's pass, and one sample at each pixel *corner*: the (W + 1) x (H + 1)
   lattice of the pixels' corners (``camera.corner_rays``), each corner shared by the
   four pixels around it. A pixel's five samples (centre and four corners) cost about two
   samples per pixel, and a straight edge that crosses a pixel always separates two of its
   corners, however little of it it covers.
2. A pixel whose five samples differ by more than the threshold (in some channel, linear
   values) is *refined*: it is traced again with a stratified n x n set of samples
   (``LEVELS[0]``, the centres of an n x n grid of strata). A detail thinner than a pixel
   that the centres miss is found where it crosses a corner.
3. A refined pixel whose n x n samples still differ from each other by more than
   ``AGAIN`` times the threshold is refined again with the next level's grid (and so
   on, if there are more levels). The samples of a pixel on an edge always differ;
   ``AGAIN`` keeps the finer grid for edges of high contrast, where it shows.

Each pixel's value is the box-filtered average of its samples at the last level it
reached (the corners only decide). The choice of a pixel depends only on its own samples'
values, so it is the same on every run and however the image is cut into bands of rows; it
is a detached decision: gradients flow through the values of the samples, never through
which pixels were refined. :func:`refine` runs the corners and steps 2 and 3 after the
integrator's first pass and returns the :class:`Plan`, the primal render's decisions;
the adjoint passes re-trace each pixel with the samples its value came from
(:meth:`Plan.adjoint_jobs`).

When to use which: ``spp`` 1 (the default) is the exact pixel-centre image that numeric
tests and fits against such a target want; ``aa`` (the command line's ``--aa`` alone:
the threshold ``raymitsuba.options`` gives it) gives clean edges at a fraction of the cost
of uniform supersampling, for images to look at; uniform ``spp`` n^2 treats every pixel
alike (a fit to a supersampled target, or a reference).
"""

from __future__ import annotations

from typing import NamedTuple

import drjit as dr
import numpy as np

from .camera import corner_rays, pixel_means, pixel_spread
from .chunks import Job

LEVELS = (4, 8)  # n of the n x n grids of the successive refinements
AGAIN = 5.0  # a refined pixel is refined again where its samples differ by AGAIN x threshold
BAND = 1024  # rows compared at a time (bounded host memory on huge images)


def contrast_mask(image, corners, threshold):
    """(H, W) bool: the pixels of ``image`` (H, W, 3) whose centre and four corners (of
    ``corners``, (H + 1, W + 1, 3)) differ by more than ``threshold`` in some channel."""
    height, width = image.shape[:2]
    mask = np.zeros((height, width), bool)
    for top in range(0, height, BAND):
        bottom = min(top + BAND, height)
        low = high = image[top:bottom]
        for dy in (0, 1):
            for dx in (0, 1):
                corner = corners[top + dy:bottom + dy, dx:width + dx]
                low, high = np.minimum(low, corner), np.maximum(high, corner)
        mask[top:bottom] = ((high - low) > threshold).any(axis=-1)
    return mask


class CornerJob:
    """The pixel corners of rows ``top`` .. ``bottom`` (both included: a band of pixel rows
    top .. bottom - 1 has bottom - top + 1 rows of corners) of a ``width`` x ``height``
    image, one sample each: a job for ``chunks.Chunker``."""

    spp = 1

    def __init__(self, width, height, top, bottom):
        self.width, self.height = width, height  # the image
        self.first = top * (width + 1)  # the first corner's number
        self.count = (bottom - top + 1) * (width + 1)  # how many corners

    def rays(self, sensor, start, count):
        return corner_rays(sensor, self.width, self.height, self.first + start, count)


def trace_corners(chunker, width, height, top, bottom):
    """The values ((bottom - top + 1, W + 1, 3) float32) of the corners of the pixel rows
    ``top`` .. ``bottom`` - 1, traced through ``chunker``."""
    job = CornerJob(width, height, top, bottom)
    values = np.empty((job.count, 3), np.float32)

    def visit(start, count, color):
        values[start:start + count] = dr.ravel(color).numpy().reshape(-1, 3)

    chunker.run(job, visit)
    return values.reshape(bottom - top + 1, width + 1, 3)


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


def refine(image, spp, threshold, chunker, estimate, height=None, first_row=0):
    """Refine the first pass ``image`` ((H, W, 3) float32, C-contiguous, traced at ``spp``
    samples per pixel) at the contrast ``threshold``: the pixel corners, then every level's
    pixels are traced by ``chunker`` (each job first admitted by the guards' ``estimate``)
    and the levels' values written into ``image``, in place. Returns the :class:`Plan`.

    A band: ``image`` holds the rows ``first_row`` .. ``first_row`` + H - 1 of an image of
    ``height`` rows (default: H, the whole image); each pixel's decision depends on its own
    centre and corners only, so the band's values are those rows of the whole image's."""
    band_height, width = image.shape[:2]
    height = height or band_height
    estimate.admit((width + 1) * (band_height + 1), 1)  # the corners
    corners = trace_corners(chunker, width, height, first_row, first_row + band_height)
    values = image.reshape(-1, 3)
    candidates = (np.flatnonzero(contrast_mask(image, corners, threshold))
                  + first_row * width).astype(np.uint32)
    del corners
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
