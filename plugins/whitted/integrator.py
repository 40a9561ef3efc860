"""``raywhitted``: the .RAY format's recursive (Whitted) ray tracer, differentiable.

For each camera ray it evaluates the format's deterministic ray tree::

    color(ray) = background                                   if the ray hits nothing
               = L_local + kr * color(reflected) + kt * color(refracted)   otherwise

    L_local = sum_ambient A ka C + sum_lights [N.L > 0] I(L) T(L) (kd C (N.L) + ks (R.V)^n)

where ``L_local`` comes from the parameters of the surface's ``rayphong`` /
``raytextured`` BSDF (read through ``protocol.py``), I(L) from the ``raylight`` emitters and
T(L), the shadow-ray transmittance, is the product of the refractivity kt of
every surface the shadow ray crosses on its way to the light (the shaded
surface itself excluded).

The pieces, one idea per module:

* ``camera.py``: which rays leave the camera for each pixel, and the box filter;
* ``protocol.py``: what the integrator reads from surfaces, lights, background;
* ``surfaces.py``: the surface table (every surface's parameters by slot), the
  lights and the background, read from the scene at the start of a render;
* ``hits.py``: the surface interaction of each hit, by lookup in one table of the
  scene's geometry;
* ``lift.py``: where shadow rays leave smooth meshes near their terminator;
* ``tree.py``: the ray tree, traced generation by generation (a wavefront), with
  the conventions for directions, normals and entering/leaving decided there;
* ``chunks.py``: which camera rays are traced together (chunks within a memory
  budget) and the estimate of a render's size;
* ``antialias.py``: which pixels adaptive anti-aliasing refines.

**Chunks.** The image is traced in chunks of consecutive pixels (all samples of a pixel
in one chunk), each chunk's whole ray tree within ``memory_budget``, and assembled on the
host (numpy), so that memory does not grow with the image: 16384 x 16384 and 4096 x 4096
at 16 spp fit in a few GB. A pixel's value does not depend on its chunk: the image is
the same, bit for bit, as the one wavefront of ``render_image``. The adjoint passes are
chunked the same way: ``render_backward`` re-traces each chunk with AD and
backpropagates its slice of ``grad_in``; ``render_forward`` propagates each chunk's
tangents, so a gradient step's memory is bounded too.

**Guards.** Before tracing, a render estimates its rays (a spread-out sample of pixels,
traced, its tree's growth extrapolated) and refuses (``BudgetError``, one line saying
why and what would work) an output buffer larger than the memory available, a pixel
whose tree alone exceeds the budget, or an estimated time beyond ``time_limit``.

**Adaptive anti-aliasing** (``aa`` > 0): a first pass at the render's sampling (one
sample per pixel: the centre); pixels that differ from one of their 8 neighbours by
more than ``aa`` (in some channel, linear values) get a stratified 4 x 4 grid, and those
whose 16 samples still differ by more than 5 ``aa`` an 8 x 8 grid; each pixel is the
box-filtered average of its last grid. Deterministic; differentiable like the rest: the
choice of pixels is a detached decision (made by the primal render; the adjoint passes
re-trace each pixel with the samples its value came from).

When to use which: ``spp`` 1 (the default) is the exact pixel-centre image that numeric
tests and fits against such a target want; ``aa`` (e.g. 0.02) gives clean edges at a
fraction of the cost of uniform supersampling, for images to look at; uniform ``spp``
n^2 treats every pixel alike (a fit to a supersampled target, or a reference).

No atomics and no randomness: the image is bit-for-bit reproducible, and every
step is differentiable (reverse and forward mode through ``render_backward`` /
``render_forward``, which re-run the trace with AD enabled). Shadow rays walk
their crossings detached, in a symbolic loop; the transmittance's derivative
with respect to kt is attached in closed form (``with_kt_derivative``). A branch
whose weight is exactly 0 is not traced, so the derivative with respect to kr or
kt *at* 0 does not see the branch it would open.

Parameters: the render options whose reader is the integrator; their list below, with
types, defaults and meanings, is made from :class:`raymitsuba.options.RenderOptions`,
where each is stated.
"""

import os

import drjit as dr
import mitsuba as mi
import numpy as np

from raymitsuba import options
from raymitsuba.options import RenderOptions

from . import antialias
from .camera import box_filter, camera_rays, pixel_means
from .chunks import (BYTES_PER_RAY, GIB, BudgetError, Chunker, Job,
                      means_and_spread, probe)
from .tree import Tracer

__doc__ += options.describe(options.INTEGRATOR)

RAYS_PER_SECOND = 4e6  # the time guard's figure: rays traced per second (2 CPU cores)


