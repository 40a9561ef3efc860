"""``raywhitted``: the .RAY format's recursive (Whitted) ray tracer, differentiable.

For each camera ray it evaluates the format's deterministic ray tree::

    color(ray) = background                                   if the ray hits nothing
               = L_local + kr * color(reflected) + kt * color(refracted)   otherwise

    L_local = sum_ambient A ka C + sum_lights [N.L > 0] I(L) T(L) (kd C (N.L) + ks (R.V)^n)

where ``L_local`` comes from the parameters of the surface's ``rayphong`` /
``raytextured`` BSDF (read through ``_protocol.py``), I(L) from the ``raylight`` emitters and
T(L), the shadow-ray transmittance, is the product of the refractivity kt of
every surface the shadow ray crosses on its way to the light (the shaded
surface itself excluded).

The pieces, one idea per module:

* ``_camera.py``: which rays leave the camera for each pixel, and the box filter;
* ``_protocol.py``: what the integrator reads from surfaces, lights, background;
* ``_surfaces.py``: the surface table (every surface's parameters by slot), the
  lights and the background, read from the scene at the start of a render;
* ``_hits.py``: the surface interaction of each hit, by lookup in one table of the
  scene's geometry;
* ``_lift.py``: where shadow rays leave smooth meshes near their terminator;
* ``_tree.py``: the ray tree, traced generation by generation (a wavefront), with
  the conventions for directions, normals and entering/leaving decided there.

No atomics and no randomness: the image is bit-for-bit reproducible, and every
step is differentiable (reverse and forward mode through ``render_backward`` /
``render_forward``, which re-run the trace with AD enabled). Shadow rays walk
their crossings detached, in a symbolic loop; the transmittance's derivative
with respect to kt is attached in closed form (``with_kt_derivative``). A branch
whose weight is exactly 0 is not traced, so the derivative with respect to kr or
kt *at* 0 does not see the branch it would open.

Parameters:

* ``max_depth`` (int, default 5): bounces after the camera ray
* ``max_shadow_crossings`` (int, default 16): a shadow ray that crosses more
  transparent surfaces than this is taken as blocked
"""

import drjit as dr
import mitsuba as mi

from ._camera import box_filter, camera_rays
from ._tree import Tracer


class Whitted(mi.CppADIntegrator):
    def __init__(self, props):
        super().__init__(props)
        max_depth = int(props.get("max_depth", 5))
        if max_depth < 0:
            raise ValueError("raywhitted: max_depth must be >= 0")
        self.tracer = Tracer(max_depth, int(props.get("max_shadow_crossings", 16)))

    @property
    def max_depth(self):
        return self.tracer.max_depth

    @property
    def progress(self):
        """Optional callable(generations_done), set by the CLI."""
        return self.tracer.progress

    @progress.setter
    def progress(self, callback):
        self.tracer.progress = callback

    @property
    def rays_per_generation(self):
        """Of the last render: how many rays each depth traced."""
        return self.tracer.rays_per_generation

    # -- mi.Integrator interface ---------------------------------------------------------------
    def render(self, scene, sensor=0, seed=0, spp=0, develop=True, evaluate=True):
        with dr.suspend_grad():
            return self.render_image(scene, sensor, spp)

    def render_forward(self, scene, params, sensor=0, seed=0, spp=0):
        with dr.resume_grad():
            image = self.render_image(scene, sensor, spp)
            dr.forward_to(image)
            return dr.grad(image)

    def render_backward(self, scene, params, grad_in, sensor=0, seed=0, spp=0):
        with dr.resume_grad():
            image = self.render_image(scene, sensor, spp)
            dr.backward_from(image * grad_in)

    # -- the image -----------------------------------------------------------------------------
    def render_image(self, scene, sensor=0, spp=0):
        """The (H, W, 3) image: per-pixel box-filtered average of the camera rays' colors
        (differentiable when called with AD enabled)."""
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        spp = spp or sensor.sampler().sample_count()
        width, height = sensor.film().crop_size()
        color = self.tracer.trace(scene, camera_rays(sensor, width, height, spp))
        return box_filter(color, width, height, spp)
