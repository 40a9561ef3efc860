"""``raywhitted``: the .RAY format's recursive (Whitted) ray tracer, differentiable.

For each camera ray it evaluates the format's deterministic ray tree::

    color(ray) = background                                   if the ray hits nothing
               = L_local + kr * color(reflected) + kt * color(refracted)   otherwise

    L_local = sum_ambient A ka C + sum_lights [N.L > 0] I(L) T(L) (kd C (N.L) + ks (R.V)^n)

where ``L_local`` comes from the parameters of the surface's ``rayphong`` /
``raytextured`` BSDF (read through ``protocol.py``), I(L) from the ``raylight`` emitters and
T(L), the shadow-ray transmittance, is the product of the refractivity kt of
every surface the shadow ray crosses on its way to the light (the shaded
surface itself excluded). Its parts, one idea per module: the package index
(``plugins/whitted/__init__.py``).

A render (:meth:`Whitted.render_array`), step by step: the guard on the output buffer
(``guards.py``); the probe's estimate of the render's rays (``chunks.probe``), which the
guards refuse past the memory budget or the time limit; the first pass, traced in chunks
of camera rays within the memory budget (``chunks.py``) and assembled on the host (on the
device for :meth:`Whitted.render`, ``mi.render``'s, without waiting for the kernels), the
image of the one wavefront of ``render_image`` bit for bit; with ``aa`` > 0, adaptive
anti-aliasing of the pixels that differ from their neighbours (see ``antialias.py``).

No atomics and no randomness: the image is bit-for-bit reproducible, and every step is
differentiable: ``render_backward`` / ``render_forward`` re-trace the same chunks with AD
enabled (so a gradient step's memory is bounded too), each pixel with the samples its
value came from. Shadow rays walk their crossings detached, in a symbolic loop; the
transmittance's derivative with respect to kt is attached in closed form
(``with_kt_derivative``). A branch whose weight is exactly 0 is not traced, so the
derivative with respect to kr or kt *at* 0 does not see the branch it would open.

Parameters: the render options whose reader is the integrator; their list below, with
types, defaults and meanings, is made from :class:`raymitsuba.options.RenderOptions`,
where each is stated.
"""

from typing import NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from raymitsuba import options
from raymitsuba.options import RenderOptions

from . import antialias, boundary, guards, replay, support
from .arrays import Assembled, jit_array, jit_tensor
from .camera import box_filter, camera_rays, pixel_means
from .chunks import Chunker, Job, probe
from .tree import Tracer

__doc__ += options.describe(options.INTEGRATOR)

# An image that does not depend on a parameter whose gradient is enabled (a sphere turned
# about its centre, samples all flat in it) has the derivative 0 with respect to it: not an
# error (Dr.Jit's default, meant to catch a forgotten dr.enable_grad)
NO_DEPENDENCE_IS_ZERO = dr.ADFlag.AllowNoGrad


class RenderStats(NamedTuple):
    """What a render measured (``Whitted.stats``, of the last render)."""

    estimate: guards.Estimate = None  # the guards' estimate (None before any render)
    chunks: int = 0  # chunks traced
    rays_traced: int = 0  # rays of every chunk's tree
    rays_per_generation: tuple = ()  # of the last chunk traced: how many rays each depth traced


