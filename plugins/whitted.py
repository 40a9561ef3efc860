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
``render_forward``, which re-run the trace with AD enabled). Shadow rays walk
their crossings detached, in a symbolic loop; the transmittance's derivative
with respect to kt is attached in closed form (``with_kt_derivative``). A branch
whose weight is exactly 0 is not traced, so the derivative with respect to kr or
kt *at* 0 does not see the branch it would open.

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
import numpy as np

from .background import Background
from .light import Light
from .phong import FLOAT_PARAMS, phong_local

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


def with_kt_derivative(surfaces, transmittance, counts):
    """The shadow transmittance T = prod_s kt_s^n_s (n_s crossings of transparent surface s),
    computed detached, given its derivative with respect to the kt: dT = T sum_s n_s dkt_s / kt_s.
    Written as T prod_s (kt_s / detach(kt_s))^n_s, whose value is exactly T."""
    if not dr.grad_enabled(surfaces.refractivity):
        return transmittance
    for s, count in zip(surfaces.transparent_slots, counts):
        kt = dr.gather(mi.Float, surfaces.refractivity, mi.UInt32(s))
        transmittance = transmittance * dr.power(kt / dr.detach(kt), mi.Float(count))
    return transmittance


class Generation:
    """One depth of the ray tree, as the trace leaves it.

    Per lane (one lane per ray of this depth): ``local`` (L_local, or the
    background on a miss), the weights of the reflected and refracted children
    and, where a child exists (``has_r`` / ``has_t``), its lane in the next
    generation (``child_r`` / ``child_t``).
    """

    def __init__(self, local):
        self.local = local
        self.weight_r = self.child_r = self.has_r = None
        self.weight_t = self.child_t = self.has_t = None

    @property
    def has_children(self):
        return self.child_r is not None

    def subtree_color(self, deeper):
        """This generation's colors given the colors of the next one (None: no next one)."""
        if deeper is None or not self.has_children:
            return self.local
        return self.local + self.weight_r * dr.gather(mi.Color3f, deeper, self.child_r, self.has_r) \
            + self.weight_t * dr.gather(mi.Color3f, deeper, self.child_t, self.has_t)


class SceneTerms:
    """What shading needs from the scene, read from its plugins at the start of a render:
    the surfaces' parameters, the lights, the summed ambient light, the background."""

    def __init__(self, scene):
        self.surfaces = Surfaces(scene)
        self.smooth_meshes = [shape for shape in scene.shapes()
                              if shape.is_mesh() and shape.has_vertex_normals()]
        lights = [e for e in scene.emitters() if isinstance(e, Light)]
        backgrounds = [e for e in scene.emitters() if isinstance(e, Background)]
        self.background = backgrounds[0].color if backgrounds else mi.Color3f(0.0)
        self.ambient = mi.Color3f(0.0)
        for light in lights:
            if light.is_ambient:
                self.ambient += light.color
        self.direct = [light for light in lights if not light.is_ambient]


class Step:
    """What one generation computes for its rays: the local colors and, unless it is
    the deepest, the children's weights and rays (reflected and refracted, per lane)."""

    def __init__(self, local, hit, weights=None, rays=None):
        self.local, self.hit = local, hit
        self.weight_r, self.weight_t = weights if weights else (None, None)
        self.reflected, self.refracted = rays if rays else (None, None)


