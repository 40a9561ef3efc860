"""The budget of a render: what a ray costs, and the guards that refuse, before tracing, what
no budget can hold.

A refused request raises :class:`BudgetError`, one line saying why and what would work:

* an output buffer larger than the memory available (:func:`check_image`);
* a render whose average pixel's ray tree alone exceeds the memory budget, or whose
  estimated time is beyond the time limit (:class:`Estimate`): the rays are estimated
  from the probe's rays per camera ray (``chunks.probe``), job by job as the render's jobs
  become known (the first pass, then each anti-aliasing job), and their time at the rays
  per second of this scene on this machine (measured: see below).

**Rays per second** are measured, not assumed, for each scene: the probe's trace (about
10^3 camera rays, traced before every render anyway) is timed by the execution time of its
kernels in Dr.Jit's kernel history, so compilation, cache loads and Python are left out (on
the CPU and on a GPU alike), and a kernel held up by other work counts at a bound
(:func:`robust_seconds`). The rate is the scene's (a scene whose rays all miss traces them
far faster than one of mirrors and glass), measured by the first render of a loaded scene
and kept by its integrator for its later renders, so they are all judged alike; a request
is refused or not the same way on every run unless its estimate is within the machine's
noise (a factor well under 2) of the limit. The probe's kernels are small, so the rate
measured is a lower bound of what large chunks reach: the estimate errs on the long side.
Where nothing was measured (a probe of fewer than ``MEASURED_RAYS`` rays or too large to
trace, or another user of the kernel history, such as a test counting kernels, has it on:
its records are not taken from it) the rate is ``NOMINAL_RAYS_PER_SECOND``.
"""

import drjit as dr

from raymitsuba.options import GIB

# Memory per ray of a chunk's tree (what every generation keeps, the widest generation's
# transient arrays, Embree's and the allocator's share). Measured peaks on the benchmark
# scenes: 50-95 bytes per ray (primal), about 100 for a whole AD step, whose graph keeps
# every generation; the figures leave a margin of 2-6x, which the output buffer, an 8-bit
# encoder's copy of it and Dr.Jit's allocator cache share.
BYTES_PER_RAY = 200
BYTES_PER_RAY_AD = 640
# Anti-aliasing's rays carry their footprints through every bounce (differentials.py): each
# generation's children hold their offset rays too, and the first pass its signatures; a
# 2048 x 1536 render of scenes/aa_showcase.ray at a 256 MB budget peaked at 1.7 times the
# budget above the image's buffers with the primal's figure
FOOTPRINT_FACTOR = 2
NOMINAL_RAYS_PER_SECOND = 4e6  # the time guard's rate where none was measured
CLIP = 2.0  # a kernel counts at most this many times the probe's third longest (robust_seconds)
MEASURED_RAYS = 1000  # a probe of fewer rays measures nothing (one probe: <= 1024 pixels)

def timed(trace):
    """(``trace()``'s result, the rays per second of its kernels or None: not measured).
    ``trace()`` returns a trace whose ``rays_per_generation`` are known (so whose kernels
    have run); see the module docstring."""
    if dr.flag(dr.JitFlag.KernelHistory):  # someone else's records: left alone
        return trace(), None
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        result = trace()
        history = dr.kernel_history()
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    seconds = robust_seconds([float(k.get("execution_time", 0.0)) for k in history])
    rays = sum(result.rays_per_generation)
    return result, (rays / seconds if rays >= MEASURED_RAYS and seconds > 0 else None)


def robust_seconds(milliseconds):
    """The kernels' execution time (seconds) from their ``milliseconds``, each counted at
    most ``CLIP`` times the third longest: on a shared machine one of a probe's ~60 kernels
    is now and then held up by other work for 10-20x its time, which would make the
    measurement as many times too slow; a few kernels (the intersections) take most of
    the time, and do so alike."""
    if not milliseconds:
        return 0.0
    ceiling = CLIP * sorted(milliseconds)[-min(3, len(milliseconds))]
    return sum(min(t, ceiling) for t in milliseconds) / 1000.0


class BudgetError(RuntimeError):
    """A request no memory budget can hold (one pixel's tree, the output buffer...)."""


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


