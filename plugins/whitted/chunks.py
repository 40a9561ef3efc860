"""Rendering in chunks of bounded size: which camera rays are traced together.

A *job* is a set of pixels (a contiguous range, or an explicit list) and a number of
samples per pixel. It is traced in *chunks*: consecutive pixels of the job, all the
samples of a pixel in the same chunk (so the box filter is per chunk), each chunk's
whole ray tree at once. A pixel's value does not depend on the chunk it is in, so the
image is the same, bit for bit, however it is split.

**Memory.** A chunk's ray tree is bounded by a number of rays, ``budget /
BYTES_PER_RAY`` (``BYTES_PER_RAY_AD`` when the chunk is traced with AD, which keeps
every generation's graph for the adjoint pass): the tracer raises ``TreeTooLarge``
before a generation would take the tree past it, and the chunk is then traced again
in halves. How many pixels a chunk holds follows the largest number of rays per
camera ray seen so far (at first twice the probe's average: the tree's size varies
over the image, mirrors and glass against sky), so that a chunk fits at the first
attempt (a failed attempt is work thrown away). Everything is decided from ray counts, so
the split, like the image, is the same on every run.

**Time.** Before a render, :func:`probe` traces a spread-out sample of the image's
pixels (at most ``PROBE_PIXELS``, tree at most ``PROBE_RAYS`` rays, extrapolated
from its growth past that) to estimate the rays per camera ray: the chunk size to
start with, and the guard's estimate of the whole render's time.
"""

from __future__ import annotations

import drjit as dr
import mitsuba as mi
import numpy as np

from .camera import camera_rays, pixel_means, pixel_spread
from .tree import TreeTooLarge

GIB = 1 << 30
# Memory per ray of a chunk's tree (what every generation keeps, the widest generation's
# transient arrays, Embree's and the allocator's share). Measured peaks on the benchmark
# scenes: 50-95 bytes per ray (primal), about 100 for a whole AD step, whose graph keeps
# every generation; the figures leave a margin of 2-6x, which the output buffer, an 8-bit
# encoder's copy of it and Dr.Jit's allocator cache share.
BYTES_PER_RAY = 200
BYTES_PER_RAY_AD = 640
MIN_CHUNK_RAYS = 1 << 12
MAX_CHUNK_LANES = 1 << 26  # camera rays of one chunk (far below Dr.Jit's 2^32 lanes)
PROBE_PIXELS = 1024
PROBE_RAYS = 1 << 20


class BudgetError(RuntimeError):
    """A request no memory budget can hold (one pixel's tree, the output buffer...)."""


class Job:
    """Pixels to render with ``spp`` samples each: ``first`` .. ``first + count - 1`` of the
    image or, with ``pixels`` (a numpy uint32 array), those pixels in that order."""

    def __init__(self, width, height, spp, first=0, count=None, pixels=None):
        self.width, self.height, self.spp = width, height, spp
        self.pixels = None if pixels is None else np.ascontiguousarray(pixels, dtype=np.uint32)
        self.first = first
        self.count = (len(self.pixels) if pixels is not None
                      else (width * height - first if count is None else count))

    def rays(self, sensor, start, count):
        """Camera rays of the job's pixels start .. start + count - 1."""
        if self.pixels is None:
            return camera_rays(sensor, self.width, self.height, self.spp, self.first + start, count)
        return camera_rays(sensor, self.width, self.height, self.spp,
                           pixels=mi.UInt32(self.pixels[start:start + count]))

    def pixel_index(self, start, count):
        """The image's pixel numbers of the job's pixels start .. start + count - 1 (UInt32)."""
        if self.pixels is None:
            return dr.arange(mi.UInt32, count) + dr.opaque(mi.UInt32, self.first + start)
        return mi.UInt32(self.pixels[start:start + count])


