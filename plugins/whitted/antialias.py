"""Adaptive anti-aliasing (the integrator's ``aa`` > 0): which pixels get more samples
(decided on the host, detached), and how they are traced.

0. *One path throughout* (``signature.py``, one sample per pixel): the first pass and the
   corners (step 1) also give each sample's path signature, a hash of the surfaces its ray tree
   hit, which lights lit them through which blockers, and its bounces. A pixel whose
   centre, four corners and four neighbours' centres share one signature differs from
   sample to sample only smoothly, and its first pass's value is its average (its
   checkerboards averaged over the whole pixel's footprint, step 5): it is not refined
   for its contrast. Where its footprint on a checkerboard is distorted by perspective
   past what the filter takes as first order, or holds a corner of the board
   (``checkerboard.residual_distortion``, ``filtered_board``), it is traced with the
   2 x 2 to 4 x 4 grid whose samples' footprints are (``signature.grid_code``).
   Silhouettes, shadows' edges, creases, a spotlight's cone, total internal
   reflection and the same seen in mirrors and through glass change the signature: those
   pixels go on as below. A subtree whose path weight is below the threshold does not
   count (whatever it sees changes the sample by less).
1. A first pass traces every pixel at the render's sampling (one sample: the centre),
   the plain image's pass, and one sample at each pixel *corner*: the (W + 1) x (H + 1)
   lattice of the pixels' corners (``camera.corner_rays``), each corner shared by the
   four pixels around it. A pixel's five samples (centre and four corners) cost about two
   samples per pixel, and a straight edge that crosses a pixel always separates two of its
   corners, however little of it it covers.
2. A pixel whose five samples differ by more than the threshold (in some channel, linear
   values) is *refined*: it is traced again with a stratified n x n set of samples (the
   centres of an n x n grid of strata) -- unless they all followed one path (step 0). A
   detail thinner than a pixel that the centres miss is found where it crosses a corner.
   So is a pixel between two refined ones (opposite neighbours: above and below, left
   and right, or across a diagonal): in a region of detail finer than the samples (a checkerboard towards the
   horizon) some pixels' five samples agree by chance, and a wire thinner than the
   samples' spacing is found in some pixels along it and missed in others, while no pixel
   beside a straight edge has two opposite refined neighbours. Such a pixel gets the
   finest grid: it holds detail its own samples missed.
3. The grid follows the contrast: the error of an n x n grid on an edge grows with the
   difference across it, so ``GRIDS`` gives each pixel refined for its own samples the
   finest grid whose contrast, in multiples of the threshold, its five samples'
   difference exceeds. The ladder (2 x 2 to 12 x 12) is what brings edges of high
   contrast within 2/255 of a 256-sample render (the 8 x 8 and 12 x 12 steps: 94 % to
   98.5 % of the pixels of the fine-detail benchmark; docs/performance.md, "Image size,
   depth and anti-aliasing").

4. A pixel refined for its neighbours (step 2) is given the finest grid, but most such
   pixels turn out flat: before its grid it is traced with a *probe*, the
   ``PROBE`` x ``PROBE`` grid, which settles it (its value is the
   probe's) where the probe's samples agree with one another (within the threshold) and
   their mean with its first pass's value (within ``SETTLE`` x the threshold): it is
   flat at the probe's resolution (towards the horizon, where the filtered board is a
   smooth grey); a wire the probe's samples miss too is the risk, which the probe's
   spacing (a quarter of a pixel) keeps to sub-pixel detail thinner than 1/4 of a pixel
   (a 6 x 6 probe until 2026-12-07: the 4 x 4 one costs the fine-detail benchmark 0.02
   points of its pixels within 2/255 and saves 4-10 % of an --aa render's time).
   Where the probe's samples differ (it saw the detail), the probe is the pixel's first
   look at it: their contrast (the largest difference between two of them) chooses the
   grid as a pixel's five samples do (step 3), and where that grid is no finer than the
   probe's own, the probe's value stands. (Those pixels were given the finest grid until
   2026-12-07; nearly all of them asked for 4 x 4 or less.) A flat probe whose mean
   disagrees with the first pass's value (a detail the centre hit and the probe's samples
   missed) keeps the finest grid.
   Such a pixel whose own samples followed one path (step 0) is settled too where all
   its probe's samples followed that path (``signature.one_path``): no detail of its
   neighbours' reaches into it, short of a quarter of a pixel.
   A pixel refined for its own samples whose grid is the finest is first probed with the
   same ``PROBE`` x ``PROBE`` grid, in the same job (the two were ``BETWEEN_PROBE`` and
   ``EDGE_PROBE``, two jobs, until 2026-12-07), and settled where its samples differ (the pixel
   holds an edge) and yet their mean agrees with the first pass's value within
   ``SETTLE`` x the threshold: the first pass's filtered footprint already averaged what
   they differ by (a checker edge seen directly); a point-sampled edge (a silhouette, a
   shadow, a reflection) makes the mean a mixture the centre's one value does not match,
   but by chance, which the probe's 16 samples and the tight ``SETTLE`` make rare. Other
   refined pixels go straight to their grid. The probe repays its 16 samples where it
   settles more than 16 / (n^2 - 16) of the pixels given n x n: 12.5 % for 12 x 12, 33 %
   for 8 x 8, 80 % for 6 x 6. Counted on the benchmark's reflective scene, the showcase,
   benchmark_glass and whitted (2026-12-07, thresholds 0.01, 0.02 and 0.05), it settled
   0-43 % of the pixels given 6 x 6 and 0-45 % of those given 8 x 8 (33 % or more on two
   of the scenes at 0.02, on none at 0.01 or 0.05), so those are not probed; of those
   given 12 x 12 it settled 0-58 % at 0.02 and 10-32 % at 0.01, where it saves the
   showcase 15 % of its time.
   Then the refined pixels' grids are traced, as two jobs (:class:`Graded`: the grids
   whose pixels fill whole packets, 4 x 4, 8 x 8 and 12 x 12, and the others), not one job
   a grid: a job has a fixed cost (about 10 ms on the CPU, measured 2026-12-07: the ray
   tree's kernels, a host sync at each bounce) whatever its size, and an ``--aa`` render
   ran nine of them (the first pass, the corners, two probes, six grids), now five; its
   image is the same, bit for bit. A chunk of them holds at most half the first pass's
   camera rays, but never fewer than ``GRADED_LANES``: in one chunk, the grids' deeper
   trees raised the peak memory of a 512 x 384 render of the showcase from 324 to 530 MB;
   so capped, it is 305 MB, and the render takes 9 % less time (whitted.ray: 11 %; the
   repository's scenes 8-12 %), whole processes, 2026-12-07.

5. A checkerboard is averaged over each sample's *footprint* (its share of the pixel: the
   whole pixel for the first pass and the corners, 1/n of it for an n x n grid), from the
   camera rays' differentials (``camera.sample``, ``hits.uv_footprint``,
   ``checkerboard.checker_filtered``: the footprint as perspective maps it, not only its
   first-order parallelogram), seen directly or in mirrors and through glass (the
   differentials carried through each bounce, ``differentials.py``). Squares smaller than
   a pixel towards the horizon, or crowding towards a mirror ball's rim, are then a smooth
   grey rather than noise no affordable grid resolves, and the edges of larger squares
   need no refinement at all (step 0).

Each pixel's value is the box-filtered average of its samples: those of its grid if it
is refined, its first pass's otherwise (the corners only decide). The choice depends only
on the values of a pixel's samples and its neighbours', so it is the same on every run
and however the image is cut into bands of rows; it is a detached decision: gradients
flow through the values of the samples, never through which pixels were refined. :func:`refine` runs the corners and steps 2 and 3 after the
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

from . import signature
from .camera import corner_rays, graded_rays, pixel_means
from .chunks import Job, fills_packets

# (n, contrast): a refined pixel gets the n x n grid of the last entry whose contrast, in
# multiples of the threshold, its five samples' difference exceeds
GRIDS = ((2, 0.0), (3, 2.0), (4, 4.0), (6, 12.0), (8, 20.0), (12, 35.0))
# The probes (step 4 above): the grid's side of a pixel refined for its neighbours, and of a
# pixel whose own grid is the finest (one job: one side); and how close, in multiples of the
# threshold, a probe's mean must be to the first pass's value to settle a pixel
PROBE = 4
SETTLE = 0.25
# A chunk of the refined pixels' grids (Graded) holds at most half the first pass's camera
# rays (their trees are deeper than the image's average: whole processes then peak within 3 %
# of where they did with a job a grid, most lower, measured 2026-12-07), or this many where
# that is more (a small
# image's refinement in one chunk)
GRADED_LANES = 1 << 16
BAND = 1024  # rows compared at a time (bounded host memory on huge images)
# The rows a band's first pass traces above and below it: a pixel between two refined ones
# reads its neighbours' decisions, and each of these reads its own neighbours' paths (step 0)
MARGIN = 2


def contrast(image, corners):
    """(H, W) float32: for each pixel of ``image`` (H, W, 3), the largest difference in one
    channel between its centre and its four corners (of ``corners``, (H + 1, W + 1, 3))."""
    height, width = image.shape[:2]
    spread = np.zeros((height, width), np.float32)
    for top in range(0, height, BAND):
        bottom = min(top + BAND, height)
        low = high = image[top:bottom]
        for dy in (0, 1):
            for dx in (0, 1):
                corner = corners[top + dy:bottom + dy, dx:width + dx]
                low, high = np.minimum(low, corner), np.maximum(high, corner)
        spread[top:bottom] = (high - low).max(axis=-1)
    return spread


def grid_of(spread, threshold):
    """The entry of ``GRIDS`` (int array) of pixels whose five samples differ by ``spread``
    at the contrast ``threshold``: the last one whose contrast ``spread`` exceeds."""
    grid = np.zeros(spread.shape, np.int8)
    for k, (_, times) in enumerate(GRIDS):
        grid[spread > times * threshold] = k
    return grid


def between(mask):
    """(H, W) bool: the pixels two opposite neighbours of which (above and below, left and
    right, or across a diagonal) are in ``mask`` ((H, W) bool; a neighbour outside the
    image counts as not in it)."""
    padded = np.pad(mask, 1)
    height, width = mask.shape

    def neighbour(dy, dx):
        return padded[1 + dy:1 + dy + height, 1 + dx:1 + dx + width]

    found = np.zeros(mask.shape, bool)
    for dy, dx in ((-1, -1), (-1, 0), (-1, 1), (0, -1)):  # one of each opposite pair
        found |= neighbour(dy, dx) & neighbour(-dy, -dx)
    return found


class CornerJob:
    """The pixel corners of rows ``top`` .. ``bottom`` (both included: a band of pixel rows
    top .. bottom - 1 has bottom - top + 1 rows of corners) of a ``width`` x ``height``
    image, one sample each: a job for ``chunks.Chunker``."""

    spp, pixels = 1, None  # one sample a corner, a range of corners
    samples, fitting, packet_margins = Job.samples, Job.fitting, Job.packet_margins
    coherent = True  # (a range: see chunks.Job)

    def __init__(self, width, height, top, bottom):
        self.width, self.height = width, height  # the image
        self.first = top * (width + 1)  # the first corner's number
        self.count = (bottom - top + 1) * (width + 1)  # how many corners
        self.total = (width + 1) * (height + 1)  # the corners of the image's numbering

    def rays(self, sensor, start, count, footprint=False):
        return corner_rays(sensor, self.width, self.height, self.first + start, count,
                           footprint)


def least_weight(threshold):
    """The path weight below which a subtree does not count in a sample's path signature
    (``Tracer.trace``'s ``signed``): the contrast ``threshold``. A subtree of radiance at
    most 1 weighed by less changes its sample by less than the threshold, whatever it sees:
    like a difference below the threshold, it does not make a pixel refined."""
    return threshold


def trace_corners(chunker, width, height, top, bottom, threshold):
    """The values ((bottom - top + 1, W + 1, 3) float32) and path signatures ((bottom - top
    + 1, W + 1) uint32, signature.py) of the corners of the pixel rows ``top`` .. ``bottom``
    - 1, traced through ``chunker`` (``threshold``: the refinement's, see least_weight)."""
    job = CornerJob(width, height, top, bottom)
    values = np.empty((job.count, 3), np.float32)
    signatures = np.empty(job.count, np.uint32)

    def visit(start, count, color, path):
        values[start:start + count] = dr.ravel(color).numpy().reshape(-1, 3)
        signatures[start:start + count] = path.numpy()

    chunker.run(job, visit, signed=least_weight(threshold))
    shape = (bottom - top + 1, width + 1)
    return values.reshape(*shape, 3), signatures.reshape(shape)


class Level(NamedTuple):
    """Refined pixels: ``pixels`` traced again with an ``n`` x ``n`` grid of samples."""

    pixels: np.ndarray  # uint32: the image's pixel numbers, in the order traced
    n: int  # the grid's side (GRIDS)


class Graded:
    """The pixels of several levels (:class:`Level`), each with its own grid, traced as one
    job (a job for ``chunks.Chunker``, as ``chunks.Job``): the levels' pixels in order, a
    pixel's n x n samples consecutive, as each level's own job would trace them (the same
    rays, the same packets: the levels' grids all fill whole packets, or none does,
    ``chunks.fills_packets``). It has the Chunker's part of a job's interface only (not
    ``spp`` nor the lane numbering an adjoint pass reads: the adjoint jobs are one
    ``chunks.Job`` a level, ``Plan.adjoint_jobs``). A job has a fixed cost (about 10 ms on
    the CPU: the ray tree's kernels recorded, a host sync at each bounce), which the levels
    then share."""

    def __init__(self, width, height, levels):
        self.width, self.height = width, height  # the image
        if not levels:
            raise ValueError("a graded job needs a level")
        self.pixels = np.concatenate([level.pixels for level in levels])  # uint32, in order
        self.sides = np.concatenate([np.full(len(level.pixels), level.n, np.uint32)
                                     for level in levels])  # each pixel's grid's side
        self.count = len(self.pixels)
        coherent = {fills_packets(level.n * level.n) for level in levels}
        if len(coherent) != 1:
            raise ValueError("levels traced together must all fill whole packets, or none")
        self.coherent = coherent.pop()
        # each pixel's samples' end: its last lane + 1, counted from the job's first
        self.ends = np.cumsum(self.sides.astype(np.int64) ** 2)

    def _lane(self, pixel):
        return int(self.ends[pixel - 1]) if pixel else 0

    def samples(self, start, count):
        return self._lane(start + count) - self._lane(start)

    def fitting(self, start, lanes):
        last = int(np.searchsorted(self.ends, self._lane(start) + lanes, side="right"))
        return max(last - start, 1)

    def packet_margins(self, start, count):
        return 0, 0  # (each pixel whole packets, or its rays traced alone)

    def rays(self, sensor, start, count, footprint=False):
        return graded_rays(sensor, self.width, self.height,
                           self.pixels[start:start + count], self.sides[start:start + count],
                           footprint)

    def means(self, start, count, samples):
        """The box-filtered value ((count, 3) float32) of each of the pixels start .. start +
        count - 1 from their ``samples`` ((lanes, 3) float32): their sum, in lane order, times
        1 / n^2, as ``camera.pixel_means`` computes it."""
        out = np.empty((count, 3), np.float32)
        sides = self.sides[start:start + count].astype(np.int64)
        firsts = np.flatnonzero(np.diff(sides, prepend=0))  # the runs of one grid
        lane = 0
        for first, end in zip(firsts, [*firsts[1:], count]):
            spp = int(sides[first]) ** 2
            run = samples[lane:lane + (end - first) * spp].reshape(end - first, spp, 3)
            total = run[:, 0].copy()
            for s in range(1, spp):
                total += run[:, s]
            out[first:end] = total * np.float32(1.0 / spp)
            lane += (end - first) * spp
        return out


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
        self.levels = levels  # the Levels: disjoint sets of pixels, each with its grid

    def is_for(self, sensor, width, height, spp, threshold):
        """Whether this is the plan of a render of these."""
        return (self.sensor is sensor and (self.width, self.height, self.spp, self.threshold)
                == (width, height, spp, threshold))

    def adjoint_jobs(self):
        """The jobs that re-trace every pixel with the samples its value came from: a list of
        (job, weights), weights (float32 by pixel) 1 on the pixels whose value is the job's
        and 0 on the others, or None: every pixel of the job."""
        if not self.levels:
            return [(Job(self.width, self.height, self.spp), None)]
        refined = np.zeros(self.width * self.height, bool)
        for level in self.levels:
            refined[level.pixels] = True
        jobs = [(Job(self.width, self.height, self.spp), (~refined).astype(np.float32))]
        return jobs + [(Job(self.width, self.height, level.n * level.n, pixels=level.pixels),
                        None) for level in self.levels]


def refine(image, spp, threshold, chunker, estimate, height=None, first_row=0, rows=None,
           signatures=None):
    """Refine the first pass ``image`` ((H, W, 3) float32, C-contiguous, traced at ``spp``
    samples per pixel) at the contrast ``threshold``: the pixel corners, then every level's
    pixels are traced by ``chunker`` (each job first admitted by the guards' ``estimate``)
    and the levels' values written into ``image``, in place. Returns the :class:`Plan`.

    A band: ``image`` holds the rows ``first_row`` .. ``first_row`` + H - 1 of an image of
    ``height`` rows (default: H, the whole image), and only the pixels of ``rows`` (top,
    bottom) are refined (default: all of them). A band's rows need MARGIN rows above and
    below (where the image has them) for the decisions: the decisions, and so the values,
    are then those of the whole image's render.

    ``signatures``: the first pass's path signatures ((H, W) uint32, signature.py), or
    None: every pixel whose samples differ is refined."""
    band_height, width = image.shape[:2]
    height = height or band_height
    top, bottom = rows or (first_row, first_row + band_height)
    estimate.admit((width + 1) * (band_height + 1), 1)  # the corners
    corners, corner_signatures = trace_corners(chunker, width, height, first_row,
                                               first_row + band_height, threshold)
    values = image.reshape(-1, 3)
    spread = contrast(image, corners)
    del corners
    contrasted = spread > threshold
    smooth = None
    if signatures is not None:  # one path throughout: the differences are smooth (step 0)
        same = signature.agree(signatures, corner_signatures)
        smooth = np.where(contrasted & same, signature.grid_sides(signatures, corner_signatures),
                          1)
        contrasted &= ~same
    del corner_signatures
    around = between(contrasted) & ~contrasted
    band = slice(top - first_row, bottom - first_row)
    refined = (contrasted | around)[band]
    sides = np.array([n for n, _ in GRIDS])  # each entry's grid side
    # a pixel refined for its neighbours holds detail its own samples missed: the finest grid
    grid = np.where(around[band], len(GRIDS) - 1, grid_of(spread[band], threshold))
    if smooth is not None:  # step 0: the grids the footprints need, traced in the same jobs
        # as the others'
        smooth = np.where(around, 1, smooth)[band]
        refined |= smooth > 1
        grid = np.where(smooth > 1, np.searchsorted(sides, smooth), grid)
    grid = np.where(refined, grid, -1).astype(np.int8).ravel()  # (-1: done, or not refined)
    first = top * width  # the band's first pixel
    offset = first_row * width  # the first pixel of ``values``
    levels = []

    # The probes (step 4), one job: the pixels refined for their neighbours, and those refined
    # for their own samples whose grid is the finest
    around = around[band].ravel()
    probed = (np.flatnonzero((around & (grid >= 0)) | (~around & (grid == len(GRIDS) - 1)))
              + first).astype(np.uint32)
    if len(probed):
        estimate.admit(len(probed), PROBE * PROBE)
        means, spread, paths = trace_probe(
            chunker, Job(width, height, PROBE * PROBE, pixels=probed),
            None if smooth is None else least_weight(threshold))
        neighbours = around[probed - first]  # (the others: an edge's)
        agree = np.abs(means - values[probed - offset]).max(axis=-1) <= SETTLE * threshold
        flat = spread <= threshold
        asked = grid_of(spread, threshold)
        # its neighbours': flat and agreeing, or asking for no finer a grid than the probe's;
        # an edge: its samples differ, yet their mean agrees (the first pass's footprint
        # averaged them)
        done = np.where(neighbours, (agree & flat) | (~flat & (sides[asked] <= PROBE)),
                        agree & ~flat)
        if paths is not None:
            # (a pixel between two refined ones whose own samples followed one path, and its
            # probe's too, holds no detail its neighbours saw: their feature misses it by a
            # quarter of a pixel)
            done |= neighbours & same[band].ravel()[probed - first] & \
                signature.one_path(signatures.ravel()[probed - offset], paths)
        regrid = neighbours & ~done & ~flat  # it saw the detail: the grid its contrast asks for
        grid[probed[regrid] - first] = asked[regrid]
        if done.any():
            values[probed[done] - offset] = means[done]
            levels.append(Level(probed[done], PROBE))
            grid[probed[done] - first] = -1
    graded = [Level((np.flatnonzero(grid == k) + first).astype(np.uint32), n)
              for k, (n, _) in enumerate(GRIDS)]
    graded = [level for level in graded if len(level.pixels)]
    for level in graded:
        estimate.admit(len(level.pixels), level.n * level.n)
    for coherent in (True, False):  # two jobs, not one a level (Graded)
        together = [level for level in graded if fills_packets(level.n * level.n) == coherent]
        if together:
            trace_graded(chunker, Graded(width, height, together), values, offset,
                         lanes=max(len(values) * spp // 2, GRADED_LANES))
    return Plan(chunker.sensor, width, height, spp, threshold, levels + graded)


def trace_graded(chunker, job, values, offset=0, lanes=None):
    """Trace the pixels of ``job`` (:class:`Graded`) through ``chunker``, at most ``lanes``
    camera rays a chunk (None: as the chunker's budget allows), each one's box-filtered value
    written into ``values`` ((H * W, 3), by pixel number less ``offset``)."""
    def visit(start, count, color):
        means = job.means(start, count, dr.ravel(color).numpy().reshape(-1, 3))
        values[job.pixels[start:start + count] - offset] = means

    chunker.run(job, visit, lanes=lanes)


def trace_probe(chunker, job, signed=None):
    """Trace ``job``'s pixels through ``chunker``: ((count, 3) float32, each pixel's
    box-filtered value; (count,) float32, the largest difference in one channel between
    two of its samples; (count, spp) uint32, its samples' path signatures, with ``signed``
    (``Tracer.trace``'s), else None)."""
    means = np.empty((job.count, 3), np.float32)
    spread = np.empty(job.count, np.float32)
    paths = None if signed is None else np.empty((job.count, job.spp), np.uint32)

    def visit(start, count, color, path=None):
        means[start:start + count] = \
            dr.ravel(pixel_means(color, count, job.spp)).numpy().reshape(-1, 3)
        samples = dr.ravel(color).numpy().reshape(count, job.spp, 3)
        spread[start:start + count] = (samples.max(axis=1) - samples.min(axis=1)).max(axis=-1)
        if path is not None:
            paths[start:start + count] = path.numpy().reshape(count, job.spp)

    chunker.run(job, visit, signed=signed)
    return means, spread, paths
