"""Rendering in chunks of bounded size: which camera rays are traced together.

A *job* is a set of pixels (a contiguous range, or an explicit list) and a number of
samples per pixel (anti-aliasing's ``Graded``: each pixel its own). Its interface to the
:class:`Chunker` (:class:`Job`'s; anti-aliasing's ``CornerJob`` and ``Graded`` have it
too): ``count`` (pixels), ``rays(sensor, start, count, footprint)``,
``samples(start, count)`` (camera rays of pixels start .. start + count - 1),
``fitting(start, lanes)`` (how many pixels from start fit in that many camera rays, at least
one), ``coherent`` and ``packet_margins(start, count)`` (its rays traced in packets, see
PACKET). It is traced in *chunks*: consecutive pixels of the job, all the
samples of a pixel in the same chunk (so the box filter is per chunk), each chunk's
whole ray tree at once. A pixel's value does not depend on the chunk it is in, so the
image is the same, bit for bit, however it is split.

**Memory.** A chunk's ray tree is bounded by a number of rays, ``budget /
BYTES_PER_RAY`` (``BYTES_PER_RAY_AD`` when the chunk is traced with AD, which keeps every
generation's graph for the adjoint pass; FOOTPRINT_FACTOR times that for anti-aliasing's
rays, which carry their footprints: ``guards.bytes_per_ray``): the tracer raises
``TreeTooLarge`` before a generation would take the tree past it, and the chunk is then
traced again in halves. A chunk also holds at most ``MAX_CHUNK_LANES`` camera rays (see
there), or fewer where the caller asks (``Chunker.run``'s ``lanes``). How many pixels a
chunk holds follows the largest number of rays per camera ray seen so far (at first twice
the probe's average: the tree's size varies over the image, mirrors and glass against sky),
so that a chunk fits at the first attempt (a failed attempt is work thrown away).
Everything is decided from ray counts, so the split, like the image, is the same on every
run.

**Time.** Before a render, :func:`probe` traces a spread-out sample of the image's
pixels (at most ``PROBE_PIXELS``, tree at most ``PROBE_RAYS`` rays, extrapolated
from its growth past that) to estimate the rays per camera ray: the chunk size to
start with, and the guards' estimate of the whole render (``guards.Estimate``); its trace
is also what measures the scene's rays per second for the guards (``guards.timed``).
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

from .camera import camera_rays
from .guards import GIB, BudgetError, bytes_per_ray, timed
from .tree import TreeTooLarge

MIN_CHUNK_RAYS = 1 << 12
# Camera rays of one chunk, at most. A process's first render touches its chunks' memory
# afresh (the kernel maps and zeroes every new page); later chunks, and later renders, reuse
# it through Dr.Jit's allocation cache. Chunks of at most 2^20 camera rays keep that first
# touch small while each kernel still has work for every core.
MAX_CHUNK_LANES = 1 << 20
PROBE_PIXELS = 1024
PROBE_RAYS = 1 << 20
# Lanes: the widest packet Embree traces coherent camera rays in on the CPU (AVX-512; AVX2's
# 8 divide it). A ray that ties between two surfaces (coincident faces, a shared edge) may
# resolve by its packet mates, so a coherent job's chunks are traced in whole packets of the
# image's own lane numbering (Chunker._trace): the same packets however it is cut.
PACKET = 16


def fills_packets(spp):
    """Whether a pixel's ``spp`` lanes are whole packets (PACKET): a list of such pixels is
    traced as coherent packets, each packet one pixel's, whatever else the list holds."""
    return spp % PACKET == 0