class Whitted(mi.CppADIntegrator):
    def __init__(self, props):
        super().__init__(props)
        options = RenderOptions.from_properties(props)  # defaults, ranges: raymitsuba.options
        # traces the ray trees (and keeps the scene tables' caches across renders)
        self.tracer = Tracer(options.max_depth, options.max_shadow_crossings, options.bailout,
                             options.ray_offset_scale, footprint=bool(options.aa))
        self.aa = options.aa or 0.0  # the adaptive anti-aliasing threshold (0: off)
        self.memory_budget = options.memory_budget  # bytes one chunk's ray tree may take
        # seconds of estimated render time past which a render is refused (0: no limit)
        self.time_limit = options.time_limit
        self.chunk_pixels = options.chunk_pixels or None  # at most this many pixels a chunk
        # this scene's rays per second, measured by the first render's probe and kept for
        # the later ones (guards.py; None: not measured yet)
        self.rays_per_second = None
        self.progress = None  # optional callable(pixels_done, pixels_total, chunks_done)
        self.stats = RenderStats()  # of the last render (also of a refused one: its estimate)
        # The anti-aliasing decisions of the last primal render (antialias.Plan; None: none
        # yet), which the adjoint passes of the same image follow
        self.plan = None
        # The first generation's ray queries of the last primal render, recorded where an
        # adjoint pass follows it (replay.Recording; None: none), and how many chunk traces
        # of the last adjoint pass replayed it
        self.recording = None
        self.replayed = 0
        # The boundary terms' keys of every lattice sample of that render, recorded by it
        # (boundary.Boundary; None: none), which its next adjoint pass adopts instead of
        # recording them itself (see _boundary)
        self.keys = None

    @property
    def max_depth(self):
        return self.tracer.max_depth

    # -- the last render's figures (stats) -------------------------------------------------------
    @property
    def chunks(self):
        return self.stats.chunks

    @property
    def rays_traced(self):
        return self.stats.rays_traced

    @property
    def estimated_rays(self):
        """The guards' estimate of the rays of the last render (None: no render yet)."""
        return None if self.stats.estimate is None else self.stats.estimate.rays

    @property
    def rays_per_generation(self):
        """Of the last chunk traced: how many rays each depth traced."""
        return self.stats.rays_per_generation

    # -- mi.Integrator interface ---------------------------------------------------------------
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        if self.aa > 0:  # (refined on the host)
            return jit_tensor(self.render_array(scene, sensor, spp))  # (aligned: arrays.py)
        # Kept on the device, each chunk's pixels evaluated there without waiting for them:
        # what follows (a loss, an adjoint pass's graph) is built while the kernels run.
        _, _, width, height = self._setup(scene, sensor, spp)
        image = Assembled(mi.Float, width * height * 3)
        self.render_array(scene, sensor, spp, on_device=True,
                          store=lambda first, values: image.add(3 * first, values))
        return mi.TensorXf(image.array, shape=(height, width, 3))

    def render_forward(self, scene, params, sensor=0, seed=0, spp=0):
        sensor, spp, width, height = self._setup(scene, sensor, spp)
        grads = np.zeros((width * height, 3), np.float32)
        chunker = self._adjoint_chunker(scene, sensor)
        edges = self._boundary(scene, sensor, spp, width, height)  # (issue 13) or None
        jobs = self._adjoint_jobs(scene, sensor, spp, width, height, edges)
        replays = self._replay(scene, sensor, spp, width, height)
        recording = edges is not None and not edges.adopted  # its keys, by this pass
        for j, (job, _) in enumerate(jobs):
            last_job = j == len(jobs) - 1 and edges is None

            def visit(start, count, color, job=job, last_job=last_job):
                if recording:
                    edges.collect(job, start, count, color)
                with dr.resume_grad():
                    means = pixel_means(color, count, job.spp)
                    last = last_job and start + count == job.count
                    # the parameters' tangents stay for the next chunk; the last one clears them
                    flags = dr.ADFlag.Default if last else \
                        dr.ADFlag.ClearEdges | dr.ADFlag.ClearInterior
                    dr.forward_to(means, flags=flags | NO_DEPENDENCE_IS_ZERO)
                    grad = dr.ravel(dr.grad(means)).numpy().reshape(-1, 3)
                grads[job.pixel_index(start, count).numpy()] = grad

            chunker.run(job, visit, ad=True, record=edges.recorder(job) if recording else None,
                        queries=None if replays is None else replays(job))
        if edges is not None:
            edges.forward(grads, last=True)
        return jit_tensor(grads.reshape(height, width, 3))

    def render_backward(self, scene, params, grad_in, sensor=0, seed=0, spp=0):
        sensor, spp, width, height = self._setup(scene, sensor, spp)
        chunker = self._adjoint_chunker(scene, sensor)
        grad_in = mi.Float(dr.detach(grad_in.array if isinstance(grad_in, mi.TensorXf)
                                     else mi.TensorXf(grad_in).array))
        edges = self._boundary(scene, sensor, spp, width, height)  # (issue 13) or None
        replays = self._replay(scene, sensor, spp, width, height)
        recording = edges is not None and not edges.adopted  # its keys, by this pass
        for job, weights in self._adjoint_jobs(scene, sensor, spp, width, height, edges):
            # pixels refined later take their value (and their gradient) from a later job
            grad = grad_in if weights is None else grad_in * jit_array(mi.Float, np.repeat(weights, 3))
            # evaluated now, alone: a chunk's first gather from it would otherwise evaluate it
            # with whatever that chunk's trace had pending (its recorded keys: a kernel that
            # traces the chunk's rays, which the backward kernel then traces again)
            dr.eval(grad)

            def visit(start, count, color, job=job, grad=grad):
                with dr.resume_grad():
                    # the adjoint of the box filter, each lane's share of its pixel's: so the
                    # colors (not gathered from) are evaluated with the derivative, in its kernel
                    share = dr.gather(mi.Color3f, grad, job.lane_pixel(start, count))
                    if job.spp > 1:
                        share *= 1.0 / job.spp
                    dr.schedule(color)
                    dr.backward_from(color * share,
                                     flags=dr.ADFlag.Default | NO_DEPENDENCE_IS_ZERO)
                if recording:
                    edges.collect(job, start, count, color)

            chunker.run(job, visit, ad=True, lazy=True,
                        record=edges.recorder(job) if recording else None,
                        queries=None if replays is None else replays(job))
        if edges is not None:
            edges.backward(grad_in.numpy().reshape(-1, 3))

    # -- the image -----------------------------------------------------------------------------
    def render_array(self, scene, sensor=0, spp=0, store=None, rows=None, on_device=False):
        """The image as a numpy float32 (H, W, 3) array, traced chunk by chunk (detached).

        ``store``: optional callable(first_pixel, values) that receives each chunk's pixels
        (float32, (count, 3)) instead: then nothing is assembled and None is returned
        (not with anti-aliasing, which needs the whole first pass). ``on_device``: the
        ``store`` receives them as a Dr.Jit Float (count 3 values, pixel-major), their
        kernel launched, not waited for (not with anti-aliasing).

        ``rows``: optional (top, bottom): only the image's rows top .. bottom - 1, a band
        of (bottom - top, W, 3), the same values, bit for bit, as those rows of the whole
        image (a pixel's value does not depend on its chunk; with anti-aliasing the first
        pass also traces the MARGIN rows above and below, whose samples decide the band's
        edge rows). A band's render keeps no anti-aliasing plan (no adjoint pass follows it)."""
        with dr.suspend_grad():
            sensor, spp, width, height = self._setup(scene, sensor, spp)
            top, bottom = (0, height) if rows is None else rows
            if not 0 <= top < bottom <= height:
                raise ValueError(f"rows {top} .. {bottom - 1} are not within the image's "
                                 f"{height} rows")
            # the rows traced by the first pass: the band, with its neighbours' for --aa
            lo, hi = (max(top - antialias.MARGIN, 0), min(bottom + antialias.MARGIN, height)) \
                if self.aa > 0 else (top, bottom)
            assemble = store is None or self.aa > 0
            # (on the device, the image is assembled there: the same memory)
            guards.check_image(width, hi - lo, self.memory_budget, assemble or on_device,
                               self.aa > 0)
            terms = self.tracer.scene_terms(scene)
            estimate = self._estimate(scene, sensor, width, height, spp, terms)
            self.stats = RenderStats(estimate)  # (its estimate is read even if refused)
            estimate.admit(width * (hi - lo), spp)  # the first pass
            chunker = Chunker(self.tracer, scene, sensor, self.memory_budget,
                              estimate.rays_per_camera_ray, self.progress, terms,
                              self.chunk_pixels)
            image = np.empty((width * (hi - lo), 3), np.float32) if assemble else None
            # (the last render's: replaced once this one is complete)
            self.recording = self.keys = None
            recording = None if rows is not None else \
                self._recording(scene, sensor, spp, width, height, terms)
            keys = None if recording is None else \
                self._keys(scene, sensor, spp, width, height, terms)
            # the pixel centres' path signatures, which anti-aliasing compares with its corners'
            signatures = np.empty(width * (hi - lo), np.uint32) \
                if self.aa > 0 and spp == 1 else None
            first_pass(chunker, Job(width, height, spp, lo * width, width * (hi - lo)),
                       assemble_into(image) if assemble else
                       store if on_device else on_host(store),
                       None if recording is None else
                       lambda start, count, terms:
                       recording.recorder((lo * width + start) * spp, count * spp), keys,
                       signatures, antialias.least_weight(self.aa))
            self.recording, self.keys = recording, keys
            if self.aa > 0:
                plan = antialias.refine(
                    image.reshape(hi - lo, width, 3), spp, self.aa, chunker, estimate, height,
                    lo, (top, bottom),
                    None if signatures is None else signatures.reshape(hi - lo, width))
                self.plan = plan if rows is None else None
            self.stats = RenderStats(estimate, chunker.chunks_done, chunker.rays_traced,
                                     chunker.rays_per_generation)
            if image is None:
                return None
            image = image.reshape(hi - lo, width, 3)
            return image if (lo, hi) == (top, bottom) else image[top - lo:bottom - lo]

    def render_image(self, scene, sensor=0, spp=0):
        """The (H, W, 3) image traced as one wavefront, unchunked and without anti-aliasing
        (differentiable when called with AD enabled): the reference the chunked render
        matches bit for bit, for images small enough."""
        sensor, spp, width, height = self._setup(scene, sensor, spp)
        trace = self.tracer.trace(scene, camera_rays(sensor, width, height, spp),
                                  self.tracer.scene_terms(scene))
        self.stats = self.stats._replace(rays_per_generation=trace.rays_per_generation)
        return box_filter(trace.color, width, height, spp)

    # -- helpers -------------------------------------------------------------------------------
    def _setup(self, scene, sensor, spp):
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        spp = spp or sensor.sampler().sample_count()
        width, height = sensor.film().crop_size()
        return sensor, spp, width, height

    def _estimate(self, scene, sensor, width, height, spp, terms):
        """The guards' estimate of a render, from the probe's rays per camera ray (no job
        admitted yet)."""
        rays, rate = probe(self.tracer, scene, sensor, width, height, spp, terms)
        self.rays_per_second = self.rays_per_second or rate
        return guards.Estimate(rays, width, height, spp, max_depth=self.max_depth,
                               memory_budget=self.memory_budget, time_limit=self.time_limit,
                               rays_per_second=self.rays_per_second,
                               ray_bytes=guards.bytes_per_ray(footprint=self.tracer.footprint))

    def _boundary(self, scene, sensor, spp, width, height):
        """(issue 13) The boundary terms of an adjoint pass (boundary.Boundary), or None where
        no parameter moves an edge. They need the uniform k x k lattice of spp = k^2: with
        anti-aliasing (whose samples differ from pixel to pixel) or another sample count, a
        derivative with respect to the geometry or the camera is refused."""
        kinds = boundary.moving_kinds(self.tracer, scene)
        if not kinds:
            return None
        if self.aa > 0 or boundary.lattice_side(spp) is None:
            if self.tracer.geometry_ad is None:
                return None  # light positions alone: the interior derivative, as before
            raise ValueError(
                "derivatives with respect to the geometry or the camera need the uniform "
                f"sample lattice of --spp k^2 (got spp={spp}"
                + (", with --aa" if self.aa > 0 else "") + "): their edges' terms are "
                "computed between neighbouring lattice samples")
        edges = boundary.Boundary(self.tracer, scene, sensor, width, height, spp,
                                  self.memory_budget, kinds)
        # the keys the last primal render recorded, if they are this pass's: the same image
        # of the same geometry, camera and lights (the recording's token; once)
        keys, self.keys = self.keys, None
        if keys is not None and self.recording is not None and self.recording.matches(
                replay.token(scene, sensor, width, height, spp), edges.terms.geometry.key):
            edges.adopt(keys)
        return edges

    def _keys(self, scene, sensor, spp, width, height, terms):
        """(issue 13) A boundary.Boundary to record the keys of a primal render's samples
        (``Boundary.recorder``, ``collect``), for the adjoint pass after it to adopt (see
        :meth:`_boundary`), where that pass need not trace every sample (only shapes move:
        ``support.py``); else None, and where the keys would not fit in the memory budget
        (the adjoint pass then refuses them, as it would)."""
        with dr.resume_grad():  # (a primal render is detached: the keys' flags are read here)
            if boundary.lattice_side(spp) is None or \
                    not support.only_shapes_move(self.tracer, scene, terms.surfaces):
                return None  # (no lattice: the adjoint pass refuses the boundary terms)
            kinds = boundary.moving_kinds(self.tracer, scene)
            try:
                return boundary.Boundary(self.tracer, scene, sensor, width, height, spp,
                                         self.memory_budget, kinds, terms)
            except guards.BudgetError:
                return None

    def _recording(self, scene, sensor, spp, width, height, terms):
        """A replay.Recording for this render's first generation, or None: recorded where an
        adjoint pass with the boundary terms follows (some key with its gradient enabled
        moves an edge: the geometry, the camera, a light, eta), the geometry is all in the
        table, there is no anti-aliasing and it fits in a quarter of the memory budget (see
        replay.py)."""
        with dr.resume_grad():  # (a primal render is detached: its keys' flags are read here)
            moves = bool(boundary.moving_kinds(self.tracer, scene))
        lanes, lights = width * height * spp, len(terms.direct)
        if not moves or self.aa > 0 or not terms.geometry.supported \
                or replay.recording_bytes(lanes, lights) > self.memory_budget / 4:
            return None
        return replay.Recording(replay.token(scene, sensor, width, height, spp),
                                terms.geometry.key)

    def _replay(self, scene, sensor, spp, width, height):
        """A callable(job) giving the ``queries`` of an adjoint pass's chunks of a job
        (``Chunker.run``): the last primal render's recording, replayed in each chunk whose
        geometry table is that render's, if the camera, lights, size and samples are too;
        or None (traced). Counts the chunk traces that replay in :attr:`replayed`."""
        recording, self.replayed = self.recording, 0
        if recording is None or self.aa > 0:
            return None
        token = replay.token(scene, sensor, width, height, spp)

        def replays(job):
            def queries(start, count, terms):
                if not recording.matches(token, terms.geometry.key):
                    return None
                self.replayed += 1
                return recording.replayer(job.lanes(start, count))

            return queries

        return replays

    def _adjoint_chunker(self, scene, sensor):
        return Chunker(self.tracer, scene, sensor, self.memory_budget,
                       max_pixels=self.chunk_pixels)

    def _adjoint_jobs(self, scene, sensor, spp, width, height, edges=None):
        """The adjoint passes' jobs: the primal render's, each with the weights of the pixels
        it gives the value of (None: all its pixels; see antialias.Plan.adjoint_jobs); only
        the pixels whose interior derivative may not be zero where ``edges`` (the pass's
        boundary terms) adopted the samples' keys and only shapes move (``support.py``)."""
        if self.aa <= 0:
            pixels = None
            if edges is not None and edges.adopted and \
                    support.only_shapes_move(self.tracer, scene, edges.terms.surfaces):
                pixels = support.interior_pixels(self.recording, edges, spp)
            return [(Job(width, height, spp, pixels=pixels), None)]
        if self.plan is None or not self.plan.is_for(sensor, width, height, spp, self.aa):
            # No plan of this image: the adjoint pass is not after its primal render (e.g.
            # render_backward called by itself). The primal is rendered again, deliberately:
            # the adjoint must re-trace each pixel with the samples its value came from.
            self.render_array(scene, sensor, spp)
        return self.plan.adjoint_jobs()


