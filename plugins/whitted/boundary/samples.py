"""The samples' keys and colors (the package docstring, "The lattice"): the first hits'
recorded by the adjoint pass's kernels (or the primal render's, adopted), the ring's traced,
then the specular chain's (``chain.py``) from there, written into the lattice's arrays; the
colors as the adjoint pass leaves them; and the camera rays of lattice points."""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..lift import lifted_point
from .lattice import DEFAULT, NO_HIT, _host, _host_keys, lattice_index, ring_points
from .spot import has_cone, spot_cosine

# bytes of one sample's keys: its first hit's (shape, face, distance, normal, checker cell, the
# chain's first ray, whether it goes on and is a total internal reflection) and those of each
# bounce of the chain (shape, face, distance, normal, cell, TIR flag); per light, at the first
# hit and each bounce: lit and the first blocker, and where the light stops in a scene with
# glass (shadows.py)
BYTES_FIRST_HIT = 4 + 4 + 4 + 12 + 8 + 24 + 2
BYTES_PER_BOUNCE = 4 + 4 + 4 + 12 + 8 + 1
BYTES_PER_LIGHT_HIT = 1 + 8
BYTES_PER_STOPPER = 8


def bytes_per_sample(bounces, lights, glass):
    """The bytes of one lattice sample's keys with ``bounces`` bounces of the chain followed
    (0 in a scene without mirrors and glass), ``lights`` lights and, with ``glass``, their
    stoppers: what the memory budget admits a lattice by (the arrays of a bounce no chain
    reaches are never made: an upper bound)."""
    per_light = BYTES_PER_LIGHT_HIT + (BYTES_PER_STOPPER if glass else 0)
    return BYTES_FIRST_HIT + bounces * BYTES_PER_BOUNCE + lights * per_light * (1 + bounces)


def _recorded_values(keys, chain):
    """(name, Dr.Jit value) of a first hit's keys as :meth:`Boundary.recorder` keeps them: a
    light's lit, occluder and stopper as lit{j}, ...; the chain's first ray (next_o, next_d),
    go and tir where the scene has a mirror or glass (``chain``)."""
    for name in ("shape", "prim", "t", "cell", "normal"):
        yield name, keys[name]
    for name in ("lit", "occluder", "stopper"):
        for j, value in enumerate(keys[name]):
            yield f"{name}{j}", value
    if chain:
        yield from (("next_o", keys["next"].o), ("next_d", keys["next"].d), ("go", keys["go"]),
                    ("tir", keys["tir"]))


