"""The ray tree of the Whitted integrator, traced generation by generation.

All rays of one depth are intersected and shaded together; the reflected and
refracted children of the lanes that need them (weight > 0) are compacted with
``dr.compress`` into the next generation; the colors are finally summed from the
deepest generation back to the first with gathers only (no atomics, no randomness).

Conventions, decided here once:

* ``ray.d`` points away from the camera (or the previous hit); V = -ray.d.
  N is the shading normal flipped to face V; all directions are world space.
* Entering or leaving an object is decided by the *geometric* normal, which
  points to the object's outside (closed objects) or front side (planes and
  triangles): a ray with d . n_geo < 0 enters (eta_i = 1, eta_t = eta),
  otherwise it leaves (eta_i = eta, eta_t = 1). Media are not nested.
* On total internal reflection the kt share follows the mirror direction.
* Depth: the first generation is 0; generations 1 .. ``max_depth`` are bounces;
  a ray beyond that adds nothing.
"""

from typing import NamedTuple

import drjit as dr
import mitsuba as mi

from raymitsuba.util import no_cyclic_gc

from . import bailout, signature
from .differentials import offset_children
from .hits import NO_SHAPE, HitTable
from .lift import lifted_point
from .surfaces import NO_SLOT, SceneTerms, with_kt_derivative
from ..phong import phong_local


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


class Generation:
    """One depth of the ray tree, as the trace leaves it (one lane per ray of this depth).

    Where a lane has a reflected (refracted) child, ``has_r`` (``has_t``), the child is at
    lane ``child_r`` (``child_t``) of the next generation; without any child in the
    generation, the children's fields stay None."""

    def __init__(self, local):
        self.local = local  # Color3f: L_local, or the background on a miss
        self.signature = None  # UInt32: the lane's own hit's signature (signature.py), or None
        self.path_weight = None  # Float, detached: the lanes' path weights, where tracked
        self.weight_r = None  # Float: the reflected child's weight (kr, + kt on total reflection)
        self.has_r = None  # Bool: whether the lane has a reflected child
        self.child_r = None  # UInt32: the reflected child's lane in the next generation
        self.weight_t = None  # Float: the refracted child's weight (kt; 0 on total reflection)
        self.has_t = None  # Bool: whether the lane has a refracted child
        self.child_t = None  # UInt32: the refracted child's lane in the next generation

    @property
    def has_children(self):
        return self.child_r is not None

    def subtree_signature(self, deeper, least_weight):
        """This generation's path signatures given the next one's (None: no next one), in
        which a child counts where its path weight exceeds ``least_weight``."""
        if deeper is None or not self.has_children:
            return self.signature
        counts_r = self.has_r & (self.path_weight * dr.detach(self.weight_r) > least_weight)
        counts_t = self.has_t & (self.path_weight * dr.detach(self.weight_t) > least_weight)
        return signature.with_children(self.signature, (
            (dr.gather(mi.UInt32, deeper, self.child_r, counts_r), counts_r),
            (dr.gather(mi.UInt32, deeper, self.child_t, counts_t), counts_t)))

    def subtree_color(self, deeper):
        """This generation's colors given the colors of the next one (None: no next one)."""
        if deeper is None or not self.has_children:
            return self.local
        return self.local + self.weight_r * dr.gather(mi.Color3f, deeper, self.child_r, self.has_r) \
            + self.weight_t * dr.gather(mi.Color3f, deeper, self.child_t, self.has_t)


class Step:
    """What one generation computes for its rays: the local colors and, unless it is
    the deepest, the children's weights and rays (reflected and refracted, per lane)."""

    def __init__(self, local, hit, weights=None, rays=None, signature=None):
        self.local, self.hit = local, hit
        self.signature = signature  # UInt32: the hits' own signatures (signature.py), or None
        self.weight_r, self.weight_t = weights if weights else (None, None)
        self.reflected, self.refracted = rays if rays else (None, None)


class Trace(NamedTuple):
    """What :meth:`Tracer.trace` returns."""

    color: mi.Color3f  # of each ray of the batch (one lane per ray), through its whole tree
    rays_per_generation: list  # how many rays each depth traced (the first: the batch)
    signature: object = None  # UInt32: each ray's path signature (signature.py), if asked


