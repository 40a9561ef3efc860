"""The first generation's ray queries of a primal render, replayed by the adjoint passes after it.

A gradient step renders the image (detached: ``Whitted.render_array``) and then traces it
again with AD enabled (``render_backward`` / ``render_forward``): the same camera rays
against the same geometry, with the same lights. The ray tracer's answers to the first
generation's two queries are then the same too:

* each camera ray's closest hit (its PreliminaryIntersection3f: t, the primitive's
  barycentric uv, the shape or none, the primitive);
* per light, its shadow ray's closest blocker (the shape or none, the primitive; its
  distance is not kept: nothing reads it).

Where a key with its gradient enabled moves an edge (``boundary.moving_kinds``: the
geometry, the camera, a light, eta; an adjoint pass with the boundary terms follows, whose
keys need the *closest* blocker), the primal render records these answers
(:class:`Recording`, :meth:`Recording.recorder`) and the adjoint passes read them back
(:meth:`Recording.replayer`) instead of asking the ray tracer again: everything else is
computed as before, from the same values, so the derivatives do not change by a bit; the
adjoint's kernels lose their two traversals (at 256 x 192, k = 4: the adjoint's kernels
34 -> 16 ms; the primal's, which asks for the closest blocker instead of any, 2 ms more).

**What the answers depend on** (:func:`token`): the camera rays (the sensor's values, the
image's size, the samples per pixel), the shapes (the geometry table's key: its shapes
and their buffers, ``hits.HitTable``) and the lights' positions and directions (the shadow
rays). A recording is replayed only by a pass whose token equals the primal's, compared
when the pass's geometry table is up to date (each chunk, see ``Chunker.run``): a pass
after any of these changed traces as before. Materials and colors may change between the
two: no answer depends on them.

The answers are outputs of each primal chunk's kernel, written in order as its colors are
(scattered to their lanes instead, they cost the primal render 5.5 ms rather than 2),
assembled into one array each at the first replay when the render took several chunks
(``arrays.Assembled``).

**Memory**: :data:`CAMERA_BYTES` per camera ray and :data:`SHADOW_BYTES` per light and
camera ray, kept until the next primal render (twice that while the chunks are assembled); a
render whose recording would take more than a quarter of the integrator's memory budget
records nothing (its adjoint passes trace; the boundary terms' keys take more than 4 times
a recording, so a gradient step that has them always records). Only renders of the whole
image without anti-aliasing record (an adjoint pass with ``--aa`` traces its refined
pixels' own samples).
"""

import drjit as dr
import mitsuba as mi
import numpy as np

from .arrays import Assembled
from .hits import NO_SHAPE, preliminary

CAMERA_BYTES = 20  # t, uv (two floats), shape (NO_SHAPE: no hit), primitive: 4 bytes each
SHADOW_BYTES = 8  # shape (NO_SHAPE: not blocked), primitive: 4 bytes each


def recording_bytes(lanes, lights):
    """Bytes a recording of ``lanes`` camera rays and ``lights`` direct lights takes."""
    return lanes * (CAMERA_BYTES + lights * SHADOW_BYTES)


def token(scene, sensor, width, height, spp):
    """What the first generation's answers depend on, but for the geometry (compared apart,
    see the module docstring): (a comparable key, the Dr.Jit values it names). The image's
    size and samples; the sensor's values and the lights' positions and directions, each
    Dr.Jit value by its variable's index (no read: a read would wait for the kernels
    queued), host values by their bytes. An index names its variable while the variable
    lives: a recording keeps its token's variables (a handle of its own to each: the
    values read here are the objects' own, which an update points at a new variable)."""
    kept = []

    def leaves(value):
        if isinstance(value, mi.Transform4f):
            value = value.matrix
        if dr.is_array_v(value) and dr.depth_v(value) > 1:
            return tuple(leaves(component) for component in value)
        if dr.is_jit_v(value):
            kept.append(type(value)(value))
            return value.index
        return np.asarray(value).tobytes()

    params = mi.traverse(sensor)
    key = [width, height, spp,
           tuple((name, leaves(params[name])) for name in sorted(params.keys()))]
    for emitter in scene.emitters():
        key.append(tuple(leaves(getattr(emitter, name))
                         for name in ("position", "direction") if hasattr(emitter, name)))
    return tuple(key), kept