def available_memory():
    """Bytes of memory available to this process (MemAvailable on Linux; None: unknown)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


class Whitted(mi.CppADIntegrator):
    def __init__(self, props):
        super().__init__(props)
        options = RenderOptions.from_properties(props)  # defaults and ranges: raymitsuba.options
        self.tracer = Tracer(options.max_depth, options.max_shadow_crossings, options.bailout)
        self.aa = options.aa or 0.0
        self.memory_budget = options.memory_budget
        self.time_limit = options.time_limit
        self.chunk_pixels = options.chunk_pixels or None  # at most this many pixels a chunk
        self.progress = None  # optional callable(pixels_done, pixels_total, chunks_done)
        self.chunks = 0  # of the last render
        self.rays_traced = 0  # of the last render: rays of every chunk's tree
        self.estimated_rays = None  # of the last render: the guard's estimate
        self._plan = None  # the last primal render's anti-aliasing decisions

    @property
    def max_depth(self):
        return self.tracer.max_depth

    @property
    def rays_per_generation(self):
        """Of the last chunk traced: how many rays each depth traced."""
        return self.tracer.rays_per_generation

    # -- mi.Integrator interface ---------------------------------------------------------------
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        image = self.render_array(scene, sensor, spp)
        return mi.TensorXf(image)

    def render_forward(self, scene, params, sensor=0, seed=0, spp=0):
        sensor, spp, width, height = self._setup(scene, sensor, spp)
        grads = np.zeros((width * height, 3), np.float32)
        jobs = self._jobs(scene, sensor, spp)
        chunker = self._chunker(scene, sensor, spp)
        for j, (job, _) in enumerate(jobs):
            last_job = j == len(jobs) - 1

            def visit(start, count, color, job=job, last_job=last_job):
                with dr.resume_grad():
                    means = pixel_means(color, count, job.spp)
                    last = last_job and start + count == job.count
                    # the parameters' tangents stay for the next chunk; the last one clears them
                    dr.forward_to(means, flags=dr.ADFlag.Default if last else
                                  dr.ADFlag.ClearEdges | dr.ADFlag.ClearInterior)
                    grad = dr.ravel(dr.grad(means)).numpy().reshape(-1, 3)
                grads[job.pixel_index(start, count).numpy()] = grad

            chunker.run(job, visit, ad=True)
        return mi.TensorXf(grads.reshape(height, width, 3))

    def render_backward(self, scene, params, grad_in, sensor=0, seed=0, spp=0):
        sensor, spp, width, height = self._setup(scene, sensor, spp)
        chunker = self._chunker(scene, sensor, spp)
        grad_in = mi.Float(dr.detach(grad_in.array if isinstance(grad_in, mi.TensorXf)
                                     else mi.TensorXf(grad_in).array))
        for job, masked in self._jobs(scene, sensor, spp):
            # pixels refined later take their value (and their gradient) from a later job
            grad = grad_in if masked is None else grad_in * mi.Float(np.repeat(masked, 3))

            def visit(start, count, color, job=job, grad=grad):
                with dr.resume_grad():
                    means = pixel_means(color, count, job.spp)
                    weight = dr.gather(mi.Color3f, grad, job.pixel_index(start, count))
                    dr.backward_from(means * weight)

            chunker.run(job, visit, ad=True)

    # -- the image -----------------------------------------------------------------------------
    def render_array(self, scene, sensor=0, spp=0, store=None):
        """The image as a numpy float32 (H, W, 3) array, traced chunk by chunk (detached).

        ``store``: optional callable(first_pixel, values) that receives each chunk's pixels
        (float32, (count, 3)) instead: then nothing is assembled and None is returned
        (not with anti-aliasing, which needs the whole first pass)."""
        with dr.suspend_grad():
            sensor, spp, width, height = self._setup(scene, sensor, spp)
            self.check(width, height, spp, assemble=store is None or self.aa > 0)
            terms = self.tracer.scene_terms(scene)
            ratio = probe(self.tracer, scene, sensor, width, height, spp, terms)
            self.estimated_rays = ratio * width * height * spp
            self.check_time(width, height, spp)
            total = [width * height]
            chunker = Chunker(self.tracer, scene, sensor, self.memory_budget, ratio,
                              self._progress(total), terms, self.chunk_pixels)
            image = None
            if store is None or self.aa > 0:
                image = np.empty((width * height, 3), np.float32)

                def store(first, values):  # noqa: F811 (the default: assemble)
                    image[first:first + len(values)] = values

            def visit(start, count, color):
                store(start, dr.ravel(pixel_means(color, count, spp)).numpy().reshape(-1, 3))

            chunker.run(Job(width, height, spp), visit)
            plan = []
            if self.aa > 0:
                candidates = np.flatnonzero(antialias.contrast_mask(
                    image.reshape(height, width, 3), self.aa)).astype(np.uint32)
                for n in antialias.LEVELS:
                    if len(candidates) == 0:
                        break
                    total[0] += len(candidates)
                    # the refinement's rays, now that its pixels are known, count too
                    self.estimated_rays += ratio * len(candidates) * n * n
                    self.check_time(width, height, spp)
                    job = Job(width, height, n * n, pixels=candidates)
                    spread = np.empty(len(candidates), np.float32)

                    def visit_refined(start, count, color, job=job, spread=spread):
                        means, spreads = means_and_spread(color, count, job.spp)
                        image[job.pixels[start:start + count]] = \
                            dr.ravel(means).numpy().reshape(-1, 3)
                        spread[start:start + count] = spreads.numpy()

                    chunker.run(job, visit_refined)
                    plan.append((candidates, n))
                    candidates = candidates[spread > antialias.AGAIN * self.aa]
            self._plan = ((id(scene), width, height, spp, self.aa), plan)
            self.chunks = chunker.chunks_done
            self.rays_traced = chunker.rays_traced
            return None if image is None else image.reshape(height, width, 3)

    def render_image(self, scene, sensor=0, spp=0):
        """The (H, W, 3) image traced as one wavefront, unchunked and without anti-aliasing
        (differentiable when called with AD enabled): the reference the chunked render
        matches bit for bit, for images small enough."""
        sensor, spp, width, height = self._setup(scene, sensor, spp)
        color = self.tracer.trace(scene, camera_rays(sensor, width, height, spp))
        return box_filter(color, width, height, spp)

    # -- guards ----------------------------------------------------------------------------------
    def check(self, width, height, spp, assemble=True):
        """Refuse (BudgetError) an image whose output buffer cannot be held."""
        if width * height * 3 >= 1 << 32:
            raise BudgetError(f"{width} x {height} is too large for one image "
                              "(over 2^32 values); render it in tiles with a smaller size")
        if not assemble:
            return
        need = width * height * 3 * 4 * 2  # the float32 image (and its copy as a tensor)
        available = available_memory()
        if available is not None and need + min(self.memory_budget, available // 2) > available:
            raise BudgetError(f"a {width} x {height} float image needs {need / GIB:.1f} GB "
                              f"and only {available / GIB:.1f} GB is available: render a "
                              "smaller image, or to an 8-bit .png without --aa")

    def check_time(self, width, height, spp):
        """Refuse (BudgetError) a render whose estimated time is beyond ``time_limit``, or
        whose average pixel's ray tree alone exceeds the memory budget."""
        pixel = self.estimated_rays / (width * height) * BYTES_PER_RAY
        if pixel > self.memory_budget:
            raise BudgetError(
                f"depth {self.max_depth} at {spp} spp: the ray tree of a pixel needs about "
                f"{pixel / GIB:.3g} GB, over the memory budget ({self.memory_budget / GIB:.3g} "
                "GB): lower --max-depth or --spp, add a --bailout (e.g. 1e-3), or raise "
                "--memory-budget")
        seconds = self.estimated_rays / RAYS_PER_SECOND
        if self.time_limit > 0 and seconds > self.time_limit:
            raise BudgetError(
                f"{width} x {height} at {spp} spp, depth {self.max_depth}: about "
                f"{self.estimated_rays:.3g} rays, an estimated {_duration(seconds)} "
                f"(over the {_duration(self.time_limit)} limit): lower the size, --spp or "
                "--max-depth, add a --bailout, or raise --time-limit")

    # -- helpers -------------------------------------------------------------------------------
    def _setup(self, scene, sensor, spp):
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        spp = spp or sensor.sampler().sample_count()
        width, height = sensor.film().crop_size()
        return sensor, spp, width, height

    def _progress(self, total):
        if self.progress is None:
            return None
        return lambda done, chunks: self.progress(done, total[0], chunks)

    def _chunker(self, scene, sensor, spp):
        return Chunker(self.tracer, scene, sensor, self.memory_budget,
                       max_pixels=self.chunk_pixels)

    def _jobs(self, scene, sensor, spp):
        """The adjoint passes' jobs: (job, mask of the pixels it gives the value of, or None)."""
        _, spp, width, height = self._setup(scene, sensor, spp)
        plan = []
        if self.aa > 0:
            key = (id(scene), width, height, spp, self.aa)
            if self._plan is None or self._plan[0] != key:
                self.render_array(scene, sensor, spp)
            plan = self._plan[1]
        if not plan:
            return [(Job(width, height, spp), None)]
        refined = np.zeros(width * height, bool)
        refined[plan[0][0]] = True
        jobs = [(Job(width, height, spp), (~refined).astype(np.float32))]
        for k, (pixels, n) in enumerate(plan):
            later = np.zeros(width * height, bool)
            if k + 1 < len(plan):
                later[plan[k + 1][0]] = True
            final = pixels[~later[pixels]]
            if len(final):
                jobs.append((Job(width, height, n * n, pixels=final), None))
        return jobs


def _duration(seconds):
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