class Walk(NamedTuple):
    """A shadow ray's walk through the surfaces it crosses (``Tracer.crossings``)."""

    transmittance: mi.Float  # the product of kt over the crossings; 0 where blocked
    slots: tuple  # max_shadow_crossings UInt32: the slot of each crossing the light passed,
    # in order, NO_SLOT past the last (None: not recorded)
    stopper: mi.Vector2u  # (shape, prim) of the surface that blocks the light: kt <= 0, or
    # the crossing past max_shadow_crossings; shape NO_SHAPE (and prim 0) where the light
    # gets through and on lanes the walk did not run (None: not asked)


class Shadow(NamedTuple):
    """A light's shadow rays from the first generation's hits, as ``Tracer.trace``'s
    ``first_hit`` receives them."""

    blocker: mi.PreliminaryIntersection3f  # the closest surface between the hit and the light
    stopper: mi.Vector2u  # in a scene with glass, where the light stops (Walk.stopper) where
    # it is blocked; None without glass (the blocker stops it)


class TreeTooLarge(Exception):
    """The ray tree would hold more rays than ``max_rays`` (generation ``depth``, of
    ``lanes`` rays, would take it past); ``rays_per_generation``: the generations traced."""

    def __init__(self, depth, lanes, rays_per_generation):
        super().__init__(f"generation {depth} of the ray tree has {lanes} rays")
        self.depth, self.lanes = depth, lanes
        self.rays_per_generation = rays_per_generation