class Surfaces:
    """The parameters of every surface of a scene as arrays indexed by a *slot*.

    A surface is one BSDF of the scene: a ``rayphong`` material or a
    ``raytextured`` one. Instead of dispatching a virtual call per hit, the
    integrator maps the hit's BSDF pointer (its Dr.Jit registry id) to a slot and
    gathers the parameters from arrays built here from the materials' own
    (differentiable) values, at the start of every render. Only the textures are
    evaluated per surface, masked to the lanes that hit it.
    """

    def __init__(self, scene):
        bsdfs = {}
        for shape in scene.shapes():
            bsdf = shape.bsdf()
            bsdfs.setdefault(dr.reinterpret_array(mi.UInt32, mi.BSDFPtr(bsdf))[0], bsdf)
        ids = list(bsdfs)
        table = np.zeros(max(ids, default=0) + 1, dtype=np.uint32)
        table[ids] = np.arange(len(ids), dtype=np.uint32)
        self.slot_of_id = mi.UInt32(table)
        materials = [bsdf.material for bsdf in bsdfs.values()]
        self.textures = [(mi.UInt32(slot), bsdf.textures)
                         for slot, bsdf in enumerate(bsdfs.values()) if bsdf.textures]
        if not materials:  # a scene with no objects: one slot of zeros, never gathered from
            self.color = dr.zeros(mi.Color3f, 1)
            for name in FLOAT_PARAMS:
                setattr(self, name, dr.zeros(mi.Float, 1))
        else:
            self.color = mi.Color3f(*(dr.concat([mi.Float(m.color[c]) for m in materials])
                                      for c in range(3)))
            for name in FLOAT_PARAMS:
                setattr(self, name, dr.concat([mi.Float(getattr(m, name)) for m in materials]))
        # Surfaces that let shadow rays through (kt > 0), by slot.
        self.transparent_slots = [int(i) for i in np.flatnonzero(self.refractivity.numpy() > 0)]

    def slot(self, si, active):
        return self.slot_of(si.bsdf(), active)

    def slot_of(self, bsdf, active):
        """The slot of each lane's BSDF (a BSDFPtr: its values are Dr.Jit registry ids)."""
        return dr.gather(mi.UInt32, self.slot_of_id, dr.reinterpret_array(mi.UInt32, bsdf), active)

    def get(self, name, slot, active):
        return dr.gather(mi.Float, getattr(self, name), slot, active)

    def base_color(self, si, slot, active):
        """C at each hit: the material's color times the surface's textures."""
        color = dr.gather(mi.Color3f, self.color, slot, active)
        for surface_slot, textures in self.textures:
            mask = active & (slot == surface_slot)
            for texture in textures:
                color = dr.select(mask, color * texture.eval(si, mask), color)
        return color