class Recording:
    """The first generation's answers of a render's camera rays (every pixel's samples,
    pixel-major, so that a chunk's lanes are a range), recorded by its chunks in order;
    ``token``: :func:`token` of that render, ``geometry``: its geometry table's key."""

    def __init__(self, token, geometry):
        (self.token, self.kept), self.geometry = token, geometry
        # per chunk, by its first lane: (the camera's fields (t, u, v, shape, prim), per
        # light its shadows' (shape, prim)); a chunk traced again in halves (too large a
        # tree, see chunks.py) is replaced by its first half
        self.parts = {}
        self.joined = None  # the parts' fields, one array each (see answers)

    def matches(self, token, geometry):
        """Whether a pass of ``token`` (:func:`token`: key and values) over a geometry table
        of key ``geometry`` may replay this recording."""
        return token[0] == self.token and geometry == self.geometry

    def recorder(self, first, count):
        """The queries of a chunk's ``count`` lanes from lane ``first``, asked of the ray
        tracer and recorded (a ``Tracer.trace`` ``queries``)."""
        return _Recorder(self.parts, first)

    def replayer(self, lane):
        """The queries of the camera rays ``lane`` (UInt32: their numbers in the recorded
        render, ``Job.lanes``), read back."""
        return _Replayer(self.answers(), lane)

    def answers(self):
        """(The camera's fields, per light its fields) of every lane (see __init__)."""
        if self.joined is None:
            firsts = sorted(self.parts)
            lanes = firsts[-1] + dr.width(self.parts[firsts[-1]][0][0])
            camera = _joined([(first, self.parts[first][0]) for first in firsts], lanes)
            shadows = [_joined([(first, self.parts[first][1][j]) for first in firsts], lanes)
                       for j in sorted(self.parts[firsts[0]][1])]
            self.joined, self.parts = (camera, shadows), {}
        return self.joined


def _joined(parts, lanes):
    """Each field of ``parts`` ((first lane, fields) pairs), assembled over ``lanes``."""
    out = []
    for i, field in enumerate(parts[0][1]):
        assembled = Assembled(type(field), lanes)
        for first, fields in parts:
            assembled.add(first, fields[i])
        out.append(assembled.array)
    return tuple(out)


class _Recorder:
    """The first generation's queries (``Tracer.trace``'s ``queries``), traced, their answers
    kept as outputs of the chunk's kernel (scheduled: evaluated with its colors)."""

    def __init__(self, parts, first):
        self.parts, self.first = parts, first
        self.shadows = {}  # light: its fields

    def camera(self, scene, ray, coherent):
        pi = scene.ray_intersect_preliminary(ray, coherent=coherent)
        fields = (pi.t, pi.prim_uv.x, pi.prim_uv.y, _shape(pi), mi.UInt32(pi.prim_index))
        dr.schedule(fields)
        self.parts[self.first] = (fields, self.shadows)
        return pi

    def shadow(self, scene, light, ray, active):
        blocker = scene.ray_intersect_preliminary(ray, coherent=False, active=active)
        self.shadows[light] = fields = (_shape(blocker), mi.UInt32(blocker.prim_index))
        dr.schedule(fields)
        return blocker


def _shape(pi):
    """The shape of each hit as a UInt32 (NO_SHAPE: none)."""
    return dr.select(pi.is_valid(), dr.reinterpret_array(mi.UInt32, pi.shape), NO_SHAPE)


class _Replayer:
    """The first generation's queries, their answers read back (``answers``: see
    Recording.answers) at lanes ``lane``."""

    def __init__(self, answers, lane):
        self.answers, self.lane = answers, lane

    def read(self, fields):
        return [dr.gather(type(f), f, self.lane) for f in fields]

    def camera(self, scene, ray, coherent):
        t, u, v, shape, prim = self.read(self.answers[0])
        return preliminary(t, mi.Point2f(u, v), shape, prim)

    def shadow(self, scene, light, ray, active):
        shape, prim = self.read(self.answers[1][light])
        # (t: not kept, any finite value where blocked; a blocker's distance has no reader)
        return preliminary(dr.select(shape != NO_SHAPE, 0.0, dr.inf), mi.Point2f(0.0),
                             shape, prim)
