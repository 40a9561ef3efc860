"""``raywhitted``: the .RAY format's recursive (Whitted) ray tracer, differentiable.

For each camera ray it evaluates the format's deterministic ray tree::

    color(ray) = background                                   if the ray hits nothing
               = L_local + kr * color(reflected) + kt * color(refracted)   otherwise

    L_local = sum_ambient A ka C + sum_lights [N.L > 0] I(L) T(L) (kd C (N.L) + ks (R.V)^n)

where ``L_local`` comes from the surface's ``rayphong`` / ``raytextured`` BSDF
(``eval`` and ``eval_attribute_*``), I(L) from the ``raylight`` emitters and
T(L), the shadow-ray transmittance, is the product of the refractivity kt of
every surface the shadow ray crosses on its way to the light (the shaded
surface itself excluded).

Conventions, decided here:

* ``ray.d`` points away from the camera (or the previous hit); V = -ray.d.
  N is the shading normal flipped to face V; all directions are world space.
* Entering or leaving an object is decided by the *geometric* normal, which
  points to the object's outside (closed objects) or front side (planes and
  triangles): a ray with d . n_geo < 0 enters (eta_i = 1, eta_t = eta),
  otherwise it leaves (eta_i = eta, eta_t = 1). Media are not nested.
* On total internal reflection the kt share follows the mirror direction.
* Depth: the camera ray is generation 0; generations 1 .. ``max_depth`` are
  bounces; a ray beyond that adds nothing.

The tree is traced **generation by generation** (a wavefront): all rays of one
depth are intersected and shaded together; the reflected and refracted
children of the lanes that need them (weight > 0) are compacted with
``dr.compress`` into the next generation; and the colors are finally summed
from the deepest generation back to the camera with gathers only. No atomics
and no randomness: the image is bit-for-bit reproducible, and every step is
differentiable (reverse and forward mode through ``render_backward`` /
``render_forward``). A branch whose weight is exactly 0 is not traced, so the
derivative with respect to kr or kt *at* 0 does not see the branch it would open.

Pixel sampling: one sample per pixel goes through the pixel centre; ``spp = n^2``
samples use the centres of an n x n grid of strata; other counts are stratified
in x with a golden-ratio sequence in y. Samples are averaged with a box filter.

Parameters:

* ``max_depth`` (int, default 5): bounces after the camera ray
* ``max_shadow_crossings`` (int, default 16): a shadow ray that crosses more
  transparent surfaces than this is taken as blocked
"""

import drjit as dr
import mitsuba as mi

from .background import Background
from .light import Light

GOLDEN = 0.6180339887498949


def reflect(v, n):
    """Mirror direction of v (pointing away from the surface) about the unit normal n."""
    return 2.0 * dr.dot(n, v) * n - v


def refract(v, n, eta_ratio):
    """(Refracted direction, total internal reflection mask) by Snell's law.

    v points away from the surface on the incident side, n is the unit normal on
    that side (n . v > 0) and ``eta_ratio`` = eta_i / eta_t.
    """
    cos_i = dr.dot(n, v)
    sin2_t = dr.square(eta_ratio) * (1.0 - dr.square(cos_i))
    tir = sin2_t >= 1.0
    cos_t = dr.safe_sqrt(1.0 - sin2_t)
    return -eta_ratio * v + (eta_ratio * cos_i - cos_t) * n, tir


def stratum_offset(s, spp):
    """Position in [0, 1)^2 of sample s of ``spp`` within its pixel (see the module docstring)."""
    if spp == 1:
        return mi.Point2f(0.5, 0.5)
    n = int(round(spp ** 0.5))
    if n * n == spp:
        row = s // n
        return mi.Point2f((mi.Float(s - row * n) + 0.5) / n, (mi.Float(row) + 0.5) / n)
    x = (mi.Float(s) + 0.5) / spp
    y = dr.fma(mi.Float(s), GOLDEN, 0.5)
    return mi.Point2f(x, y - dr.floor(y))


class Generation:
    """One depth of the ray tree: local colors, and where each lane's children are."""

    def __init__(self, local, weight_r=None, child_r=None, has_r=None,
                 weight_t=None, child_t=None, has_t=None):
        self.local = local
        self.weight_r, self.child_r, self.has_r = weight_r, child_r, has_r
        self.weight_t, self.child_t, self.has_t = weight_t, child_t, has_t

    def color(self, deeper):
        """This generation's colors given the colors of the next one (None at the leaves)."""
        if deeper is None or self.child_r is None:
            return self.local
        reflected = dr.gather(mi.Color3f, deeper, self.child_r, self.has_r)
        refracted = dr.gather(mi.Color3f, deeper, self.child_t, self.has_t)
        return self.local + self.weight_r * reflected + self.weight_t * refracted