class Whitted(mi.CppADIntegrator):
    def __init__(self, props):
        super().__init__(props)
        self.max_depth = int(props.get("max_depth", 5))
        self.max_shadow_crossings = int(props.get("max_shadow_crossings", 16))
        if self.max_depth < 0:
            raise ValueError("raywhitted: max_depth must be >= 0")
        self.progress = None  # optional callable(generations_done), set by the CLI
        self.rays_per_generation = []  # of the last render: how many rays each depth traced

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
        """The color of each ray of ``ray`` (one lane per ray) through its whole tree."""
        terms = SceneTerms(scene)
        generations = []
        self.rays_per_generation = []
        for depth in range(self.max_depth + 1):
            self.rays_per_generation.append(dr.width(ray))
            last = depth == self.max_depth
            step = self.step(scene, terms, ray, depth, not last)
            generation = Generation(step.local)
            generations.append(generation)
            if last:
                break
            ray = self.spawn(generation, step)
            if self.progress is not None:
                self.progress(depth + 1)
            if ray is None:
                break

        color = None
        for generation in reversed(generations):
            color = generation.subtree_color(color)
            dr.eval(color)  # once for all three channels: the next step gathers from each
        return color

    def step(self, scene, terms, ray, depth, children):
        """Intersect and shade ``ray``; with ``children``, also the children's weights and rays.
"""
        si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=(depth == 0))
        hit = si.is_valid()
        surfaces = terms.surfaces
        slot = surfaces.slot(si, hit)
        color = surfaces.base_color(si, slot, hit)
        local = self.shade(scene, terms, si, slot, color, ray)
        local = dr.select(hit, local, terms.background)
        if not children:
            return Step(local, hit)
        kr = surfaces.get("reflectivity", slot, hit)
        kt = surfaces.get("refractivity", slot, hit)
        eta = surfaces.get("ior", slot, hit)
        v = -ray.d
        n = self.facing_normal(si, ray)
        entering = dr.dot(si.n, ray.d) < 0
        refracted_d, tir = refract(v, n, dr.select(entering, dr.rcp(eta), eta))
        weights = (kr + dr.select(tir, kt, 0.0), dr.select(tir, 0.0, kt))
        rays = (si.spawn_ray(reflect(v, n)), si.spawn_ray(refracted_d))
        return Step(local, hit, weights, rays)

    def facing_normal(self, si, ray):
        """The shading normal flipped to the side the ray comes from."""
        n = si.sh_frame.n
        return dr.select(dr.dot(n, ray.d) > 0, -n, n)

    def shade(self, scene, terms, si, slot, color, ray):
        """L_local at each hit: ambient term plus each light's shadowed Phong term."""
        hit = si.is_valid()
        surfaces, lights = terms.surfaces, terms.direct
        result = terms.ambient * surfaces.get("ambient_mix", slot, hit) * color
        if not lights:
            return result
        kd = surfaces.get("diffuse_mix", slot, hit)
        ks = surfaces.get("specular_mix", slot, hit)
        exponent = surfaces.get("phong_coeff", slot, hit)
        n, v = self.facing_normal(si, ray), -ray.d
        lifted = self.lifted_point(terms.smooth_meshes, si, hit)
        for light in lights:
            wi, dist, intensity = light.illuminate(si.p)
            active = hit & (dr.dot(n, wi) > 0)
            transmittance = self.transmittance(scene, surfaces, si, wi, dist, active, lifted)
            phong = phong_local(n, v, wi, color, kd, ks, exponent)
            result += dr.select(active, intensity * phong * transmittance, 0.0)
        return result

    def lifted_point(self, smooth_meshes, si, active):
        """Where shadow rays leave a smooth-shaded mesh near its terminator (None: no such mesh).

        Where the shading normal faces a light but the flat facet that was hit does not,
        a shadow ray leaving the facet would run through the mesh's own far side and
        shadow a point that the contract says is lit (a convex object never shadows
        itself). Such a ray starts instead from the hit point lifted off its facet onto
        the smooth surface that the vertex normals describe (Hanika, "Hacking the shadow
        terminator", Ray Tracing Gems II, 2021): the barycentric average of its
        projections onto the tangent planes of the corners it lies below, then a ray
        epsilon out along the shading normal.
        """
        if not smooth_meshes:
            return None
        lifted = mi.Point3f(si.p)
        for mesh in smooth_meshes:
            mask = active & (si.shape == mi.ShapePtr(mesh))
            face = mesh.face_indices(si.prim_index, mask)
            corners = [mesh.vertex_position(face[k], mask) for k in range(3)]
            normals = [mesh.vertex_normal(face[k], mask) for k in range(3)]
            e1, e2, q = corners[1] - corners[0], corners[2] - corners[0], si.p - corners[0]
            d11, d12, d22 = dr.dot(e1, e1), dr.dot(e1, e2), dr.dot(e2, e2)
            q1, q2 = dr.dot(q, e1), dr.dot(q, e2)
            inv = dr.rcp(d11 * d22 - d12 * d12)
            w1, w2 = (d22 * q1 - d12 * q2) * inv, (d11 * q2 - d12 * q1) * inv
            p = mi.Point3f(si.p)
            for w, corner, n in zip((1.0 - w1 - w2, w1, w2), corners, normals):
                p -= w * dr.minimum(dr.dot(si.p - corner, n), 0.0) * n
            lifted = dr.select(mask, p, lifted)
        return lifted + (1.0 + dr.max(dr.abs(lifted))) * mi.math.RayEpsilon * si.sh_frame.n

    def transmittance(self, scene, surfaces, si, wi, dist, active, lifted=None):
        """Product of kt over the surfaces between si.p and the light (0 when blocked)."""
        ray = si.spawn_ray(wi)
        if lifted is not None:  # see lifted_point
            terminator = (dr.dot(si.sh_frame.n, wi) > 0) & (dr.dot(si.n, wi) <= 0)
            ray.o = dr.select(terminator, lifted, ray.o)
        ray.maxt = dist * (1.0 - mi.math.ShadowEpsilon)
        # The walk is detached: the parameters reach the transmittance only through the kt
        # of the surfaces crossed (*which* surfaces are crossed changes in jumps), and that
        # derivative is attached in closed form afterwards (see ``with_kt_derivative``).
        with dr.suspend_grad():
            # A cheap any-hit test first: most shadow rays cross nothing, and then the
            # transmittance is exactly 1. Only the others walk their crossings.
            blocked = scene.ray_test(ray, active)
            if not surfaces.transparent_slots:
                return dr.select(blocked, 0.0, 1.0)  # nothing lets light through
            transmittance, counts = self.crossings(scene, surfaces, ray, wi, active & blocked)
        return with_kt_derivative(surfaces, transmittance, counts)

    def crossings(self, scene, surfaces, ray, wi, active):
        """(Product of kt over the surfaces ``ray`` crosses, 0 past max_shadow_crossings;
        for each transparent surface, how many times the ray crossed it)."""
        slots = surfaces.transparent_slots

        def body(ray, transmittance, crossings, counts, active):
            # Only the distance and the BSDF of each crossing matter: a preliminary
            # intersection is enough. The next ray starts just past the crossing.
            crossing = scene.ray_intersect_preliminary(ray, coherent=False, active=active)
            crossed = active & crossing.is_valid()
            slot = surfaces.slot_of(crossing.shape.bsdf(), crossed)
            kt = surfaces.get("refractivity", slot, crossed)
            transmittance = dr.select(crossed, transmittance * kt, transmittance)
            counts = tuple(count + dr.select(crossed & (slot == s), 1, 0)
                           for count, s in zip(counts, slots))
            crossings += 1
            onward = crossed & (kt > 0)
            # Past max_shadow_crossings the light counts as blocked.
            transmittance = dr.select(onward & (crossings >= self.max_shadow_crossings),
                                      0.0, transmittance)
            p = ray(crossing.t)
            step = (1.0 + dr.max(dr.abs(p))) * mi.math.RayEpsilon
            ray = mi.Ray3f(dr.select(onward, p + step * ray.d, ray.o), ray.d,
                           dr.select(onward, ray.maxt - crossing.t - step, ray.maxt))
            return ray, transmittance, crossings, counts, \
                onward & (crossings < self.max_shadow_crossings)

        state = (ray, mi.Float(1.0), mi.UInt32(0), tuple(mi.UInt32(0) for _ in slots),
                 mi.Bool(active))
        _, transmittance, _, counts, _ = dr.while_loop(state, lambda *s: s[-1], body,
                                                       label="shadow ray")
        return transmittance, counts

    def spawn(self, generation, step):
        """Record the children of ``generation`` and return their rays (None: no children).

        A lane has a reflected (refracted) child where its weight is > 0; the children
        are compacted, reflected ones first, into the next generation's lanes."""
        weight_r, weight_t = step.weight_r, step.weight_t
        has_r, has_t = step.hit & (weight_r > 0), step.hit & (weight_t > 0)
        dr.eval(generation.local, weight_r, weight_t, has_r, has_t, step.reflected, step.refracted)
        index_r, index_t = dr.compress(has_r), dr.compress(has_t)
        count_r, count_t = dr.width(index_r), dr.width(index_t)
        if count_r + count_t == 0:
            return None
        generation.weight_r, generation.has_r = weight_r, has_r
        generation.weight_t, generation.has_t = weight_t, has_t
        generation.child_r = dr.prefix_sum(mi.UInt32(has_r))  # exclusive: rank among the lanes with a child
        # The count is data, not a constant of the kernels: it changes from render to render.
        first_t = dr.opaque(mi.UInt32, count_r)
        generation.child_t = dr.prefix_sum(mi.UInt32(has_t)) + first_t
        lane = dr.arange(mi.UInt32, count_r + count_t)
        is_t = lane >= first_t
        if count_r == 0 or count_t == 0:  # (a gather from an empty array is an error)
            parent = index_t if count_r == 0 else index_r
        else:  # not dr.concat: it would make count_r a constant of the kernel
            parent = dr.select(is_t, dr.gather(mi.UInt32, index_t, lane - first_t, is_t),
                               dr.gather(mi.UInt32, index_r, lane, ~is_t))
        reflected, refracted = step.reflected, step.refracted
        origin = dr.select(is_t, dr.gather(mi.Point3f, refracted.o, parent),
                           dr.gather(mi.Point3f, reflected.o, parent))
        direction = dr.select(is_t, dr.gather(mi.Vector3f, refracted.d, parent),
                              dr.gather(mi.Vector3f, reflected.d, parent))
        return mi.Ray3f(origin, direction)