class Samples:
    """The keys and colors of :class:`Boundary`'s lattice samples (a mixin of Boundary)."""

    def adopt(self, keys):
        """Take every sample's keys and color from ``keys``, a Boundary of the same image
        whose :meth:`recorder` and :meth:`collect` the primal render before this pass ran
        (``Whitted._boundary``): this pass records none."""
        self.recorded, self.colors, self.adopted = keys.recorded, keys.colors, True

    def collect(self, job, start, count, color):
        """Keep the colors of a chunk's samples (``color``: one lane per camera ray of the
        job's pixels start .. start + count - 1; the job: a range of pixels, as the adjoint
        pass's is without anti-aliasing)."""
        self.colors.append(((job.first + start) * self.k ** 2, dr.detach(color)))

    def recorder(self, job):
        """The ``record`` of the adjoint pass's chunks of ``job`` (``Chunker.run``): the keys
        of each chunk's first hits (:meth:`hit_keys`, from the trace's own hits and shadow
        rays) scattered to their lattice points in :attr:`recorded`, in the chunk's kernel:
        the samples' keys cost no trace of their own."""
        def record(start, count):
            return self.first_hit(lattice_index(self.width, self.k, job.first + start, count))

        return record

    def first_hit(self, index):
        """A ``first_hit`` hook (``Tracer.trace``) that scatters each ray's keys to entry
        ``index`` (UInt32, a lane per ray) of :attr:`recorded`."""
        def first_hit(si, rays, hit, shadows):
            with dr.suspend_grad():
                keys = self.hit_keys(si, rays, hit, shadows)
                keys["normal"] = si.n
                for name, value in _recorded_values(keys, self.terms.surfaces.any_specular):
                    value = dr.detach(value)
                    if name not in self.recorded:
                        self.recorded[name] = dr.empty(type(value), self.rows * self.cols)
                    dr.scatter(self.recorded[name], value, index)

        return first_hit

    def trace_ring(self):
        """Trace the ring's samples (:func:`ring_points`): their keys recorded as the adjoint
        pass records the image's (:meth:`recorder`; their colors, should a jump need them,
        are traced then: :meth:`colors_at`)."""
        y, x = ring_points(self.width, self.height, self.k)
        index = jit_array(mi.UInt32, (y * self.cols + x).astype(np.uint32))
        with dr.suspend_grad():
            rays = self.film_rays(y, x, camera=False)
            si = self.tracer.intersect(self.scene, self.terms.geometry, rays, coherent=True)
            self.first_hit(index)(si, rays, si.is_valid(), None)

    def trace_keys(self):
        """The keys of every lattice sample: the first hits' as the adjoint pass recorded them
        (:meth:`recorder`), then the specular chain's (:meth:`chain_keys`), traced from there
        in blocks of lattice rows; written into the lattice's arrays as they come (those of
        one block kept as they are)."""
        self.trace_ring()
        recorded, lights = self.recorded, range(len(self.lights))
        first = {name: recorded[name] for name in ("shape", "prim", "t", "cell")}
        first |= {name: [recorded[f"{name}{j}"] for j in lights]
                  for name in ("lit", "occluder") + (("stopper",) if self.glass else ())}
        total, columns = self.rows, self.cols
        self.put(_host_keys(first) | {"normal": [c.numpy() for c in recorded["normal"]]}, 0,
                 total)
        if "go" not in recorded:  # (no mirror, no glass: no chain)
            self.stoppers_of_occluders()
            return
        block = max(self.block_lanes // columns, 1)
        for first_row in range(0, total, block):
            rows = min(block, total - first_row)
            lane = dr.arange(mi.UInt32, rows * columns) \
                + dr.opaque(mi.UInt32, first_row * columns)
            ray = mi.Ray3f(dr.gather(mi.Point3f, recorded["next_o"], lane),
                           dr.gather(mi.Vector3f, recorded["next_d"], lane))
            with dr.suspend_grad():
                self.put(self.chain_keys(ray, dr.gather(mi.Bool, recorded["go"], lane),
                                         dr.gather(mi.Bool, recorded["tir"], lane)),
                         first_row, rows)
        self.stoppers_of_occluders()

    def stoppers_of_occluders(self):
        """In a scene without glass the first blocker stops each light: the stoppers'
        arrays are the occluders' (no keys of their own, shadows.py)."""
        if not self.glass:
            self.stopper, self.chain_stopper = self.occluder, self.chain_occluder

    def put(self, keys, first, rows):
        """Write ``keys`` (numpy, of lattice rows first .. first + rows - 1; lists: per light,
        bounce, or bounce and light) into the lattice's arrays (:meth:`put_rows`)."""
        for name, values in keys.items():
            if isinstance(values, list):
                into = getattr(self, name)
                for j, v in enumerate(values):
                    into += [None] * (j + 1 - len(into))
                    into[j] = self.put_rows(into[j], name, first, rows, v)
            else:
                setattr(self, name, self.put_rows(getattr(self, name), name, first, rows, values))

    def put_rows(self, target, name, first, rows, values):
        """``target`` (a lattice array of key ``name``, or None: not yet made) with the
        lattice rows first .. first + rows - 1 set to ``values`` (one per lane of those rows,
        row-major; checker cells as planes, (2, lanes)). Made where None: ``values`` itself
        if they are every row, else filled with the key's DEFAULT (a bounce that the chains
        of earlier rows did not reach)."""
        total, columns = self.rows, self.cols
        planes = name.endswith("cell")
        values = values.reshape((2, rows, columns) if planes
                                else (rows, columns) + values.shape[1:])
        if rows == total:
            return values
        if target is None:
            shape = values.shape[:int(planes)] + (total,) + values.shape[1 + int(planes):]
            target = np.full(shape, DEFAULT.get(name, 0), values.dtype)
        target[(slice(None),) * int(planes) + (slice(first, first + rows),)] = values
        return target

    def colors_at(self, points):
        """The colors (numpy (n, 3)) of the samples at lattice points (y, x) (numpy: entries
        of the lattice's arrays, the ring's included)."""
        k = self.k
        y, x = points[0] - 1, points[1] - 1  # (the image's lattice point)
        pixel = (y // k) * self.width + x // k
        lane = pixel * k * k + (y % k) * k + x % k  # (sample (sy, sx): lane sy k + sx)
        out = np.zeros((len(lane), 3), np.float32)
        ring = (y < 0) | (y >= self.height * k) | (x < 0) | (x >= self.width * k)
        for first, color in self.colors:
            inside = ~ring & (lane >= first) & (lane < first + dr.width(color))
            if inside.any():
                index = jit_array(mi.UInt32, (lane[inside] - first).astype(np.uint32))
                out[inside] = _host(dr.gather(mi.Color3f, color, index))
        if ring.any():  # (traced: outside the image, the adjoint pass did not)
            with dr.suspend_grad():
                color = self.tracer.trace(self.scene, self.film_rays(points[0][ring],
                                                                     points[1][ring]),
                                          self.terms).color
            out[ring] = _host(color)
        return out

    def hit_keys(self, si, rays, hit, shadows=None):
        """The keys of the hits ``si`` of ``rays`` where ``hit`` (Dr.Jit, not evaluated): the
        shape (NO_HIT: none), face and distance (inf: none); the checker cell; per light,
        whether it lights the point (it faces the light, lies in a spot's cone and the
        shadow ray is free), what blocks it first and where the light stops (the occluder
        and the stopper, (shape, prim); NO_HIT: nothing, see :meth:`Shadows.stopper_of`);
        and the specular chain's next ray (see chain_step). ``shadows``: per light, the
        tracer's own shadow rays from these hits (``tree.Shadow``: their blocker and, in a
        scene with glass, where the light stops; ``Tracer.trace``'s ``first_hit``); None:
        traced here."""
        keys = {"shape": dr.select(hit, dr.reinterpret_array(mi.UInt32, si.shape), NO_HIT),
                "prim": si.prim_index, "t": dr.select(hit, si.t, dr.inf),
                "cell": self.checker_cell(self.terms, si, hit), "lit": [], "occluder": [],
                "stopper": []}
        n = self.tracer.facing_normal(si, rays)
        # (the renderer's shadow rays: lifted off a smooth mesh near a terminator)
        lifted = None if shadows is not None else \
            lifted_point(self.terms.geometry, si, hit, self.tracer.offset_scale)
        for j, light in enumerate(self.lights):
            wi, dist, _ = light.illuminate(si.p)
            active = hit & (dr.dot(n, wi) > 0)
            if has_cone(light):  # its cone, cos a > 0
                active &= spot_cosine(light, wi) > 0
            if shadows is None:
                shadow = self.tracer.shadow_ray(si, wi, lifted)
                shadow.maxt = dist * (1.0 - mi.math.ShadowEpsilon)
                blocker = self.scene.ray_intersect_preliminary(shadow, coherent=False,
                                                               active=active)
            else:  # (the tracer's, which walked through glass to the stopper too)
                blocker, stopper = shadows[j]
            blocked = active & blocker.is_valid()
            keys["lit"].append(active & ~blocked)
            occluder = mi.Vector2u(
                dr.select(blocked, dr.reinterpret_array(mi.UInt32, blocker.shape), NO_HIT),
                blocker.prim_index)
            keys["occluder"].append(occluder)
            if self.glass:  # (else the first blocker stops the light: no key of its own)
                keys["stopper"].append(
                    self.stopper_of(shadow, blocked) if shadows is None else
                    # (its walk ran where the light is blocked and faces the hit, also out
                    # of a spot's cone)
                    mi.Vector2u(dr.select(blocked, stopper.x, NO_HIT),
                                dr.select(blocked, stopper.y, 0)))
        keys["next"], keys["go"], keys["tir"] = self.chain_step(self.terms, si, rays)
        return keys

    def film_rays(self, y, x, camera=True):
        """The camera rays of lattice points (y, x) (numpy: entries of the lattice's arrays,
        whose image points are (y - 1, x - 1)), with ``camera`` the camera keys attached
        (else as the sensor makes them: ``Tracer.trace`` attaches them itself)."""
        k = self.k
        pos = mi.Point2f(jit_array(mi.Float, ((x - 0.5) / (k * self.width)).astype(np.float32)),
                         jit_array(mi.Float, ((y - 0.5) / (k * self.height)).astype(np.float32)))
        ray, _ = self.sensor.sample_ray(time=0.0, sample1=0.5, sample2=pos,
                                        sample3=mi.Point2f(0.5))
        ray = mi.Ray3f(ray)
        ad = self.tracer.geometry_ad
        return ray if ad is None or not camera else ad.camera_rays(ray)