class Whitted(mi.CppADIntegrator):
    def __init__(self, props):
        super().__init__(props)
        self.max_depth = int(props.get("max_depth", 5))
        self.max_shadow_crossings = int(props.get("max_shadow_crossings", 16))
        self.progress = None  # optional callable(generations_done), set by the CLI
        if self.max_depth < 0:
            raise ValueError("raywhitted: max_depth must be >= 0")

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
        """The (H, W, 3) image: per-pixel box-filtered average of the camera rays' colors."""
        if isinstance(sensor, int):
            sensor = scene.sensors()[sensor]
        spp = spp or sensor.sampler().sample_count()
        width, height = sensor.film().crop_size()
        ray = self.camera_rays(sensor, width, height, spp)
        color = self.trace(scene, ray)
        pixel = dr.arange(mi.UInt32, width * height) * spp
        image = dr.gather(mi.Color3f, color, pixel)
        for s in range(1, spp):
            image += dr.gather(mi.Color3f, color, pixel + s)
        if spp > 1:
            image *= 1.0 / spp
        return mi.TensorXf(dr.ravel(image), shape=(height, width, 3))

    def camera_rays(self, sensor, width, height, spp):
        """Camera rays, pixel-major (all samples of pixel 0, then pixel 1...); row 0 is the top."""
        index = dr.arange(mi.UInt32, width * height * spp)
        pixel = index // spp
        offset = stratum_offset(index - pixel * spp, spp)
        row = pixel // width
        film_pos = mi.Point2f((mi.Float(pixel - row * width) + offset.x) / width,
                              (mi.Float(row) + offset.y) / height)
        ray, _ = sensor.sample_ray(time=0.0, sample1=0.5, sample2=film_pos, sample3=mi.Point2f(0.5))
        return mi.Ray3f(ray)

    # -- the ray tree --------------------------------------------------------------------------
    def trace(self, scene, ray):
        """Color of each ray of ``ray`` (one lane each) through the whole tree."""
        lights = [e for e in scene.emitters() if isinstance(e, Light)]
        backgrounds = [e for e in scene.emitters() if isinstance(e, Background)]
        background = backgrounds[0].color if backgrounds else mi.Color3f(0.0)
        ambient = mi.Color3f(0.0)
        for light in lights:
            if light.is_ambient:
                ambient += light.color
        direct = [light for light in lights if not light.is_ambient]

        generations = []
        for depth in range(self.max_depth + 1):
            si = scene.ray_intersect(ray)
            hit = si.is_valid()
            bsdf = si.bsdf(ray)
            local = dr.select(hit, self.shade(scene, si, bsdf, ray, ambient, direct), background)
            if depth == self.max_depth:
                generations.append(Generation(local))
                break
            generation, ray = self.spawn(si, bsdf, ray, hit, local)
            generations.append(generation)
            if self.progress is not None:
                self.progress(depth + 1)
            if ray is None:
                break

        color = None
        for generation in reversed(generations):
            color = generation.color(color)
        return color

    def facing_normal(self, si, ray):
        """The shading normal flipped to the side the ray comes from."""
        n = si.sh_frame.n
        return dr.select(dr.dot(n, ray.d) > 0, -n, n)

    def shade(self, scene, si, bsdf, ray, ambient, lights):
        """L_local at each hit: ambient term plus each light's shadowed Phong term."""
        hit = si.is_valid()
        color = ambient * bsdf.eval_attribute_3("ambient_reflectance", si, hit)
        if not lights:
            return color
        ctx = mi.BSDFContext()
        n = self.facing_normal(si, ray)
        for light in lights:
            wi, dist, intensity = light.illuminate(si.p)
            active = hit & (dr.dot(n, wi) > 0)
            phong = bsdf.eval(ctx, si, si.to_local(wi), active)
            transmittance = self.transmittance(scene, si, wi, dist, active)
            color += dr.select(active, intensity * phong * transmittance, 0.0)
        return color

    def transmittance(self, scene, si, wi, dist, active):
        """Product of kt over the surfaces between si.p and the light (0 when blocked)."""
        transmittance = mi.Float(1.0)
        ray = si.spawn_ray(wi)
        ray.maxt = dist * (1.0 - mi.math.ShadowEpsilon)
        active = mi.Bool(active)
        for _ in range(self.max_shadow_crossings):
            blocker = scene.ray_intersect(ray, active)
            crossed = active & blocker.is_valid()
            kt = blocker.bsdf(ray).eval_attribute_1("refractivity", blocker, crossed)
            transmittance = dr.select(crossed, transmittance * kt, transmittance)
            active = crossed & (kt > 0)
            if not dr.any(active):
                return transmittance
            remaining = ray.maxt - blocker.t
            ray = blocker.spawn_ray(wi)
            ray.maxt = remaining
        return dr.select(active, 0.0, transmittance)

    def spawn(self, si, bsdf, ray, hit, local):
        """This generation's record and the next generation's rays (None when there are none)."""
        kr = bsdf.eval_attribute_1("reflectivity", si, hit)
        kt = bsdf.eval_attribute_1("refractivity", si, hit)
        eta = bsdf.eval_attribute_1("ior", si, hit)
        v = -ray.d
        n = self.facing_normal(si, ray)
        entering = dr.dot(si.n, ray.d) < 0
        refracted_d, tir = refract(v, n, dr.select(entering, dr.rcp(eta), eta))
        weight_r = kr + dr.select(tir, kt, 0.0)
        weight_t = dr.select(tir, 0.0, kt)
        has_r, has_t = hit & (weight_r > 0), hit & (weight_t > 0)

        index_r, index_t = dr.compress(has_r), dr.compress(has_t)
        count_r, count_t = dr.width(index_r), dr.width(index_t)
        child_r = dr.prefix_sum(mi.UInt32(has_r))  # exclusive
        child_t = dr.prefix_sum(mi.UInt32(has_t)) + count_r
        generation = Generation(local, weight_r, child_r, has_r, weight_t, child_t, has_t)
        if count_r + count_t == 0:
            return generation, None

        reflected = si.spawn_ray(reflect(v, n))
        refracted = si.spawn_ray(refracted_d)
        source = dr.concat([index_r, index_t])
        is_t = dr.arange(mi.UInt32, count_r + count_t) >= count_r
        origin = dr.select(is_t, dr.gather(mi.Point3f, refracted.o, source),
                           dr.gather(mi.Point3f, reflected.o, source))
        direction = dr.select(is_t, dr.gather(mi.Vector3f, refracted.d, source),
                              dr.gather(mi.Vector3f, reflected.d, source))
        return generation, mi.Ray3f(origin, direction)