def bytes_per_ray(ad=False, footprint=False):
    """The memory a ray of a chunk's tree is counted at: traced with AD (``ad``) or not, its
    rays carrying footprints (``footprint``, anti-aliasing) or not."""
    return (BYTES_PER_RAY_AD if ad else BYTES_PER_RAY) * (FOOTPRINT_FACTOR if footprint else 1)


def check_image(width, height, memory_budget, assemble=True, corners=False):
    """Refuse (BudgetError) a ``width`` x ``height`` image whose output buffer cannot be
    held: too many values for one image or, when the image is ``assemble``d on the host,
    more memory than is available besides one chunk's ``memory_budget`` (with
    ``corners``: also the anti-aliasing's values and path signatures at the pixel corners,
    and its centres' signatures)."""
    if width * height * 3 >= 1 << 32:
        raise BudgetError(f"{width} x {height} is too large for one image "
                          "(over 2^32 values); render it in tiles with a smaller size")
    if not assemble:
        return
    need = width * height * 3 * 4 * 2  # the float32 image (and its copy as a tensor)
    if corners:  # float32 values and uint32 signatures at the (W + 1) x (H + 1) corners,
        # uint32 signatures at the pixels (signature.py)
        need += (width + 1) * (height + 1) * (3 + 1) * 4 + width * height * 4
    available = available_memory()
    if available is not None and need + min(memory_budget, available // 2) > available:
        raise BudgetError(f"a {width} x {height} float image needs {need / GIB:.1f} GB "
                          f"and only {available / GIB:.1f} GB is available: render a "
                          "smaller image, or to an 8-bit .png without --aa")


class Estimate:
    """The rays a render of a ``width`` x ``height`` image at ``spp`` samples per pixel will
    trace, counted as its jobs become known (:meth:`admit`), and the guards on them.

    ``rays_per_camera_ray``: the probe's estimate; ``max_depth``: the tree's depth (the
    messages name it); ``memory_budget``: bytes one chunk's tree may take; ``time_limit``:
    seconds (0: none); ``rays_per_second``: the scene's measured rate (None: the nominal
    one); ``ray_bytes``: what a ray of a chunk's tree is counted at (:func:`bytes_per_ray`)."""

    def __init__(self, rays_per_camera_ray, width, height, spp, max_depth, memory_budget,
                 time_limit, rays_per_second=None, ray_bytes=BYTES_PER_RAY):
        self.rays_per_camera_ray = rays_per_camera_ray  # the probe's estimate
        self.width, self.height = width, height  # the image
        self.spp = spp  # the render's samples per pixel
        self.max_depth = max_depth  # bounces after the camera ray
        self.memory_budget = memory_budget  # bytes one chunk's tree may take
        self.ray_bytes = ray_bytes  # what a ray of it is counted at (bytes_per_ray)
        self.time_limit = time_limit  # seconds of estimated time refused past (0: none)
        self.rays = 0.0  # the estimate: the rays of the jobs admitted so far
        # the time guard's rate: rays traced per second
        self.rays_per_second = rays_per_second or NOMINAL_RAYS_PER_SECOND

    def admit(self, pixels, samples):
        """Count a job of ``pixels`` pixels at ``samples`` samples each in the estimate, then
        refuse (BudgetError) the render if its average pixel's ray tree alone exceeds the
        memory budget, or if its estimated time is beyond the time limit."""
        self.rays += self.rays_per_camera_ray * pixels * samples
        pixel = self.rays / (self.width * self.height) * self.ray_bytes
        if pixel > self.memory_budget:
            raise BudgetError(
                f"depth {self.max_depth} at {self.spp} spp: the ray tree of a pixel needs about "
                f"{pixel / GIB:.3g} GB, over the memory budget ({self.memory_budget / GIB:.3g} "
                "GB): lower --max-depth or --spp, add a --bailout (e.g. 1e-3), or raise "
                "--memory-budget")
        rate = self.rays_per_second
        seconds = self.rays / rate
        if self.time_limit > 0 and seconds > self.time_limit:
            raise BudgetError(
                f"{self.width} x {self.height} at {self.spp} spp, depth {self.max_depth}: about "
                f"{self.rays:.3g} rays, an estimated {duration(seconds)} at {rate / 1e6:.2g} M "
                f"rays/s (over the {duration(self.time_limit)} limit): lower the size, --spp or "
                "--max-depth, add a --bailout, or raise --time-limit")


def duration(seconds):
    """``seconds`` as a message says it: seconds, minutes or hours."""
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"