class Tracer:
    """Traces the ray tree of a batch of rays (see the module docstring).

    ``max_depth``: bounces after the first generation; ``max_shadow_crossings``: a shadow
    ray that crosses more transparent surfaces than this is taken as blocked;
    ``bailout``: which children are not traced (see bailout.py): None, the bounded rule;
    0, none (every child of weight > 0: the exact tree); p > 0, those whose path weight
    (the product of the kr / kt weights from the camera ray down to them) is at most p;
    ``offset_scale``: secondary and shadow rays start this many times Mitsuba's ray
    epsilon off the surface (1: ``si.spawn_ray`` itself).
    """

    def __init__(self, max_depth, max_shadow_crossings, bailout, offset_scale=1.0,
                 footprint=False):
        self.max_depth = max_depth  # bounces after the first generation
        # whether camera rays carry their samples' footprints (anti-aliasing): a checkerboard
        # seen directly, or in mirrors and through glass (their children carry them on:
        # differentials.py), is then averaged over each sample's footprint (checker_filtered)
        self.footprint = footprint
        # secondary and shadow rays start this many ray epsilons off the surface (see spawn_ray)
        self.offset_scale = offset_scale
        self.max_shadow_crossings = max_shadow_crossings  # past this many, a shadow ray is blocked
        self.bailout = bailout  # the option: None (bounded), 0 (exact) or a path weight
        # Caches across renders, each keyed by the scene's shapes (see scene_terms):
        self.geometry = HitTable()  # the geometry table: rebuilt when the shapes change
        self.surfaces = None  # the last surface table: its layout serves the same shapes again
        # Hook (issue 13): the parameter keys that move shapes and the camera
        # (geometry_ad.GeometryAD, set by raymitsuba.parameters; None: none)
        self.geometry_ad = None

    def scene_terms(self, scene):
        """What shading needs from ``scene`` (its SceneTerms, with the geometry table), built
        once per render and shared by its chunks."""
        with no_cyclic_gc():  # a Python pass over every shape and surface
            terms = SceneTerms(scene, self.surfaces, self.geometry, self.geometry_ad)
        self.surfaces = terms.surfaces
        return terms

    def trace(self, scene, ray, terms, max_rays=None, lazy=False, first_hit=None, queries=None,
              signed=None, coherent=True):
        """The :class:`Trace` of each ray of ``ray`` (one lane per ray) through its whole
        tree, with the scene's ``terms`` (from :meth:`scene_terms`). ``max_rays``: a tree of
        more rays than this raises :class:`TreeTooLarge` (None: no limit). ``lazy``: the
        camera rays' colors are left unevaluated, for a caller that evaluates them with what
        it computes from them (an adjoint pass: with the derivative, in its kernel); a gather
        from them would evaluate them alone. ``first_hit``: optional callable(si, ray, hit,
        shadows) given the first generation's hits and, per light, its shadow rays'
        :class:`Shadow` (their closest blocker; in a scene with glass, where the light
        stops), lazily, as they are traced (the
        boundary terms' keys, boundary/samples.py, computed in the same kernel). ``queries``:
        optional: who answers the first generation's ray queries (``camera(scene, ray,
        coherent)``: each ray's closest hit; ``shadow(scene, light, ray, active)``: the
        closest blocker of light number ``light``'s shadow rays), recorded or replayed
        (replay.py); None: the ray tracer, and an any-hit test for the shadow rays where
        no ``first_hit`` wants their blockers. ``signed``: None, or the Trace has each ray's
        path signature (signature.py; anti-aliasing's first pass) in which a subtree counts
        where its path weight (the product of the kr / kt weights from the camera ray down
        to it) exceeds ``signed``. ``coherent``: the camera rays are intersected as coherent
        packets (Embree's packet traversal, packets of the vector width, 16 lanes with
        AVX-512: faster for neighbouring rays, but an exact tie between two surfaces,
        coincident faces or a ray through a shared edge, may resolve by the ray's packet
        mates); False: each ray alone, for rays whose packets depend on how the image is cut
        (chunks.Job's ``coherent``)."""
        # (no kr or kt > 0: one generation, no child to bail out; the bound reads the lights'
        # colors on the host, which waits for every kernel queued)
        limits = None if not terms.surfaces.any_specular else \
            bailout.path_weight_limits(self.bailout, terms, self.max_depth,
                                       self.max_shadow_crossings)
        # (signed: the path weights tell which subtrees count in a signature; no bailout, no
        # limit: every child of weight > 0 is traced, as without them)
        path_weight = None if limits is None and signed is None else mi.Float(1.0)
        generations, rays_per_generation = [], []
        if self.geometry_ad is not None:  # hook (issue 13): the camera keys' derivatives
            ray = self.geometry_ad.camera_rays(ray)
        for depth in range(self.max_depth + 1):
            rays_per_generation.append(dr.width(ray))
            # (no kr or kt > 0 in the scene: no ray has a child, the tree is one generation)
            last = depth == self.max_depth or not terms.surfaces.any_specular
            step = self.step(scene, terms, ray, depth, not last,
                             *((first_hit, queries) if depth == 0 else (None, None)), signed,
                             coherent and depth == 0)
            generation = Generation(step.local)
            generation.signature, generation.path_weight = step.signature, path_weight
            generations.append(generation)
            if last:
                break
            # The limit is data, not a constant of the kernels: a new value compiles nothing.
            limit = None if path_weight is None else \
                dr.opaque(mi.Float, -1.0 if limits is None else limits[depth])
            ray, path_weight = self.spawn(generation, step, path_weight, limit)
            if ray is None:
                break
            if max_rays is not None and sum(rays_per_generation) + dr.width(ray) > max_rays:
                raise TreeTooLarge(depth + 1, dr.width(ray), rays_per_generation)

        color = path = None
        # (data, not a constant of the kernels: a new threshold compiles nothing)
        least_weight = None if signed is None else dr.opaque(mi.Float, signed)
        for generation in reversed(generations):
            color = generation.subtree_color(color)
            if signed is not None:
                path = generation.subtree_signature(path, least_weight)
            if not (lazy and generation is generations[0]):
                dr.eval(color, path)  # once for all channels: the next step gathers from each
        return Trace(color, rays_per_generation, path)

    def step(self, scene, terms, ray, depth, children, first_hit=None, queries=None,
             signed=None, coherent=False):
        """Intersect and shade ``ray``; with ``children``, also the children's weights and rays
        (``first_hit``, ``queries``, ``signed``: see :meth:`trace`; ``coherent``: the rays are
        intersected as coherent packets)."""
        si = self.intersect(scene, terms.geometry, ray, coherent=coherent, queries=queries)
        hit = si.is_valid()
        surfaces = terms.surfaces
        slot = surfaces.slot(si.shape, si.prim_index, hit)
        footprint = None  # a sample's footprint in texture space, for the checkerboard
        footprints = self.carries_footprints(ray, terms)
        if footprints:
            footprint = terms.geometry.uv_footprint(si, ray, hit)
        base = surfaces.base_color(si, slot, hit, footprint)
        shadows = None if first_hit is None else []
        codes = None if signed is None else []  # the lights' codes of the hits' signatures
        local = self.shade(scene, terms, si, slot, base.color, ray, shadows, queries, codes)
        local = dr.select(hit, local, terms.background)
        if first_hit is not None:
            first_hit(si, ray, hit, shadows)
        own = None if signed is None else \
            self.hit_signature(terms, si, base, codes)
        if not children:
            return Step(local, hit, signature=own)
        kr = surfaces.get("reflectivity", slot, hit)
        kt = surfaces.get("refractivity", slot, hit)
        eta = surfaces.get("ior", slot, hit)
        v = -ray.d
        n = self.facing_normal(si, ray)
        entering = dr.dot(si.n, ray.d) < 0
        eta_ratio = dr.select(entering, dr.rcp(eta), eta)
        if surfaces.any_kt or dr.grad_enabled(kt):
            refracted_d, tir = refract(v, n, eta_ratio)
            weights = (kr + dr.select(tir, kt, 0.0), dr.select(tir, 0.0, kt))
            rays = (self.spawn_ray(si, reflect(v, n)), self.spawn_ray(si, refracted_d))
        else:  # every kt 0 (nor its derivative): no lane has a refracted child, and none is
            # computed (its weight kt = 0; its ray the reflected one, which no lane takes: the
            # kernel's outputs and the children's gathers are the reflected ray's only)
            weights, rays = (kr, kt), (self.spawn_ray(si, reflect(v, n)),)
        if footprints:  # the children carry their footprints on (see differentials.py)
            rays = offset_children(ray, si, n, eta_ratio, rays, terms.geometry.normal_at, hit,
                                   reflect, refract)
        if len(rays) == 1:
            rays = rays * 2
        return Step(local, hit, weights, rays, own)

    def hit_signature(self, terms, si, base, codes):
        """The signature of each lane's own hit (signature.py): its surface, the lights'
        ``codes``, and from its ``base`` color (``Surfaces.base_color``) whether a texture
        was read at a point and the grid a checkerboard's footprint needs."""
        hit = si.is_valid()
        return signature.local(hit, si.shape, self.surface_key(terms.geometry, si, hit), codes,
                               base.sampled, signature.grid_code(base.distortion))

    def carries_footprints(self, ray, terms):
        """Whether the rays ``ray`` carry their samples' footprints that a checkerboard is
        averaged over (anti-aliasing's rays, ray differentials, in a scene with a
        checkerboard whose geometry the table knows)."""
        return isinstance(ray, mi.RayDifferential3f) and \
            terms.surfaces.layout.checker_size is not None and terms.geometry.supported

    def spawn_ray(self, si, d):
        """A ray leaving the hit ``si`` along ``d``: Mitsuba's ``si.spawn_ray``, its origin
        moved off the surface along the geometric normal, to the side ``d`` leaves to, by
        (1 + max |p_i|) RayEpsilon, times ``offset_scale``."""
        if self.offset_scale == 1.0:
            return si.spawn_ray(d)  # bit for bit what Mitsuba does
        mag = (1.0 + dr.max(dr.abs(si.p))) * (mi.math.RayEpsilon * self.offset_scale)
        mag = dr.detach(dr.mulsign(mag, dr.dot(si.n, d)))
        return mi.Ray3f(dr.fma(mag, dr.detach(si.n), si.p), d, dr.largest(mi.Float), si.time,
                        si.wavelengths)

    def shadow_ray(self, si, wi, lifted=None):
        """The shadow ray from the hit ``si`` toward a light in direction ``wi`` (no maxt):
        :meth:`spawn_ray`'s, or, near a terminator of a smooth-shaded mesh, from the lifted
        point ``lifted`` (``lift.lifted_point``; None: no smooth mesh). The boundary terms'
        shadow edges start g's rays here too: the edge the image has is that of these rays
        (the ray epsilon moves it, by a few hundredths of a lattice unit at k = 16 where a
        shadow is long)."""
        ray = self.spawn_ray(si, wi)
        if lifted is not None:  # see lift.py
            terminator = (dr.dot(si.sh_frame.n, wi) > 0) & (dr.dot(si.n, wi) <= 0)
            ray.o = dr.select(terminator, lifted, ray.o)
        return ray

    def intersect(self, scene, geometry, ray, coherent, queries=None):
        """The surface interaction of each ray: by lookup in the geometry table (see
        hits.py), or, for a scene with shapes the table does not know, through Mitsuba's
        dispatch (the shapes' own parameters detached: they are not the renderer's).
        ``queries``: who finds the closest hits (see :meth:`trace`; the table's scenes only)."""
        if geometry.supported:
            pi = None if queries is None else queries.camera(scene, ray, coherent)
            return geometry.intersect(scene, ray, coherent, pi)
        return scene.ray_intersect(ray, ray_flags=mi.RayFlags.AllNonDifferentiable,
                                   coherent=coherent)

    def surface_key(self, geometry, si, hit):
        """Which part of its shape each lane hit, for its signature (``HitTable.surface_key``;
        the primitive for a shape the table does not know)."""
        return geometry.surface_key(si, hit) if geometry.supported else mi.UInt32(si.prim_index)

    def facing_normal(self, si, ray):
        """The shading normal flipped to the side the ray comes from."""
        n = si.sh_frame.n
        return dr.select(dr.dot(n, ray.d) > 0, -n, n)

    def shade(self, scene, terms, si, slot, color, ray, shadows=None, queries=None, codes=None):
        """L_local at each hit: ambient term plus each light's shadowed Phong term
        (``shadows``: a list that receives each light's :class:`Shadow`, ``queries``: who
        finds its blocker; see transmittance; ``codes``: a list that receives each light's code of
        the hit's signature, ``signature.light_code``)."""
        hit = si.is_valid()
        surfaces, lights = terms.surfaces, terms.direct
        result = terms.ambient * surfaces.get("ambient_mix", slot, hit) * color
        if not lights:
            return result
        kd = surfaces.get("diffuse_mix", slot, hit)
        ks = surfaces.get("specular_mix", slot, hit)
        exponent = surfaces.get("phong_coeff", slot, hit)
        n, v = self.facing_normal(si, ray), -ray.d
        lifted = lifted_point(terms.geometry, si, hit, self.offset_scale)  # see lift.py
        for j, light in enumerate(lights):
            wi, dist, intensity = light.illuminate(si.p)
            active = hit & (dr.dot(n, wi) > 0)
            blocker = None if queries is None else \
                (lambda ray, active, j=j: queries.shadow(scene, j, ray, active))
            transmittance = self.transmittance(scene, surfaces, si, wi, dist, active, lifted,
                                               shadows, blocker)
            if codes is not None:
                codes.append(signature.light_code(active, transmittance, intensity))
            phong = phong_local(n, v, wi, color, kd, ks, exponent)
            result += dr.select(active, intensity * phong * transmittance, 0.0)
        return result

    def transmittance(self, scene, surfaces, si, wi, dist, active, lifted=None, shadows=None,
                      blocker=None):
        """Product of kt over the surfaces between si.p and the light (0 when blocked).
        ``shadows``: a list that receives the shadow rays' :class:`Shadow`, their closest
        blocker found by a closest-hit query instead of the any-hit test (the same rays);
        ``blocker``:
        optional callable(ray, active) that finds it (a ``queries``' shadow, see trace)."""
        ray = self.shadow_ray(si, wi, lifted)
        ray.maxt = dist * (1.0 - mi.math.ShadowEpsilon)
        # The walk is detached: the parameters reach the transmittance only through the kt
        # of the surfaces crossed (*which* surfaces are crossed changes in jumps), and that
        # derivative is attached in closed form afterwards (see ``with_kt_derivative``),
        # from the slots of the crossings, recorded only when the kt have gradients.
        record = dr.grad_enabled(surfaces.refractivity)
        with dr.suspend_grad():
            # A cheap any-hit test first: most shadow rays cross nothing, and then the
            # transmittance is exactly 1. Only the others walk their crossings.
            if shadows is None and blocker is None:
                blocked = scene.ray_test(ray, active)
            else:
                blocker = scene.ray_intersect_preliminary(ray, coherent=False, active=active) \
                    if blocker is None else blocker(ray, active)
                blocked = active & blocker.is_valid()
            if not surfaces.any_transparent:  # nothing lets light through
                if shadows is not None:
                    shadows.append(Shadow(blocker, None))
                return dr.select(blocked, 0.0, 1.0)
            walk = self.crossings(scene, surfaces, ray, active & blocked, record,
                                  stop=shadows is not None)
            if shadows is not None:
                shadows.append(Shadow(blocker, walk.stopper))
        return with_kt_derivative(surfaces, walk.transmittance, walk.slots)

    def crossings(self, scene, surfaces, ray, active, record=False, stop=False):
        """The walk of the shadow rays ``ray`` (where ``active``: they are blocked) through
        the surfaces they cross, up to the light (``ray.maxt``): a :class:`Walk`.

        Each crossing multiplies the transmittance by its surface's kt; the walk ends at a
        surface that lets no light through (kt <= 0), where nothing more is crossed, or past
        max_shadow_crossings crossings: a ray that would cross more transparent surfaces
        than that counts as blocked (docs/format.md), its transmittance 0. With ``record``,
        the slot of each crossing that let the ray through, in order; with ``stop``, the
        surface at which the light counts as blocked (``boundary/shadows.py``'s stopper)."""
        limit = self.max_shadow_crossings

        def body(ray, transmittance, crossings, slots, stopper, active):
            # Only the distance and the BSDF of each crossing matter: a preliminary
            # intersection is enough. The next ray starts just past the crossing.
            crossing = scene.ray_intersect_preliminary(ray, coherent=False, active=active)
            crossed = active & crossing.is_valid()
            slot = surfaces.slot(crossing.shape, crossing.prim_index, crossed)
            kt = surfaces.get("refractivity", slot, crossed)
            transmittance = dr.select(crossed, transmittance * kt, transmittance)
            onward = crossed & (kt > 0)
            slots = tuple(dr.select(onward & (crossings == k), slot, recorded)
                          for k, recorded in enumerate(slots))
            crossings += 1
            # Past max_shadow_crossings the light counts as blocked.
            past = onward & (crossings > limit)
            transmittance = dr.select(past, 0.0, transmittance)
            if stop:
                stops = crossed & (~onward | past)  # (kt <= 0, or one crossing too many)
                stopper = (dr.select(stops, dr.reinterpret_array(mi.UInt32, crossing.shape),
                                     stopper[0]),
                           dr.select(stops, crossing.prim_index, stopper[1]))
            p = ray(crossing.t)
            step = (1.0 + dr.max(dr.abs(p))) * (mi.math.RayEpsilon * self.offset_scale)
            # (not mi.Ray3f(o, d, maxt): with three arguments the third is the ray's *time*,
            # and maxt stays infinite: the walk would run on past the light)
            ray = mi.Ray3f(dr.select(onward, p + step * ray.d, ray.o), ray.d,
                           dr.select(onward, ray.maxt - crossing.t - step, ray.maxt),
                           ray.time, ray.wavelengths)
            return ray, transmittance, crossings, slots, stopper, onward & ~past

        slots = tuple(mi.UInt32(NO_SLOT) for _ in range(limit if record else 0))
        stopper = (mi.UInt32(NO_SHAPE), mi.UInt32(0)) if stop else ()
        state = (ray, mi.Float(1.0), mi.UInt32(0), slots, stopper, mi.Bool(active))
        _, transmittance, _, slots, stopper, _ = dr.while_loop(
            state, lambda *s: s[-1], body, label="shadow ray")
        return Walk(transmittance, slots if record else None,
                    mi.Vector2u(*stopper) if stop else None)

    def spawn(self, generation, step, path_weight=None, min_weight=None):
        """Record the children of ``generation`` and return their rays (None: no children)
        and, given the lanes' ``path_weight`` (detached; None: no bailout), the children's.

        A lane has a reflected (refracted) child where its weight is > 0 (and its path
        weight above ``min_weight``, an opaque Float: the bailout); the children are
        compacted, reflected ones first, into the next generation's lanes."""
        weight_r, weight_t = step.weight_r, step.weight_t
        has_r, has_t = step.hit & (weight_r > 0), step.hit & (weight_t > 0)
        paths = ()
        if path_weight is not None:
            path_r = path_weight * dr.detach(weight_r)
            path_t = path_weight * dr.detach(weight_t)
            has_r, has_t = has_r & (path_r > min_weight), has_t & (path_t > min_weight)
            paths = (path_r, path_t)
        # One evaluation of everything the step computed: one kernel intersects and shades
        # (evaluated apart, the path weights would need that work done twice).
        dr.eval(generation.local, generation.signature, weight_r, weight_t, has_r, has_t,
                step.reflected, step.refracted, *paths)
        index_r, index_t = dr.compress(has_r), dr.compress(has_t)
        count_r, count_t = dr.width(index_r), dr.width(index_t)
        if count_r + count_t == 0:
            return None, None
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
        children = mi.Ray3f(origin, direction)
        if isinstance(reflected, mi.RayDifferential3f):  # their footprints too
            children = mi.RayDifferential3f(children)
            for name, kind in (("o_x", mi.Point3f), ("o_y", mi.Point3f), ("d_x", mi.Vector3f),
                               ("d_y", mi.Vector3f)):
                setattr(children, name,
                        dr.select(is_t, dr.gather(kind, getattr(refracted, name), parent),
                                  dr.gather(kind, getattr(reflected, name), parent)))
            children.has_differentials = True
        if path_weight is not None:
            path_weight = dr.select(is_t, dr.gather(mi.Float, path_t, parent),
                                    dr.gather(mi.Float, path_r, parent))
        return children, path_weight