class Job:
    """Pixels to render with ``spp`` samples each: ``first`` .. ``first + count - 1`` of the
    image or, with ``pixels`` (a numpy uint32 array), those pixels in that order."""

    def __init__(self, width, height, spp, first=0, count=None, pixels=None):
        self.width, self.height = width, height  # the image
        self.spp = spp  # samples per pixel
        # uint32: the job's pixels, in order (None: the range from first)
        self.pixels = None if pixels is None else np.ascontiguousarray(pixels, dtype=np.uint32)
        self.first = first  # the range's first pixel
        self.count = (len(self.pixels) if pixels is not None  # how many pixels
                      else (width * height - first if count is None else count))
        # whether the camera rays are traced as coherent packets (Tracer.trace): a range's
        # neighbouring rays are, and a list's whose pixels are each whole packets (PACKET);
        # other lists' rays alone: their packets would depend on what else the list holds
        self.coherent = pixels is None or fills_packets(spp)
        self.total = width * height  # the pixels of the image's numbering

    def rays(self, sensor, start, count, footprint=False):
        """Camera rays of the job's pixels start .. start + count - 1 (``footprint``: with
        their samples' footprints, see camera.camera_rays)."""
        if self.pixels is None:
            return camera_rays(sensor, self.width, self.height, self.spp, self.first + start,
                               count, footprint=footprint)
        return camera_rays(sensor, self.width, self.height, self.spp,
                           pixels=mi.UInt32(self.pixels[start:start + count]),
                           footprint=footprint)

    def samples(self, start, count):
        """The camera rays of the job's pixels start .. start + count - 1."""
        return count * self.spp

    def fitting(self, start, lanes):
        """How many of the job's pixels from start have at most ``lanes`` camera rays (at
        least one)."""
        return max(lanes // self.spp, 1)

    def packet_margins(self, start, count):
        """(pixels before, pixels after) the job's pixels start .. start + count - 1 that
        complete their first and last packets of PACKET lanes, the lanes numbered from the
        image's first (a list: 0, 0; its pixels are each whole packets, or its rays are
        traced alone)."""
        if self.pixels is not None:
            return 0, 0
        unit = PACKET // math.gcd(self.spp, PACKET)  # pixels of a whole number of packets
        first = self.first + start
        return first % unit, min(-(first + count) % unit,
                                 self.total - first - count)

    def lane_pixel(self, start, count):
        """The image's pixel number of each lane (camera ray) of the job's pixels start ..
        start + count - 1 (UInt32, ``spp`` lanes a pixel; computed, not gathered from a lazy
        array, so it evaluates nothing)."""
        lane = dr.arange(mi.UInt32, count * self.spp) // self.spp
        if self.pixels is None:
            return lane + dr.opaque(mi.UInt32, self.first + start)
        return dr.gather(mi.UInt32, mi.UInt32(self.pixels[start:start + count]), lane)

    def lanes(self, start, count):
        """The image's camera ray number (pixel-major: pixel p's samples are p spp .. p spp +
        spp - 1) of each lane of the job's pixels start .. start + count - 1 (UInt32;
        computed, not gathered from a lazy array)."""
        lane = dr.arange(mi.UInt32, count * self.spp)
        if self.pixels is None:
            return lane + dr.opaque(mi.UInt32, (self.first + start) * self.spp)
        return self.lane_pixel(start, count) * self.spp + lane % self.spp

    def pixel_index(self, start, count):
        """The image's pixel numbers of the job's pixels start .. start + count - 1 (UInt32)."""
        if self.pixels is None:
            return dr.arange(mi.UInt32, count) + dr.opaque(mi.UInt32, self.first + start)
        return mi.UInt32(self.pixels[start:start + count])


class Chunker:
    """Runs jobs chunk by chunk within a memory ``budget`` (bytes), for one render of
    ``scene`` from ``sensor``; see the module docstring.

    ``rays_per_camera_ray``: the estimate to size the first chunk with; ``progress``:
    optional callable(pixels_done, pixels_total, chunks_done) called after each chunk;
    ``terms``: the scene's terms for detached chunks (default: built at the first one);
    ``max_pixels``: at most this many pixels a chunk (None: by budget only)."""

    def __init__(self, tracer, scene, sensor, budget, rays_per_camera_ray=2.0,
                 progress=None, terms=None, max_pixels=None):
        self.tracer, self.scene, self.sensor = tracer, scene, sensor  # what is traced
        self.budget = budget  # bytes one chunk's tree may take
        self.max_pixels = max_pixels  # at most this many pixels a chunk (None: by budget only)
        self.progress = progress  # optional callable(pixels_done, pixels_total, chunks_done)
        self.terms = terms  # the scene's terms for detached chunks (built once)
        # The largest rays per camera ray seen so far, which sizes the next chunk
        self.ratio = max(2.0 * float(rays_per_camera_ray), 1.0)
        # Counters of the jobs run so far
        self.pixels_total = 0  # pixels of the jobs run (or running)
        self.pixels_done = 0  # pixels traced
        self.chunks_done = 0  # chunks traced
        self.rays_traced = 0  # rays of every chunk's tree
        self.rays_per_generation = []  # of the chunk traced last: how many rays each depth traced

    def tree_rays(self, ad):
        return max(int(self.budget // bytes_per_ray(ad, self.tracer.footprint)), MIN_CHUNK_RAYS)

    def run(self, job, visit, ad=False, lazy=False, record=None, queries=None, signed=None,
            lanes=None):
        """Trace ``job`` chunk by chunk; for each chunk call ``visit(start, count, color)``
        with the camera rays' colors (one lane per camera ray, pixel-major; ``signed``, not
        None: ``visit(start, count, color, signature)``, with their path signatures, see
        ``Tracer.trace``). ``visit`` is
        called with AD enabled when ``ad`` (and then the tree is sized for its graph);
        ``lazy``: the colors are handed over unevaluated (``Tracer.trace``); ``record``:
        optional callable(start, count) giving the ``first_hit`` hook of the chunk's trace;
        ``queries``: optional callable(start, count, terms) giving its ``queries`` (or None;
        ``Tracer.trace``, ``terms`` the chunk's scene terms); ``lanes``: at most this many
        camera rays a chunk, or one pixel's (None: MAX_CHUNK_LANES); start counts the job's
        pixels."""
        max_rays = self.tree_rays(ad)
        max_lanes = MAX_CHUNK_LANES if lanes is None else min(lanes, MAX_CHUNK_LANES)
        self.pixels_total += job.count
        start = 0
        while start < job.count:
            count = min(self._chunk_pixels(job, start, max_rays, max_lanes),
                        job.count - start)
            trace, count = self._trace_within(job, start, count, ad, max_rays, lazy, record,
                                              queries, signed)
            rays = sum(trace.rays_per_generation)
            self.rays_traced += rays
            self.rays_per_generation = trace.rays_per_generation
            self.ratio = max(rays / job.samples(start, count), self.ratio)
            visit(start, count, trace.color, *(() if signed is None else (trace.signature,)))
            del trace
            start += count
            self.pixels_done += count
            self.chunks_done += 1
            if self.progress is not None:
                self.progress(self.pixels_done, self.pixels_total, self.chunks_done)

    def _chunk_pixels(self, job, start, max_rays, max_lanes):
        # 1.5: room for a chunk whose tree is larger than any before
        lanes = min(int(max_rays / (self.ratio * 1.5)), max_lanes)
        pixels = job.fitting(start, lanes)
        if self.max_pixels is not None and self.max_pixels < pixels:
            return self.max_pixels  # (as asked: its chunks take their margins, _trace)
        return self._whole_packets(job, start, pixels)

    def _whole_packets(self, job, start, count):
        """``count`` pixels from ``start``, fewer so that the next chunk starts a packet
        (PACKET) where that leaves some: a chunk then needs no margins (Chunker._trace)."""
        if start + count >= job.count:
            return count
        past = job.packet_margins(start + count, 0)[0]  # pixels past the last packet's start
        return count - past if past < count else count

    def _trace_within(self, job, start, count, ad, max_rays, lazy=False, record=None,
                      queries=None, signed=None):
        """(The trace of the ``count`` pixels from ``start``, or of the first half of them,
        halved again until the tree holds at most ``max_rays`` rays; that count)."""
        while True:
            try:
                return self._trace(job, start, count, ad, max_rays, lazy, record,
                                   queries, signed), count
            except TreeTooLarge:
                if count == 1:
                    raise BudgetError(
                        f"the ray tree of one pixel ({job.samples(start, 1)} samples) exceeds "
                        f"the memory budget ({self.budget / GIB:.2g} GB): use a smaller "
                        "--max-depth, a --bailout (e.g. 1e-3) or a larger --memory-budget"
                    ) from None
                count = self._whole_packets(job, start, max(count // 2, 1))

    def _trace(self, job, start, count, ad, max_rays, lazy=False, record=None, queries=None,
               signed=None):
        if ad:  # terms of its own: each chunk's adjoint pass consumes its graph
            with dr.resume_grad():
                terms = self.tracer.scene_terms(self.scene)
        else:
            if self.terms is None:
                self.terms = self.tracer.scene_terms(self.scene)
            terms = self.terms
        first_hit = None if record is None else record(start, count)
        asked = None if queries is None else queries(start, count, terms)
        # a coherent job's chunk traced in whole packets (PACKET): the rays before and after
        # it that complete them too (not where a hook or an adjoint pass reads the lanes)
        before, after = (0, 0) if ad or record or queries else job.packet_margins(start, count)
        with dr.resume_grad(when=ad):
            trace = self.tracer.trace(self.scene,
                                      self._rays(job, start - before, before + count + after),
                                      terms, max_rays, lazy, first_hit, asked, signed,
                                      job.coherent)
        if not before and not after:
            return trace
        # (the offset is data, not a constant of the kernel: it changes from chunk to chunk)
        lanes = dr.arange(mi.UInt32, job.samples(start, count)) + \
            dr.opaque(mi.UInt32, job.samples(start - before, before))
        return trace._replace(color=dr.gather(mi.Color3f, trace.color, lanes),
                              signature=None if trace.signature is None else
                              dr.gather(mi.UInt32, trace.signature, lanes))

    def _rays(self, job, start, count):
        return job.rays(self.sensor, start, count, self.tracer.footprint)


def probe(tracer, scene, sensor, width, height, spp, terms):
    """(Estimated rays per camera ray of the whole image, from a spread-out sample of its
    pixels (see the module docstring); the rays per second of that sample's trace, or None:
    not measured, ``guards.timed``)."""
    total = width * height
    stride = max(total // PROBE_PIXELS, 1)
    pixels = np.arange(0, total, stride, dtype=np.uint32)[:PROBE_PIXELS]
    samples = min(spp, max(PROBE_PIXELS * 4 // len(pixels), 1))  # enough lanes, few rays
    job = Job(width, height, samples, pixels=pixels)
    camera = len(pixels) * samples
    try:
        with dr.suspend_grad():
            trace, rate = timed(lambda: tracer.trace(scene, job.rays(sensor, 0, job.count,
                                                                     tracer.footprint),
                                                     terms, PROBE_RAYS))
        return sum(trace.rays_per_generation) / camera, rate
    except TreeTooLarge as e:
        return extrapolated_rays(e, tracer.max_depth) / camera, None


def extrapolated_rays(e, max_depth):
    """The rays of a tree too large to trace (TreeTooLarge ``e``), its growth from the last
    generation traced to the one refused extrapolated to ``max_depth``."""
    widths = e.rays_per_generation
    growth = max(e.lanes / max(widths[-1], 1), 1.0)
    rest = max_depth - e.depth + 1  # generations e.depth .. max_depth
    if growth == 1.0:
        deeper = e.lanes * rest
    else:
        deeper = e.lanes * (growth ** min(rest, 200) - 1) / (growth - 1)
    return sum(widths) + deeper