class Chunker:
    """Runs jobs chunk by chunk within a memory ``budget`` (bytes); see the module docstring.

    ``rays_per_camera_ray``: the estimate to size the first chunk with; ``progress``:
    optional callable(pixels_done, chunks_done) called after each chunk."""

    def __init__(self, tracer, scene, sensor, budget, rays_per_camera_ray=2.0,
                 progress=None, terms=None, max_pixels=None):
        self.tracer, self.scene, self.sensor = tracer, scene, sensor
        self.max_pixels = max_pixels  # at most this many pixels a chunk (None: by budget only)
        self.terms = terms  # the scene's terms for detached chunks (built once)
        self.budget = budget
        self.ratio = max(2.0 * float(rays_per_camera_ray), 1.0)
        self.progress = progress
        self.pixels_done = 0
        self.chunks_done = 0
        self.rays_traced = 0

    def tree_rays(self, ad):
        return max(int(self.budget // (BYTES_PER_RAY_AD if ad else BYTES_PER_RAY)), MIN_CHUNK_RAYS)

    def run(self, job, visit, ad=False):
        """Trace ``job`` chunk by chunk; for each chunk call ``visit(start, count, color)``
        with the camera rays' colors (one lane per camera ray, pixel-major). ``visit`` is
        called with AD enabled when ``ad`` (and then the tree is sized for its graph)."""
        max_rays = self.tree_rays(ad)
        start = 0
        while start < job.count:
            pixels = self._chunk_pixels(job, max_rays)
            count = min(pixels, job.count - start)
            while True:
                self.tracer.max_rays = max_rays
                try:
                    color = self._trace(job, start, count, ad)
                    break
                except TreeTooLarge:
                    if count == 1:
                        raise BudgetError(
                            f"the ray tree of one pixel ({job.spp} samples) exceeds the memory "
                            f"budget ({self.budget / GIB:.2g} GB): use a smaller --max-depth, "
                            "a --bailout (e.g. 1e-3) or a larger --memory-budget") from None
                    count = max(count // 2, 1)
                finally:
                    self.tracer.max_rays = None
            rays = sum(self.tracer.rays_per_generation)
            self.rays_traced += rays
            self.ratio = max(rays / (count * job.spp), self.ratio)
            visit(start, count, color)
            del color
            start += count
            self.pixels_done += count
            self.chunks_done += 1
            if self.progress is not None:
                self.progress(self.pixels_done, self.chunks_done)

    def _chunk_pixels(self, job, max_rays):
        # 1.5: room for a chunk whose tree is larger than any before
        lanes = min(int(max_rays / (self.ratio * 1.5)), MAX_CHUNK_LANES)
        pixels = max(lanes // job.spp, 1)
        return pixels if self.max_pixels is None else min(pixels, self.max_pixels)

    def _trace(self, job, start, count, ad):
        if ad:  # terms of its own: each chunk's adjoint pass consumes its graph
            with dr.resume_grad():
                return self.tracer.trace(self.scene, job.rays(self.sensor, start, count),
                                         self.tracer.scene_terms(self.scene))
        if self.terms is None:
            self.terms = self.tracer.scene_terms(self.scene)
        return self.tracer.trace(self.scene, job.rays(self.sensor, start, count), self.terms)


def probe(tracer, scene, sensor, width, height, spp, terms):
    """Estimated rays per camera ray of the whole image, from a spread-out sample of its
    pixels (see the module docstring)."""
    total = width * height
    stride = max(total // PROBE_PIXELS, 1)
    pixels = np.arange(0, total, stride, dtype=np.uint32)[:PROBE_PIXELS]
    samples = min(spp, max(PROBE_PIXELS * 4 // len(pixels), 1))  # enough lanes, few rays
    job = Job(width, height, samples, pixels=pixels)
    camera = len(pixels) * samples
    tracer.max_rays = PROBE_RAYS
    try:
        with dr.suspend_grad():
            tracer.trace(scene, job.rays(sensor, 0, job.count), terms)
        return sum(tracer.rays_per_generation) / camera
    except TreeTooLarge as e:
        widths = list(tracer.rays_per_generation)
        growth = max(e.lanes / max(widths[-1], 1), 1.0)
        traced = sum(widths)
        rest = tracer.max_depth - e.depth + 1  # generations e.depth .. max_depth
        if growth == 1.0:
            deeper = e.lanes * rest
        else:
            deeper = e.lanes * (growth ** min(rest, 200) - 1) / (growth - 1)
        return (traced + deeper) / camera
    finally:
        tracer.max_rays = None


def means_and_spread(color, count, spp):
    """Per pixel of a chunk: the box-filtered mean and the spread of its samples."""
    return pixel_means(color, count, spp), pixel_spread(color, count, spp)