def on_host(store):
    """A first pass's ``store`` of the chunks' pixels as a numpy (count, 3) array, from
    ``store(first, values)`` of such arrays."""
    def to_host(first, values):
        store(first, values.numpy().reshape(-1, 3))

    return to_host


def assemble_into(image):
    """A first pass's ``store`` that writes each chunk's pixels into ``image`` ((H * W, 3))."""
    return on_host(lambda first, values: image.__setitem__(slice(first, first + len(values)),
                                                         values))


def first_pass(chunker, job, store, queries=None, keys=None, signatures=None, least_weight=None):
    """Trace ``job`` through ``chunker``, each chunk's box-filtered pixels (a Float of count
    3 values, evaluated) handed to ``store(first_pixel, values)`` (``queries``: see
    ``Chunker.run``; ``keys``: a boundary.Boundary that records its samples' keys and
    colors, or None; ``signatures``: a numpy uint32 array, by the job's pixel, that receives
    each one's path signature (one sample per pixel; ``least_weight``: see
    ``Tracer.trace``'s ``signed``), or None)."""
    def visit(start, count, color, signature=None):
        if keys is not None:
            keys.collect(job, start, count, color)
        values = dr.ravel(pixel_means(color, count, job.spp))
        dr.eval(values)  # (launched, not waited for: the chunk's tree is freed)
        store(start, values)
        if signature is not None:
            signatures[start:start + count] = signature.numpy()

    chunker.run(job, visit, queries=queries,
                record=None if keys is None else keys.recorder(job),
                signed=None if signatures is None else least_weight)

