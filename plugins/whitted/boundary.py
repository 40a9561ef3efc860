"""Boundary terms: the derivative of the pixel-integrated image where an edge moves.

A pixel's value is the integral of the Whitted tree's color f over the pixel (box filter),
estimated on the uniform k x k lattice of ``spp = k^2`` samples. Where f jumps along a curve
that moves with a parameter theta, the derivative of the integral has, besides the interior
term that automatic differentiation of the samples gives, a boundary term (Reynolds
transport) ``oint (f- - f+) v_n ds``. It is computed here, deterministically, on the same
lattice, for these discontinuities:

* **visibility**: silhouettes of analytic spheres, outlines of flat meshes (triangles),
  creases between two surfaces and between faces of a flat mesh that are not coplanar;
* **shadow edges** of point, spot and directional lights on the surface seen, the
  **terminator** (N.L = 0, where the specular term is cut off) and a spot's **cone**
  (cos a = 0, where a spot of coefficient 0 ends);
* **checker lines** on the surface seen;
* visibility edges, shadow edges and checker lines **seen along the specular chain**, and
  **total internal reflection** switching on or off along it: the path that
  follows, from the surface seen, the refracted ray where kt > 0 (the reflected one under
  total internal reflection), else the reflected ray where kr > 0, up to CHAIN_DEPTH
  bounces (so eta's derivative sees the checker lines seen through glass, and a mirror's
  reflection of an edge moves with the geometry and the camera).

The lattice's own error where the interior derivative is singular -- a sphere's rim, when
the sphere or the camera moves -- is subtracted per pair (:meth:`Boundary.rim_correction`).

Not covered (left out, documented in docs/gradients.md): the branches of the tree other
than the specular chain, and a pair of samples with two edges of different kinds between
them (a checker line and a shadow edge); checker lines, however many, are a crossing each
(:meth:`Boundary.one_crossing_per_line`).

**The lattice.** The samples of all pixels form one uniform grid over the image, spacing
1/k pixel (sample (sx, sy) of pixel (px, py) is lattice point X = px k + sx, Y = py k + sy).
Each sample's *key* is recorded as the adjoint pass traces it, from its own hits and shadow
rays, in the same kernel (:meth:`Boundary.recorder`: the keys cost no trace of their own):
the shape and face hit (and the face's normal), the checker cell, for each light whether it
is lit and what blocks it; the same of each bounce of the specular chain (with its total
internal reflection flag) is traced from there (:meth:`Boundary.trace_keys`); the sample's
color f is kept as the adjoint pass leaves it (:meth:`Boundary.collect`). The samples
nearest the border lie half a lattice spacing inside it: an edge between them and the border
would be straddled by no pair, so the lattice has a *ring* of samples outside the image,
half a spacing beyond its border all round (:func:`ring_points`, traced with their keys by
:meth:`Boundary.trace_ring`), paired with the border's; a crossing outside the image adds
nothing (the eye's per-pixel error at k = 4 on benchmarks/edges_bench.py's scene 14.1 % ->
10.4 %). The lattice's arrays hold the ring too: entry (Y + 1, X + 1) is lattice point (Y,
X). These keys take memory (BYTES_PER_SAMPLE per sample): a lattice whose keys exceed the
memory budget is refused (BudgetError) before anything is traced.

**Pairs.** Two lattice neighbours (in a row or a column) whose keys differ have an edge
between them. Only the edges that some key with its gradient enabled moves form pairs:
the kinds it moves (:func:`moving_kinds`), and, the camera still, an edge of what moves
(:meth:`Boundary.moving_edges`): any other's term is zero. For each such pair a smooth
signed *crossing function* g(ray, theta) is chosen, whose sign differs between the two
samples:

* a visibility edge of the nearer surface N (the other sample's ray misses N's primitive):
  N's inside function -- r - |(c - o) x d| for a sphere, the least of the three normalized
  edge functions for a triangle; else the other surface's; else (both rays meet both
  primitives: a crease) the difference of the two primitives' hit distances;
* a shadow edge of light j: the blocking primitive's inside function on the two samples'
  shadow rays (from the attached hit point toward the attached light); where the unlit
  sample has no blocker, it faces away from the light or lies outside a spot's cone: N.L
  at the attached hit (the shading normal facing the ray), or the spot's cos a where its
  sign differs between the two samples;
* a checker line: u / size - m (or v), m the line between the two cells, of the attached
  texture coordinates;
* the same at bounce d of the specular chain, each sample's chain replayed with
  derivatives (eta, the geometry, the camera) to that bounce; where total internal
  reflection switches at a surface of the chain, the refraction margin 1 - (eta_i /
  eta_t)^2 (1 - cos^2 theta_i) there.

g is evaluated at the two samples L, R and at their neighbours across the axis (for the
edge's normal), detached. Where L and R see one face of one shape (every kind but a
visibility edge of the surface seen), each of these rays' hits is solved on that face, not
traced (:meth:`Boundary.hits_at`, ``HitTable.known_hits``): g is then that surface's own
function, smooth where another surface hides a neighbour or the face ends (the camera's
per-pixel error at k = 4 on benchmarks/edges_bench.py's scene: eye 10.4 -> 9.6 %, fov 8.2 ->
7.2 %; and a fifth of the boundary pass's kernel time). With g linear between L and R the crossing lies at the fraction
w = g_L / (g_L - g_R) of the way from L to R. Where edges crowd, g is seldom linear over a
lattice unit (a checker seen through a glass ball's rim, compressed), so g is evaluated
again, with derivatives (the camera's rays and the geometry as the keys attach them,
``geometry_ad.py``; the lights' own parameters), at two points either side of that
estimate, a quarter of its distance to the nearer sample away. The crossing moves at
du*/dtheta = -dg(u*)/dtheta / g' lattice units, with dg(u*)/dtheta their mean's derivative
and g' their slope where they bracket the crossing (which then lies between them),
elsewhere the secant g_R - g_L (eta through glass over a checkerboard: per-pixel error
20.9 % -> 11.0 % at k = 4 for the refinement; the terminator 3.6 % -> 1.9 %; where they do
not bracket it, L's and R's derivatives interpolated served until the pass with
derivatives was cut to these two points: the benchmark's errors relative to the sum of
sizes moved by at most 0.02 points, its per-pixel errors by less than 0.1 point). The row (column) integral of f changes by (f_L - f_R)
du*/dtheta. Each pair adds, to the pixel in which the crossing lies,

    (f_L - f_R) du*/dtheta / k^2 * n_a^2

where n_a is the component, along the pair's axis, of the edge's unit normal in the lattice
(centred differences of g at L, R and their neighbours across the axis): the rows estimate the boundary integral, and so do the columns; the
weights n_x^2 + n_y^2 = 1 combine them so that an edge parallel to an axis is counted by the
pairs across it only. The term enters as a zero-valued surrogate with that derivative, so the
primal image does not change by a bit. The crossing stands for the piece of edge in its
lattice band; the term is shared by the pixels that piece lies in (:meth:`Boundary.spread`).
f_L, f_R are the samples' colors (the one-sided limits
within O(1/k) of a pixel). Pairs are processed in chunks (memory bounded), in reverse mode
(``backward``) and forward mode (``forward``).
"""

import copy

import drjit as dr
import mitsuba as mi
import numpy as np

from raymitsuba.options import GIB

from .arrays import jit_array
from .chunks import MAX_CHUNK_LANES
from .guards import BudgetError
from .hits import MESH, SMOOTH, SPHERE, traversed_values
from .tree import reflect, refract

PAIRS_PER_CHUNK = 1 << 16
NO_HIT = 0xFFFFFFFF
COPLANAR = 1e-5  # faces whose unit normals differ by less than this are one surface
KINDS = 7  # kinds of pairs:
VISIBILITY, SHADOW, CHECKER, CHAIN_VISIBILITY, CHAIN_CHECKER, CHAIN_TIR, CHAIN_SHADOW = range(KINDS)
CHAIN_DEPTH = 4  # bounces of the specular chain followed past the first hit
# bytes of one sample's keys (shape, face, distance, normal, checker cell, the chain's first
# ray, whether it goes on and is a total internal reflection and, per bounce of the chain,
# shape, face, distance, cell, TIR flag) and per light (lit, blocker)
BYTES_PER_SAMPLE = 4 + 4 + 4 + 12 + 8 + 24 + 2 + CHAIN_DEPTH * (4 + 4 + 4 + 8 + 1)
BYTES_PER_LIGHT = (1 + 8) * (1 + CHAIN_DEPTH)  # lit and blocker, first hit and chain
STOP = 0xFFFFFFFE  # a chain that ended (a surface neither mirror nor glass)
# the chain's keys of a sample whose chain ended before the bounce (those of the first hit
# are set for every sample)
DEFAULT = {"chain_shape": STOP, "chain_prim": 0, "chain_t": np.inf, "chain_cell": 0,
           "chain_tir": False, "chain_lit": False, "chain_occluder": NO_HIT}
LIMIT = 0.02  # lattice units: how close to a crossing its one-sided colors are traced
# ... of a visibility edge of the surface seen: closer, where the rays either side are
# checked to see L's and R's surfaces. A sphere's color changes like the square root of the
# distance to its rim: at LIMIT, f_L - f_R was off by about sqrt(LIMIT / k) of its rim's
# change over a pixel (a radius's weighted sums at k = 8: 1.55 % -> 0.50 %). At least
# FILM_ULPS of the film position's float32 resolution (k W 2^-24 lattice units).
RIM_LIMIT, FILM_ULPS = 2e-4, 4
# the crossing's refinement: g at two points either side of it, this share of its distance
# to the nearer sample away, at least REFINE_MIN lattice units (float32's g resolves it)
REFINE, REFINE_MIN = 0.25, 0.005
# a checker pair with more lines than this between its samples is left out (the pattern
# finer than the lattice there: aliased; its lines' terms nearly cancel)
CHECKER_LINES = 8
POINTS = ("L", "R", "LA", "RA", "LB", "RB")  # a pair's samples and their neighbours across


def moving_kinds(tracer, scene):
    """The kinds of pairs whose edges some key with its gradient enabled moves (empty: a
    derivative pass needs no boundary terms). A key that moves the geometry or the camera
    moves every kind; a material's eta, what is seen through glass (the specular chain's
    kinds); a light's position or direction, its shadow edges, the terminator and a spot's
    cone (the shadow kinds). The others' surrogates would have no derivative: their pairs
    are not formed."""
    if tracer.geometry_ad is not None and tracer.geometry_ad.moves():
        return set(range(KINDS))
    kinds = set()
    if tracer.surfaces is not None and any(  # eta moves what is seen through glass
            dr.grad_enabled(material.ior) for material in tracer.surfaces.layout.materials):
        kinds |= {CHAIN_VISIBILITY, CHAIN_CHECKER, CHAIN_TIR, CHAIN_SHADOW}
    if any(light_moves(emitter) for emitter in scene.emitters()):
        kinds |= {SHADOW, CHAIN_SHADOW}
    return kinds


def light_moves(emitter):
    """Whether a key with its gradient enabled moves ``emitter`` (its position or direction:
    its shadow edges, terminator and cone)."""
    return any(dr.grad_enabled(value) for value in
               (getattr(emitter, name, None) for name in ("position", "direction"))
               if value is not None)


def hurwitz_zeta_half(q):
    """Hurwitz's zeta(1/2, q) = sum over n >= 0 of (q + n)^-1/2 (regularized), for q > 0
    (numpy): eight terms, then Euler-Maclaurin's tail to the B_6 term (error < 1e-9)."""
    q = np.asarray(q, np.float64)
    n = 8
    total = sum((q + i) ** -0.5 for i in range(n))
    x = q + n
    # the tail: -2 sqrt(x) + x^-1/2 / 2 + B2/2! s x^(-s-1) + B4/4! s(s+1)(s+2) x^(-s-3) + ...
    s = 0.5
    tail = -2.0 * np.sqrt(x) + 0.5 * x ** -s
    tail += (1.0 / 6.0) / 2.0 * s * x ** (-s - 1.0)
    tail += (-1.0 / 30.0) / 24.0 * s * (s + 1) * (s + 2) * x ** (-s - 3.0)
    tail += (1.0 / 42.0) / 720.0 * s * (s + 1) * (s + 2) * (s + 3) * (s + 4) * x ** (-s - 5.0)
    return total + tail


def has_cone(light):
    """Whether ``light`` is a spot, whose cone (cos a = 0) is an edge (light.py's kinds)."""
    return getattr(light, "kind", None) == "spotlight"


def spot_cosine(light, wi):
    """cos a of a spotlight at the points whose direction toward it is ``wi``: > 0 inside
    its cone (light.py)."""
    return dr.dot(dr.normalize(light.direction), -wi)


def flat(points, cols):
    """The flat positions (row-major) of the lattice points ``points`` = (y, x) (numpy) in
    arrays of ``cols`` columns: the lattice's arrays are read at these (:func:`at`)."""
    return points[0] * cols + points[1]


def at(plane, index):
    """The entries of ``plane`` (a contiguous lattice array, (rows, cols, ...)) at the flat
    positions ``index`` (numpy, see :func:`flat`), by ``np.take``: numpy's indexing by a
    pair of index arrays (y, x) is about four times slower, and of an array of vectors
    (an occluder's (shape, prim)) by an index array ten times."""
    return np.take(plane.reshape((-1,) + plane.shape[2:]), index, axis=0)


def crossed(cells, left, right):
    """How many checker lines (u and v) lie between the cells at the flat positions ``left``
    and ``right`` (numpy, see :func:`flat`) of ``cells`` (planes of u and v cells, (2,
    ...)): an int8 array."""
    return (at(cells[0], left) != at(cells[0], right)).view(np.int8) \
        + (at(cells[1], left) != at(cells[1], right)).view(np.int8)


def spread_adjoint(grad_in, pixel, fraction):
    """Each term's weight: the image's adjoint ``grad_in`` (numpy (H W, 3)) at the pixels
    it goes to (``pixel``, (n, 3)), by its fraction in each (``fraction``, (n, 3); see
    :meth:`Boundary.spread`): float32 (n, 3). (By np.take and a sum written out: numpy's
    indexing of an array of vectors by an index array, and einsum, are each about three
    times slower.)"""
    adjoint = np.take(grad_in, pixel, axis=0)
    return (fraction[:, 0:1] * adjoint[:, 0] + fraction[:, 1:2] * adjoint[:, 1]
            + fraction[:, 2:3] * adjoint[:, 2]).astype(np.float32)


def nonzero(mask):
    """(y, x) of the True entries of a 2-D mask, row-major (np.nonzero's, faster: one pass
    for flat positions, then their rows and columns)."""
    return np.divmod(np.flatnonzero(mask), mask.shape[1])


def picked(arrays, index, positions):
    """The entry of arrays[index[i]] at positions[i] for each i (``arrays``: a list of
    lattice arrays, (H k, W k, ...); ``index``, ``positions``: numpy, per pair, the
    positions flat: see :func:`flat`)."""
    if len(arrays) == 1:
        return at(arrays[0], positions)
    out = np.empty((len(index),) + arrays[0].shape[2:], arrays[0].dtype)
    for j, array in enumerate(arrays):
        where = index == j
        if where.any():
            out[where] = at(array, positions[where])
    return out


def lattice_index(width, k, first_pixel, count):
    """The entry of the lattice's arrays (flat, row-major: W k + 2 columns, the ring
    included: see the module docstring) of each camera ray of the pixels first_pixel ..
    first_pixel + count - 1 of a ``width``-pixel-wide image on the k x k lattice (a lane
    per ray, pixel-major; sample s of a pixel at (s // k, s % k) within it): a UInt32."""
    lane = dr.arange(mi.UInt32, count * k * k)
    pixel = lane // (k * k)
    sample = lane - pixel * (k * k)
    pixel += dr.opaque(mi.UInt32, first_pixel)  # (data, not a constant of the kernel)
    py = pixel // width
    y, x = py * k + sample // k, (pixel - py * width) * k + sample % k
    return (y + 1) * (width * k + 2) + x + 1


def ring_points(width, height, k):
    """(Y, X) of the lattice's ring (numpy, entries of the lattice's arrays): the points
    half a lattice spacing outside the image, all round (the module docstring)."""
    rows, cols = height * k + 2, width * k + 2
    y = np.concatenate([np.zeros(cols, np.int64), np.full(cols, rows - 1),
                        np.arange(1, rows - 1), np.arange(1, rows - 1)])
    x = np.concatenate([np.arange(cols), np.arange(cols), np.zeros(rows - 2, np.int64),
                        np.full(rows - 2, cols - 1)])
    return y, x


def span(a, b):
    """Lattice units between two lattice points (y, x) that lie on one row or column (numpy;
    at least 1)."""
    return np.maximum(np.abs(a[0] - b[0]) + np.abs(a[1] - b[1]), 1)


def slope_across(w, at_l, at_r):
    """g's slope across a pair's axis at its crossing, a fraction ``w`` of the way from L to
    R: L's and R's centred differences ``at_l``, ``at_r`` (numpy) interpolated. Where one is
    not finite (a neighbour's ray that sees nothing there, so g is undefined) the other's;
    where neither is, 0 (the edge taken across the axis)."""
    ok_l, ok_r = np.isfinite(at_l), np.isfinite(at_r)
    at_l, at_r = np.where(ok_l, at_l, 0.0), np.where(ok_r, at_r, 0.0)
    return np.where(ok_l & ok_r, (1.0 - w) * at_l + w * at_r, np.where(ok_l, at_l, at_r))


def lattice_side(spp):
    """k for ``spp`` = k^2 samples per pixel (None: not a square lattice)."""
    k = int(round(spp ** 0.5))
    return k if k * k == spp else None


def _evaluated(si):
    """``si`` with the fields read here evaluated once (each ``.numpy()`` or later kernel
    would otherwise trace the rays again)."""
    dr.eval(si.t, si.p, si.n, si.sh_frame.n, si.uv, si.shape, si.prim_index)
    return si


def stacked(values, lanes):
    """A per-pair numpy array (P pairs) repeated for each point set of stacked rays of
    ``lanes`` lanes (point set i at lanes i P .. (i + 1) P - 1)."""
    return np.tile(values, (lanes // len(values),) + (1,) * (values.ndim - 1))


def at_l_and_r(value, count):
    """The values of a stacked array at L and at R (point sets 0 and 1, ``count`` pairs): two
    arrays of ``count`` lanes, on the device."""
    lane = dr.arange(mi.UInt32, count)
    return (dr.gather(type(value), value, lane),
            dr.gather(type(value), value, lane + dr.opaque(mi.UInt32, count)))


def on_lanes(value, lanes):
    """A per-pair Dr.Jit array (P lanes) repeated for each point set of stacked rays of
    ``lanes`` lanes (the device's :func:`stacked`)."""
    count = dr.width(value)
    return dr.gather(type(value), value, dr.arange(mi.UInt32, lanes) % dr.opaque(mi.UInt32, count))


def signs_differ(a, b):
    """Whether the signs of ``a`` and ``b`` (Floats) differ, as numpy's ``np.sign(a) !=
    np.sign(b)`` decides it (zero has its own sign; a NaN differs from everything)."""
    def sign(x):
        return dr.select(x > 0, 1, dr.select(x < 0, -1, 0))

    return (sign(a) != sign(b)) | dr.isnan(a) | dr.isnan(b)


def lanes_of(stack, i, count):
    """Point set i of a stacked Float (``count`` pairs): its lanes i P .. (i + 1) P - 1. (Its
    adjoint scatters directly: by default the LLVM backend would expand the stack per thread
    with its size a constant of the kernel, compiled anew for each count of pairs.)"""
    lane = dr.arange(mi.UInt32, count) + dr.opaque(mi.UInt32, i * count)
    return dr.gather(mi.Float, stack, lane, mode=dr.ReduceMode.Direct)


def _planes(vector):
    """A Dr.Jit vector of whole numbers as floats (evaluated) as numpy int32 (components,
    lanes)."""
    return np.stack([c.numpy() for c in vector]).astype(np.int32)


def _host_keys(keys):
    """The keys of :meth:`Boundary.hit_keys` (evaluated) as numpy arrays: shape, prim, t,
    cell (planes), and per light lit and occluder (lists)."""
    return {"shape": keys["shape"].numpy(), "prim": keys["prim"].numpy(),
            "t": keys["t"].numpy(), "cell": _planes(keys["cell"]),
            "lit": [v.numpy() for v in keys["lit"]],
            "occluder": [_host(v) for v in keys["occluder"]]}


def _recorded_values(keys, chain):
    """(name, Dr.Jit value) of a first hit's keys as :meth:`Boundary.recorder` keeps them: a
    light's lit and occluder as lit{j}, occluder{j}; the chain's first ray (next_o, next_d),
    go and tir where the scene has a mirror or glass (``chain``)."""
    for name in ("shape", "prim", "t", "cell", "normal"):
        yield name, keys[name]
    for name in ("lit", "occluder"):
        for j, value in enumerate(keys[name]):
            yield f"{name}{j}", value
    if chain:
        yield from (("next_o", keys["next"].o), ("next_d", keys["next"].d), ("go", keys["go"]),
                    ("tir", keys["tir"]))


def _host(vector):
    """A Dr.Jit vector (evaluated) as a numpy (lanes, components) array."""
    return np.stack([c.numpy() for c in vector], -1)


def _merge(mask, si, other):
    """The fields the boundary terms read (uv, shape, prim_index, t, p, n and the shading
    normal) of ``si`` where ``mask``, else of ``other``."""
    out = dr.zeros(mi.SurfaceInteraction3f, dr.width(mask))
    out.p, out.n = dr.select(mask, si.p, other.p), dr.select(mask, si.n, other.n)
    out.sh_frame = mi.Frame3f(dr.select(mask, si.sh_frame.n, other.sh_frame.n))
    out.uv = dr.select(mask, si.uv, other.uv)
    out.shape = dr.select(mask, si.shape, other.shape)
    out.prim_index = dr.select(mask, si.prim_index, other.prim_index)
    out.t = dr.select(mask, si.t, other.t)
    return out


class Faces:
    """Primitives (shape, prim), one per lane (numpy ids; NO_HIT: none), on the device once
    for every function of them that g reads (:meth:`Boundary.inside`, :meth:`Boundary.depth`,
    :meth:`Boundary.crossed_edge`): whether there is one (``valid``), its kind bits and first
    row in the geometry table ``table``, and the primitive (UInt32)."""

    def __init__(self, table, shape, prim):
        ids = jit_array(mi.UInt32, np.where(shape == NO_HIT, 0, shape).astype(np.uint32))
        self.valid, self.kind, self.row = table.entries(ids, jit_array(mi.Bool, shape != NO_HIT))
        self.prim = jit_array(mi.UInt32, prim.astype(np.uint32))


class Ends:
    """The two samples of each pair of a block, L and R: their lattice points (``L``, ``R``:
    (y, x), numpy), flat positions (``l``, ``r``: see :func:`flat`) and what their first
    hits are (``shape``, ``prim``, ``t``: (at L, at R) each), read once for the block: g's
    evaluations, the one-sided colors and the rim correction all read them."""

    def __init__(self, boundary, L, R):
        self.L, self.R = L, R
        self.l, self.r = flat(L, boundary.cols), flat(R, boundary.cols)
        self.shape, self.prim, self.t = (
            (at(plane, self.l), at(plane, self.r))
            for plane in (boundary.shape, boundary.prim, boundary.t))


class Boundary:
    """The boundary terms of one adjoint pass over a ``width`` x ``height`` image sampled on
    the k x k lattice (``spp`` = k^2) of ``sensor`` (see the module docstring), forming the
    pairs of ``kinds`` (:func:`moving_kinds`); ``terms``: the scene's detached terms, if
    already built."""

    def __init__(self, tracer, scene, sensor, width, height, spp, budget, kinds, terms=None):
        self.tracer, self.scene, self.sensor = tracer, scene, sensor
        self.width, self.height, self.k = width, height, lattice_side(spp)
        # the lattice's arrays: its (H k) x (W k) samples and the ring around them
        self.rows, self.cols = height * self.k + 2, width * self.k + 2
        if terms is None:  # detached: the keys, the one-sided colors (a primal render's)
            with dr.suspend_grad():
                terms = tracer.scene_terms(scene)
        self.terms = terms
        self.lights = self.terms.direct
        self.kind_of = self.terms.geometry.kind_host  # HitTable kind bits by shape id
        # the kinds of pairs formed, as a table by kind + 1 (-1: no pair)
        self.formed = np.zeros(KINDS + 1, bool)
        self.formed[np.array(sorted(kinds), int) + 1] = True
        self.light_type = np.min_scalar_type(max(len(self.lights) - 1, 0))  # (a light's index)
        # What the keys with their gradients enabled move (see moving_edges): the camera,
        # the shapes (by registry id; the last entry: NO_HIT, nothing) and the lights
        ad = tracer.geometry_ad
        self.camera_moves = ad is not None and ad.camera_moves()
        self.shape_moves = np.zeros(len(self.kind_of) + 1, bool)
        if ad is not None:
            ids = self.terms.geometry.id_by_name
            self.shape_moves[[ids[name] for name in ad.moving_shapes()]] = True
        self.light_moves = np.array([light_moves(light) for light in self.lights], bool)
        per_sample = BYTES_PER_SAMPLE + BYTES_PER_LIGHT * len(self.lights)
        need = width * height * spp * per_sample
        # the specular chain's keys are traced in blocks of at most this many samples (their
        # Dr.Jit arrays and the host's copy: within the budget, and within a chunk's size)
        self.block_lanes = int(min(MAX_CHUNK_LANES, max(budget // (2 * per_sample), 1)))
        if need > budget:
            raise BudgetError(
                f"the boundary terms' keys of {width} x {height} x {spp} samples take "
                f"{need / GIB:.2g} GB, more than the memory budget ({budget / GIB:.2g} GB): "
                "use a smaller image or spp, or a larger --memory-budget")
        # The lattice's keys ((H k + 2, W k + 2) arrays, the ring's included: see
        # trace_keys): set as they are read. The specular chain's (see chain_step): a list
        # with an array per bounce traced (none past the last bounce any chain reaches): the
        # shape and face hit, its distance, the checker cell there and whether the bounce
        # was a total internal reflection; lit and what blocks it, per bounce and light
        # (index d * lights + j)
        self.shape = self.prim = self.t = self.cell = None
        self.normal, self.lit, self.occluder = [], [], []  # (normal: its x, y, z planes)
        # the samples' colors as the adjoint pass left them: (first lane, Color3f) per chunk,
        # a lane per camera ray in pixel order (read where a pair's jump needs them)
        self.colors = []
        # the first hits' keys recorded by the adjoint pass (recorder), or by the primal
        # render before it (adopt), and the ring's (trace_ring): {name: Dr.Jit array, an
        # entry per lattice point, row-major}
        self.recorded = {}
        self.adopted = False  # whether they are those a primal render recorded (adopt)
        self.chain_shape, self.chain_prim, self.chain_t, self.chain_cell = [], [], [], []
        self.chain_tir, self.chain_lit, self.chain_occluder = [], [], []

    # -- the keys --------------------------------------------------------------------------------
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
        first |= {"lit": [recorded[f"lit{j}"] for j in lights],
                  "occluder": [recorded[f"occluder{j}"] for j in lights]}
        total, columns = self.rows, self.cols
        self.put(_host_keys(first) | {"normal": [c.numpy() for c in recorded["normal"]]}, 0,
                 total)
        if "go" not in recorded:  # (no mirror, no glass: no chain)
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

    def chain_keys(self, ray, alive, tir):
        """The keys of the specular chain (numpy lists, a bounce each: ``chain_shape``, ...,
        ``chain_tir``) from its first rays ``ray``, where ``alive`` (the first hits with a
        next ray), ``tir``: where that ray is a total internal reflection. Each bounce's keys
        are one evaluation."""
        scene, table = self.scene, self.terms.geometry
        out = {"chain_" + name: [] for name in ("shape", "prim", "t", "cell", "tir", "lit",
                                                 "occluder")}
        for _ in range(CHAIN_DEPTH):
            if not dr.any(alive):  # (the chain's keys past its end: as the lattice starts)
                break
            si_k = self.tracer.intersect(scene, table, ray, coherent=False)
            found = alive & si_k.is_valid()
            keys_k = self.hit_keys(si_k, ray, found)
            keys_k["shape"] = dr.select(found, keys_k["shape"],
                                        dr.select(alive, mi.UInt32(NO_HIT), mi.UInt32(STOP)))
            at_tir = alive & tir  # (total internal reflection at the bounce that led here)
            alive = found & keys_k["go"]
            ray, tir = keys_k["next"], keys_k["tir"]
            dr.eval(keys_k, at_tir, alive)
            for name, value in _host_keys(keys_k).items():  # (lit, occluder: one per light)
                out["chain_" + name] += value if isinstance(value, list) else [value]
            out["chain_tir"].append(at_tir.numpy())
        return out

    def hit_keys(self, si, rays, hit, shadows=None):
        """The keys of the hits ``si`` of ``rays`` where ``hit`` (Dr.Jit, not evaluated): the
        shape (NO_HIT: none), face and distance (inf: none); the checker cell; per light,
        whether it lights the point (it faces the light, lies in a spot's cone and the
        shadow ray is free) and what blocks it ((shape, prim); NO_HIT: nothing); and the
        specular chain's next ray (see chain_step). ``shadows``: per light, the blocker of
        the tracer's own shadow rays from these hits (``Tracer.trace``'s ``first_hit``);
        None: traced here."""
        keys = {"shape": dr.select(hit, dr.reinterpret_array(mi.UInt32, si.shape), NO_HIT),
                "prim": si.prim_index, "t": dr.select(hit, si.t, dr.inf),
                "cell": self.checker_cell(self.terms, si, hit), "lit": [], "occluder": []}
        n = self.tracer.facing_normal(si, rays)
        for j, light in enumerate(self.lights):
            wi, dist, _ = light.illuminate(si.p)
            active = hit & (dr.dot(n, wi) > 0)
            if has_cone(light):  # its cone, cos a > 0
                active &= spot_cosine(light, wi) > 0
            if shadows is None:
                shadow = self.tracer.spawn_ray(si, wi)
                shadow.maxt = dist * (1.0 - mi.math.ShadowEpsilon)
                blocker = self.scene.ray_intersect_preliminary(shadow, coherent=False,
                                                               active=active)
            else:
                blocker = shadows[j]
            blocked = active & blocker.is_valid()
            keys["lit"].append(active & ~blocked)
            keys["occluder"].append(mi.Vector2u(
                dr.select(blocked, dr.reinterpret_array(mi.UInt32, blocker.shape), NO_HIT),
                blocker.prim_index))
        keys["next"], keys["go"], keys["tir"] = self.chain_step(self.terms, si, rays)
        return keys

    def checker_cell(self, terms, si, hit):
        """(floor(u / size), floor(v / size)) of each hit on a checkered surface, else (0, 0)
        (Dr.Jit Floats)."""
        layout = terms.surfaces.layout
        if layout.checker_size is None:
            return dr.zeros(mi.Vector2f, dr.width(hit))
        slot = terms.surfaces.slot(si.shape, si.prim_index, hit)
        size = dr.gather(mi.Float, layout.checker_size, slot, hit)
        checkered = hit & (size > 0)
        size = dr.select(checkered, size, 1.0)
        return mi.Vector2f(dr.select(checkered, dr.floor(si.uv.x / size), 0.0),
                           dr.select(checkered, dr.floor(si.uv.y / size), 0.0))

    def refraction_margin(self, terms, si, ray):
        """1 - sin^2 of the refracted angle at the hit ``si`` of ``ray``, 1 - (eta_i /
        eta_t)^2 (1 - cos^2 theta_i): > 0 where the ray refracts, <= 0 under total internal
        reflection (as ``tree.refract`` decides it). Attached as ``si`` and ``ray`` are."""
        hit = si.is_valid()
        slot = terms.surfaces.slot(si.shape, si.prim_index, hit)
        eta = terms.surfaces.get("ior", slot, hit)
        v, n = -ray.d, self.tracer.facing_normal(si, ray)
        ratio = dr.select(dr.dot(si.n, ray.d) < 0, dr.rcp(eta), eta)
        return 1.0 - dr.square(ratio) * (1.0 - dr.square(dr.dot(n, v)))

    def chain_step(self, terms, si, ray):
        """The next ray of the *specular chain* from the hit ``si`` of ``ray``: the refracted
        ray where the surface has kt > 0 (the reflected one under total internal reflection),
        else the reflected ray where kr > 0; (ray, whether there is one, TIR mask). Attached
        when ``si`` and ``ray`` are (eta, the geometry, the camera)."""
        surfaces = terms.surfaces
        hit = si.is_valid()
        slot = surfaces.slot(si.shape, si.prim_index, hit)
        kr = surfaces.get("reflectivity", slot, hit)
        kt = surfaces.get("refractivity", slot, hit)
        eta = surfaces.get("ior", slot, hit)
        v, n = -ray.d, self.tracer.facing_normal(si, ray)
        entering = dr.dot(si.n, ray.d) < 0
        refracted, tir = refract(v, n, dr.select(entering, dr.rcp(eta), eta))
        through = hit & (kt > 0) & ~tir
        back = hit & ~through & ((kr > 0) | (kt > 0))
        d = dr.select(through, refracted, reflect(v, n))
        return self.tracer.spawn_ray(si, d), through | back, hit & (kt > 0) & tir

    # -- the pairs -------------------------------------------------------------------------------
    def pairs(self):
        """Every lattice pair with an edge between: a dict of numpy arrays (one entry per
        pair): L, R, O as (Y, X), the kind, the light (shadows), and what g is made of.

        The pairs of each axis are classified among its candidates only: the pairs whose
        samples differ in some key (a few percent of the lattice; every other pair has no
        edge between), found by one pass of comparisons over the lattice."""
        found = []
        rows, cols = self.t.shape
        bounces = self.chain_bounces()
        for axis in (1, 0):  # rows (X, X + 1), then columns (Y, Y + 1)
            ly, lx = self.candidates(axis, bounces)
            L, R = (ly, lx), (ly + (axis == 0), lx + (axis == 1))
            kind, light, depth = self.classify(L, R, bounces)
            keep = self.kept(kind)
            if not self.camera_moves:  # (if it does, every edge moves)
                where = np.flatnonzero(keep)
                keep[where] = self.moving_edges(kind[where], light[where],
                                                flat(L, cols)[where], flat(R, cols)[where])
            ly, lx = ly[keep], lx[keep]
            ry, rx = ly + (axis == 0), lx + (axis == 1)
            # the neighbours of L and R across the axis, either side (one side at the border):
            # they give the edge's normal at the crossing (centred differences)
            if axis == 1:
                beside = [(np.minimum(y + 1, rows - 1), x) for y, x in ((ly, lx), (ry, rx))] \
                    + [(np.maximum(y - 1, 0), x) for y, x in ((ly, lx), (ry, rx))]
            else:
                beside = [(y, np.minimum(x + 1, cols - 1)) for y, x in ((ly, lx), (ry, rx))] \
                    + [(y, np.maximum(x - 1, 0)) for y, x in ((ly, lx), (ry, rx))]
            points = dict(L=(ly, lx), R=(ry, rx), LA=beside[0], RA=beside[1], LB=beside[2],
                          RB=beside[3])
            found.append(dict(axis=np.full(len(ly), axis), kind=kind[keep].astype(np.int64),
                              light=light[keep].astype(np.int64),
                              depth=depth[keep].astype(np.int64), **points))
        return self.one_crossing_per_line(
            {name: (tuple(np.concatenate([f[name][i] for f in found]) for i in range(2))
                    if name in POINTS else np.concatenate([f[name] for f in found]))
             for name in found[0]})

    def one_crossing_per_line(self, pairs):
        """``pairs`` with each checker pair repeated once per checker line between its two
        samples (u lines, then v lines: where the pattern is finer than the lattice, or a
        corner passes between them; at most CHECKER_LINES, else left out; along the
        specular chain exactly one, else left out: through a glass ball's rim, where the
        lines crowd and u is far from linear, their crossings added more error than they
        took away, measured), and what each
        entry's g is: ``coord`` (0: u, 1: v; -1: not a checker line) and ``line`` m, the
        line's index (g = u / size - m: the line between the cells m - 1 and m). Each line
        is a crossing of its own, its jump traced either side of it."""
        chain = pairs["kind"] == CHAIN_CHECKER
        checker = (pairs["kind"] == CHECKER) | chain
        low, count = [], []
        for c in (0, 1):
            a, b = (self.checker_cells(c, pairs[name], chain, pairs["depth"])
                    for name in ("L", "R"))
            low.append(np.minimum(a, b))
            count.append(np.where(checker, np.abs(a - b), 0))
        lines = count[0] + count[1]
        most = np.where(chain, 1, CHECKER_LINES)
        entries = np.where(checker, np.where(lines <= most, lines, 0), 1)
        if (entries == 1).all():  # (one line each: the pairs as they are)
            index, out = np.arange(len(entries)), dict(pairs)
        else:
            index = np.repeat(np.arange(len(entries)), entries)
            out = {name: tuple(a[index] for a in value) if name in POINTS else value[index]
                   for name, value in pairs.items()}
        j = np.arange(len(index)) - np.repeat(np.cumsum(entries) - entries, entries)
        u = j < count[0][index]
        out["coord"] = np.where(checker[index], np.where(u, 0, 1), -1)
        out["line"] = np.where(u, low[0][index] + 1 + j,
                               low[1][index] + 1 + j - count[0][index]).astype(np.float32)
        return out

    def checker_cells(self, c, points, chain, depth):
        """The checker cells (coordinate ``c``: 0 u, 1 v; int64) at the lattice ``points``
        (y, x) of each pair: the first hit's, or where ``chain``, those of the chain's
        bounce ``depth``."""
        positions = flat(points, self.cols)
        cells = at(self.cell[c], positions).astype(np.int64)
        if chain.any():
            where = np.flatnonzero(chain)
            cells[where] = picked([bounce[c] for bounce in self.chain_cell], depth[where],
                                  positions[where])
        return cells

    def chain_bounces(self):
        """How many bounces of the specular chain some chain reaches: those before the first
        that none does (0: no mirror, no glass)."""
        reached = [not np.all(shape == STOP) for shape in self.chain_shape]
        return (reached + [False]).index(False)  # (every bounce reached: CHAIN_DEPTH)

    def candidates(self, axis, bounces):
        """(Y, X) of L of the pairs along ``axis`` (1: rows, 0: columns) whose samples differ
        in some key (the first hit's shape, face, light and checker cell, and those of the
        chain's first ``bounces`` bounces), row-major: the lattice's order. None along the
        ring: a pair has a sample of the image."""
        planes = [self.shape, self.prim, *self.lit, self.cell[0], self.cell[1]]
        for d in range(bounces):
            planes += [self.chain_shape[d], self.chain_tir[d], self.chain_cell[d][0],
                       self.chain_cell[d][1]]
            planes += self.chain_lit[d * len(self.lights):(d + 1) * len(self.lights)]
        # Each entry against the one ``step`` further in row-major order (its right or lower
        # neighbour), the planes flat: comparisons of contiguous arrays, three times faster
        # than of the lattice's 2-D views
        rows, cols = self.rows, self.cols
        step = 1 if axis == 1 else cols
        differs = np.zeros(rows * cols, bool)  # (by L's flat position)
        pair, other = differs[:-step], np.empty(rows * cols - step, bool)
        for plane in planes:
            values = plane.reshape(-1)
            np.not_equal(values[:-step], values[step:], out=other)
            pair |= other
        # None along the ring: rows (L on the ring's rows, or R past the last column),
        # columns (L on the ring's columns; past the last row none is compared)
        lattice = differs.reshape(rows, cols)
        if axis == 1:
            lattice[[0, rows - 1]] = False
            lattice[:, cols - 1] = False
        else:
            lattice[:, [0, cols - 1]] = False
        return nonzero(lattice)

    def classify(self, L, R, bounces):
        """(kind (int8; -1: none, or left out), light, depth) of the pairs (L, R) (numpy
        (Y, X) each, one entry per pair): what edge lies between their samples."""
        L, R = flat(L, self.cols), flat(R, self.cols)  # (read at: see flat)
        visibility = self.surface_differs(L, R, self.kind_of)
        kind = np.full(visibility.shape, -1, np.int8)  # (small types: a pass per array)
        light = np.zeros(visibility.shape, self.light_type)
        kind[visibility] = VISIBILITY
        same = ~visibility & (at(self.shape, L) != NO_HIT)
        # On one surface, a pair across one kind of edge only: where a shadow edge and a
        # checker line (or two shadow edges) pass between the same two samples, the jump
        # f_L - f_R is the sum of both and belongs to neither alone (such pairs are left
        # out: a share of the crossings that falls as 1/k). Checker lines, however many,
        # are one crossing each (see one_crossing_per_line).
        edges = np.zeros(visibility.shape, np.int16)
        for j in range(len(self.lights)):
            edge = same & (at(self.lit[j], L) != at(self.lit[j], R))
            edges += edge
            kind[edge], light[edge] = SHADOW, j
        lines = crossed(self.cell, L, R)  # u and v lines crossed
        checker = same & (lines > 0)
        edges += checker
        kind[checker] = CHECKER
        kind[same & (edges > 1)] = -1
        # Seen along the specular chain (mirrors, glass): the first bounce whose key
        # differs, if the first hits are alike: total internal reflection switching at
        # the surface the bounce leaves, else a visibility edge, checker lines or one
        # shadow edge (a pair across edges of two kinds at that bounce is left out).
        depth = np.full(visibility.shape, -1, np.int8)
        pending = same & (edges == 0)
        for d in range(bounces):  # (past every chain's end: no pair)
            if not pending.any():
                break
            cs_l, cs_r = at(self.chain_shape[d], L), at(self.chain_shape[d], R)
            tir = at(self.chain_tir[d], L) != at(self.chain_tir[d], R)
            shape_differs = cs_l != cs_r
            lines = crossed(self.chain_cell[d], L, R)
            shadows = np.zeros(visibility.shape, np.int16)  # shadow edges at the bounce
            for j in range(len(self.lights)):
                lit = self.chain_lit[d * len(self.lights) + j]
                edge = ~shape_differs & (at(lit, L) != at(lit, R))
                shadows += edge
                light[pending & edge & ~tir] = j
            here = pending & (shape_differs | (lines > 0) | tir | (shadows > 0))
            ok = here & ~tir & (shape_differs | ((lines > 0) & (shadows == 0))
                                | ((lines == 0) & (shadows == 1)))
            ok &= (cs_l != STOP) & (cs_r != STOP)
            kind[ok & shape_differs] = CHAIN_VISIBILITY
            kind[ok & ~shape_differs & (lines > 0)] = CHAIN_CHECKER
            kind[ok & ~shape_differs & (shadows == 1)] = CHAIN_SHADOW
            # total internal reflection switching at the bounce's surface: what the two
            # chains meet after it differs because of it
            switch = here & tir
            kind[switch] = CHAIN_TIR
            depth[ok | switch] = d
            pending &= ~here
        return kind, light, depth

    def moving_edges(self, kind, light, L, R):
        """Where the edge between the samples of the pairs (L, R) (flat positions, see
        :func:`flat`) of ``kind`` (and ``light``: a shadow's) moves, the camera still: a
        visibility edge where either sample sees a moving shape, a checker line on one, a
        shadow edge whose surface, light or blocker moves, and every edge seen along the
        specular chain (not told apart: kept). Elsewhere g reads nothing a key moves: the
        term is zero, and its pair is not formed (a fit of one object's pose, the camera
        still: the checker lines of a floor that does not move, four fifths of the pairs
        of benchmarks/edges_bench.py's scene, cost nothing)."""
        moves = (kind >= CHAIN_VISIBILITY) | self.moves(at(self.shape, L)) \
            | self.moves(at(self.shape, R))
        shadow = np.flatnonzero(kind == SHADOW)
        if len(shadow):
            blocker = self.blocker(self.lit, self.occluder, light[shadow], L[shadow], R[shadow])
            moves[shadow] |= self.light_moves[light[shadow]] | self.moves(blocker[:, 0])
        return moves

    def moves(self, shape):
        """Whether the shapes ``shape`` (registry ids, numpy; NO_HIT: none) move."""
        last = len(self.shape_moves) - 1
        return self.shape_moves[np.where(shape < last, shape, last)]

    def kept(self, kind):
        """Where a pair of ``kind`` (int8 array; -1: none, or left out) is formed."""
        if self.formed[1:].all():
            return kind >= 0
        keep = np.zeros(kind.shape, bool)
        for formed in np.flatnonzero(self.formed[1:]):
            keep |= kind == formed
        return keep

    def surface_differs(self, L, R, kind_of):
        """Whether the samples of the pairs (L, R) (numpy flat positions, see :func:`flat`)
        see different surfaces: another shape (or one a miss), or another face of a flat mesh
        that is not coplanar with the first."""
        sl, sr = at(self.shape, L), at(self.shape, R)
        differs = sl != sr
        faces = ~differs & (sl != NO_HIT) & (at(self.prim, L) != at(self.prim, R))
        if not faces.any():
            return differs
        kind = kind_of[np.minimum(sl[faces], len(kind_of) - 1)]
        planar = (kind & MESH != 0) & (kind & SMOOTH == 0)
        where = np.flatnonzero(faces)[planar]
        nl, nr = (np.stack([at(c, side[where]) for c in self.normal], -1) for side in (L, R))
        differs[where[np.linalg.norm(nl - nr, axis=-1) > COPLANAR]] = True
        return differs

    # -- the surrogates --------------------------------------------------------------------------
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

    def surrogates(self, pairs, lo, hi):
        """(Color3f surrogate per pair lo .. hi - 1, zero-valued, with the derivative of the
        pair's term; the pixel each term goes to, numpy)."""
        terms = self.tracer.scene_terms(self.scene)  # attached: the keys' derivatives
        sl = slice(lo, hi)
        count = hi - lo
        points = {name: tuple(a[sl] for a in pairs[name]) for name in POINTS}
        L, ends = points["L"], Ends(self, points["L"], points["R"])
        kind, light, axis = pairs["kind"][sl], pairs["light"][sl], pairs["axis"][sl]
        # what picks g (see g_at); its choices made from L's and R's values, kept for the
        # second pass
        crossing = (ends, kind, light, pairs["depth"][sl],
                    (pairs["coord"][sl], pairs["line"][sl]), {})
        # g at the lattice points (detached): the crossing where it changes sign, linear
        # between L and R
        with dr.suspend_grad():
            _, (gl, gr, gla, gra, glb, grb) = self.g_at(
                terms, [points[name] for name in POINTS], *crossing)
        valid = (np.sign(gl) != np.sign(gr)) & (gl != gr) & np.isfinite(gr - gl)
        w = np.clip(np.where(valid, gl / np.where(valid, gl - gr, 1.0), 0.5), 0.0, 1.0)
        # refined where g curves between L and R (a checker seen through a glass ball's
        # rim: its lines compressed, u far from linear): g at two points either side of the
        # crossing, REFINE of its distance to the nearer sample (at least REFINE_MIN):
        # their values bracket the crossing again, their difference is g's slope across
        # it (otherwise L's and R's secant). Their mean's derivative is g's at the crossing
        # (at its linear estimate where they do not bracket it): the one pass with
        # derivatives, two rays a pair.
        eps = np.clip(REFINE * np.minimum(w, 1.0 - w), REFINE_MIN, REFINE)
        beside = [self.along_axis(L, axis, w + side * eps) for side in (-1.0, 1.0)]
        g, (gm, gp) = self.g_at(terms, beside, *crossing)
        g_star = 0.5 * (lanes_of(g, 0, count) + lanes_of(g, 1, count))
        bracket = valid & (np.sign(gm) != np.sign(gp)) & np.isfinite(gp - gm)
        along = np.where(bracket, (gp - gm) / (2.0 * eps), gr - gl)  # dg per lattice unit
        w = np.where(bracket, np.clip(w - eps + 2.0 * eps * gm / np.where(bracket, gm - gp, 1.0),
                                      0.0, 1.0), w)
        across = slope_across(w, (gla - glb) / span(points["LA"], points["LB"]),
                              (gra - grb) / span(points["RA"], points["RB"]))
        normal2 = along ** 2 / np.maximum(along ** 2 + across ** 2, 1e-30)
        df = self.jump(ends, axis, w, kind)
        # (a pair whose g beside the crossing is undefined, a ray there seeing nothing its
        # function reads, adds no term: selected out, as a product with 0 would carry NaN in
        # forward mode)
        valid &= np.isfinite(gm) & np.isfinite(gp)
        scale = np.where(valid, normal2 / (self.k ** 2 * np.where(valid, along, 1.0)), 0.0)
        rate = -(g_star - dr.detach(g_star)) * jit_array(mi.Float, scale.astype(np.float32))
        rate = dr.select(jit_array(mi.Bool, valid), rate, 0.0)
        surrogate = mi.Color3f(*(jit_array(mi.Float, df[:, c]) for c in range(3))) * rate
        rim = self.rim_correction(terms, terms.geometry, kind, axis, ends, w,
                                  np.where(valid, normal2, 0.0))
        if rim is not None:
            surrogate += rim
        return surrogate, self.spread(L, axis, w, np.abs(across) / np.maximum(np.abs(along), 1e-30))

    def g_at(self, terms, sets, ends, kind, light, depth, line, choices):
        """g at the point sets ``sets`` (a list of (y, x) lattice coordinates, numpy, one
        point per pair; ``ends``: the pairs' :class:`Ends`) traced as one stack of rays: (a
        Float of len(sets) P lanes, point set i at lanes i P .. (i + 1) P - 1, attached as
        ``terms`` and the camera's keys are; its values as numpy (len(sets), P)).
        ``choices`` (a dict): the picks made from L's and R's values (which function, which
        edge of a face) by an earlier call with the same pairs, or empty: made here, from
        the first two sets (then L and R), and kept in it."""
        table = terms.geometry
        ray = self.film_rays(*(np.concatenate([point[i] for point in sets]) for i in range(2)))
        dr.eval(ray)
        si = _evaluated(self.hits_at(table, ray, ends, kind))
        g = self.crossing(table, terms, ray, si, ends, kind, light, line, choices)
        if (depth >= 0).any():
            g = self.chain_crossing(table, terms, ray, si, ends, kind, depth, g, light, line,
                                    choices)
        # (the choices made here evaluated with g: a later call reads them, not their graph)
        dr.eval(g, [v for made in choices.values() for v in made if isinstance(v, dr.ArrayBase)])
        return g, dr.detach(g).numpy().astype(np.float64).reshape(len(sets), len(kind))

    def hits_at(self, table, ray, ends, kind):
        """The surface interactions of g_at's stacked rays ``ray``, a point set after another,
        for the pairs (L, R) of ``kind`` (their :class:`Ends`). Where L and R see one face
        of one shape (every kind but a visibility edge of the first hit, mostly), each ray's
        hit on that face, solved from the table (``HitTable.known_hits``: no ray tracing; g
        then is the function of that surface's, smooth where another hides it or where the
        face ends); elsewhere, and where the ray does not meet that face's plane or sphere,
        by the ray tracer. A visibility edge's rays have none (its g reads the rays only)."""
        if not table.supported:  # (coherent: the stack's rays in the lattice's order)
            return self.tracer.intersect(self.scene, table, ray, coherent=True)
        lanes = dr.width(ray.d)
        shape, prim = ends.shape[0], ends.prim[0]
        needed = kind != VISIBILITY
        known = needed & (shape == ends.shape[1]) & (prim == ends.prim[1]) & (shape != NO_HIT)
        pi = table.known_hits(ray, jit_array(mi.UInt32, stacked(np.where(known, shape, NO_HIT),
                                                                lanes)),
                              jit_array(mi.UInt32, stacked(prim, lanes)),
                              jit_array(mi.Float, stacked(ends.t[0], lanes)))
        traced = jit_array(mi.Bool, stacked(needed, lanes)) & ~pi.is_valid()
        found = self.scene.ray_intersect_preliminary(ray, coherent=True, active=traced)
        return table.intersect(self.scene, ray, True, dr.select(traced, found, pi))

    @staticmethod
    def along_axis(L, axis, offset):
        """The lattice points (y, x) ``offset`` lattice units from L along each pair's axis."""
        return (np.where(axis == 1, L[0], L[0] + offset), np.where(axis == 1, L[1] + offset, L[1]))

    def rim_correction(self, terms, table, kind, axis, ends, w, normal2):
        """The lattice's error on the rim of a sphere (or ellipsoid) that moves across the
        rays (zero-valued Color3f surrogates per pair, or None).

        Where a ray grazes a sphere, the interior derivative of what it sees at a fixed image
        point diverges like a / sqrt(x), x its distance to the rim (the hit's depth changes
        like the square root of the distance): integrable, but a row of lattice samples
        that starts at distance delta (lattice units) from the rim sums it with the error
        a zeta(1/2, delta) (Hurwitz's zeta: the midpoint rule of a / sqrt(x)). With the
        first sample inside, D(delta) ~ a / sqrt(delta), so each visibility pair of a sphere
        subtracts zeta(1/2, delta) sqrt(delta) D(delta) / k^2 from its pixel, weighted by
        n_a^2 as the boundary term is (rows and columns both estimate it): one more sample
        traced, attached to the geometry's and the camera's keys alone, and only where they
        move the sphere's hits: the sphere moves, or the camera does (a light, a material or
        another shape leaves the hit in place: nothing is singular; the lights' and the
        materials' derivatives are kept out of D); the smooth part of D at the
        first sample is taken for singular too, a bias of at most 1.5 D / k^2 per pair
        (measured on benchmarks/edges_bench.py's spheres: per-pixel error at k = 4 from
        18-19 % to 4-5 %; on its whole scene moved by the eye, 14.1 % to 14.0 %)."""
        ad = self.tracer.geometry_ad
        if ad is None or not ad.moves():
            return None
        near_l = ends.t[0] <= ends.t[1]
        inside = tuple(np.where(near_l, a, b) for a, b in zip(ends.L, ends.R))
        shape = np.where(near_l, *ends.shape)
        kind_of = self.kind_of
        sphere = (kind == VISIBILITY) & (shape != NO_HIT) & (normal2 > 0)
        if not self.camera_moves:  # (a sphere that stays, seen by a still camera)
            sphere &= self.moves(shape)
        sphere &= (kind_of[np.minimum(np.where(shape == NO_HIT, 0, shape), len(kind_of) - 1)]
                   & SPHERE) != 0
        # the row goes on inside: the next sample away from the rim sees the same sphere
        step = np.where(near_l, -1, 1)
        rows, cols = self.shape.shape
        y, x = inside[0] + step * (axis == 0), inside[1] + step * (axis == 1)
        # (both within the image: a row of its samples; not the ring's)
        sphere &= (y >= 1) & (y < rows - 1) & (x >= 1) & (x < cols - 1)
        sphere &= (inside[0] >= 1) & (inside[0] < rows - 1) & (inside[1] >= 1) \
            & (inside[1] < cols - 1)
        onward = (np.clip(y, 0, rows - 1), np.clip(x, 0, cols - 1))
        onward = flat(onward, cols)
        sphere &= (at(self.shape, onward) == shape) \
            & (at(self.prim, onward) == np.where(near_l, *ends.prim))
        if not sphere.any():
            return None
        traced = np.flatnonzero(sphere)  # (only these pairs' samples are traced)
        delta = np.maximum(np.where(near_l, w, 1.0 - w), 1e-3)[traced]
        factor = -hurwitz_zeta_half(delta) * np.sqrt(delta) * normal2[traced] / self.k ** 2
        # d's derivative: the geometry's and the camera's alone, whose interior term is
        # singular at the rim (the materials' tables detached, the lights' values suspended;
        # the tracer attaches the camera's keys to the rays)
        moving = copy.copy(self.terms)
        moving.geometry = table
        with dr.suspend_grad(*(value for light in self.lights
                               for value in traversed_values(light))):
            rays = self.film_rays(inside[0][traced], inside[1][traced], camera=False)
            d = self.tracer.trace(self.scene, rays, moving).color
        term = (d - dr.detach(d)) * jit_array(mi.Float, factor.astype(np.float32))
        # each pair's term (zero where none is traced)
        index = np.cumsum(sphere) - 1
        return dr.gather(mi.Color3f, term,
                         jit_array(mi.UInt32, np.maximum(index, 0).astype(np.uint32)),
                         jit_array(mi.Bool, sphere))

    def jump(self, ends, axis, w, kind):
        """f_L - f_R across each pair's crossing: the colors of two rays traced just either
        side of it (LIMIT lattice units, RIM_LIMIT for a visibility edge of the surface seen;
        within the pair; both sides stacked, one trace),
        where they see what L and R see (else the colors of L and R themselves)."""
        count = len(kind)
        rim = max(RIM_LIMIT, FILM_ULPS * self.k * max(self.width, self.height) * 2.0 ** -24)
        limit = np.where(kind == VISIBILITY, rim, LIMIT)
        step = np.minimum(limit, 0.5 * np.minimum(w, 1.0 - w))
        sides = [self.along_axis(ends.L, axis, w + offset) for offset in (-step, step)]
        seen = []  # (the shape each side's ray sees, from the trace's own hits)

        def first_hit(si, ray, hit, shadows):
            seen.append(dr.select(hit, dr.reinterpret_array(mi.UInt32, si.shape), NO_HIT))

        with dr.suspend_grad():
            ray = self.film_rays(*(np.concatenate([side[i] for side in sides]) for i in range(2)))
            color = self.tracer.trace(self.scene, ray, self.terms, first_hit=first_hit).color
            shape = seen[0]
            dr.eval(color, shape)
            colors = _host(color).reshape(2, count, 3)
            shapes = shape.numpy().reshape(2, count)
        same = (shapes[0] == ends.shape[0]) & (shapes[1] == ends.shape[1])
        jump = colors[0] - colors[1]
        if not same.all():
            other = ~same
            jump[other] = self.colors_at(tuple(p[other] for p in ends.L)) \
                - self.colors_at(tuple(p[other] for p in ends.R))
        return jump

    def spread(self, L, axis, w, slope):
        """Where each pair's term goes: (pixel (n, 3), fraction (n, 3)) numpy. The crossing
        stands for the piece of edge inside its band (the lattice row, or column, of unit
        width), which runs along the axis over ``slope`` lattice units centred on the crossing:
        its term is shared by the pixels that piece lies in, by length (at most three)."""
        k = self.k
        ly, lx = L[0] - 1, L[1] - 1  # (the image's lattice point: the ring's at -1)
        band = np.where(axis == 1, ly, lx) // k  # the pixel row (rows) or column (columns)
        c = np.where(axis == 1, lx, ly) + 0.5 + w  # the crossing along the axis, lattice units
        lo, hi = c - 0.5 * slope, c + 0.5 * slope
        first = np.floor(c / k).astype(np.int64) - 1
        limit = np.where(axis == 1, self.width, self.height)
        pixels, fractions = [], []
        for i in range(3):
            along = first + i
            overlap = np.clip(np.minimum(hi, (along + 1) * k) - np.maximum(lo, along * k), 0, None)
            fraction = np.where(slope > 0, overlap / np.where(slope > 0, slope, 1.0),
                                float(i == 1))
            inside = (along >= 0) & (along < limit)
            fractions.append(np.where(inside, fraction, 0.0))
            along = np.clip(along, 0, limit - 1)
            pixels.append(np.where(axis == 1, band * self.width + along, along * self.width + band))
        return np.stack(pixels, -1), np.stack(fractions, -1)

    def crossing(self, table, terms, ray, si, ends, kind, light, line, choices):
        """g at the stacked rays ``ray`` (see g_at), hitting ``si`` (a Float, attached)."""
        left, right = ((ends.shape[i], ends.prim[i], ends.t[i]) for i in (0, 1))
        choice = self.visibility(table, ray, left, right, choices, "first")
        if (kind == SHADOW).any():
            blocker = self.blocker(self.lit, self.occluder, light, ends.l, ends.r)
            choice = self.shadow_crossing(table, ray, si, light, blocker, kind == SHADOW, choice,
                                          choices, "first")
        # checker lines
        if (kind == CHECKER).any():
            choice = self.checker_crossing(terms, si, *line, kind == CHECKER, choice,
                                           choices, "first")
        return choice

    @staticmethod
    def blocker(lit, occluder, index, L, R):
        """(shape, prim) per pair (numpy) of what blocks light ``index`` (per pair: the first
        index of ``lit`` and ``occluder``) at the unlit one of L and R (their flat positions,
        see :func:`flat`; NO_HIT: nothing)."""
        blocked_l = ~picked(lit, index, L)
        return np.where(blocked_l[:, None], picked(occluder, index, L),
                        picked(occluder, index, R))

    def shadow_crossing(self, table, ray, si, light, blocker, which, g, choices, name):
        """g of the shadow pairs ``which`` (numpy) of light ``light`` (per pair) at the hits
        ``si`` of the stacked rays ``ray``: the blocking primitive's inside function on the
        shadow rays; where the unlit sample has no blocker, it faces away from the light
        (the terminator: N.L) or lies outside a spot's cone (cos a, where its sign differs
        between L and R). ``choices``: see g_at (theirs: under ``name`` and the light)."""
        lanes = dr.width(si.p)
        unblocked = jit_array(mi.Bool, stacked(blocker[:, 0] == NO_HIT, lanes))
        for j, source in enumerate(self.lights):
            mask = which & (light == j)
            if not mask.any():
                continue
            wi, _, _ = source.illuminate(si.p)
            shadow = mi.Ray3f(si.p, wi)
            facing = dr.dot(self.tracer.facing_normal(si, ray), wi)
            made = choices.get((name, "shadow", j))
            if has_cone(source):  # a spot's cone edge (cos a = 0) rather than the terminator
                cone = spot_cosine(source, wi)
                if made is None:
                    crosses = signs_differ(*at_l_and_r(dr.detach(cone), len(which)))
                else:
                    crosses = made[0]
                facing = dr.select(on_lanes(crosses, lanes), cone, facing)
            else:
                crosses = None
            edge = made[1] if made is not None else \
                self.crossed_edge(table, shadow, Faces(table, blocker[:, 0], blocker[:, 1]))
            choices[(name, "shadow", j)] = (crosses, edge)
            gs = self.inside(table, shadow, Faces(table, stacked(blocker[:, 0], lanes),
                                                  stacked(blocker[:, 1], lanes)),
                             on_lanes(edge, lanes))
            g = dr.select(jit_array(mi.Bool, stacked(mask, lanes)),
                          dr.select(unblocked, facing, gs), g)
        return g

    def visibility(self, table, ray, left, right, choices, name):
        """g of a visibility edge between the rays of L and R (of the stacked rays ``ray``),
        which see (shape, prim, t) ``left`` and ``right`` (per pair): N is the nearer; N's
        inside function where the other ray's line misses N's primitive, else the other's,
        else (a crease) the difference of the two primitives' distances. ``choices``: see
        g_at (theirs: under ``name``)."""
        lanes = dr.width(ray.d)
        near_is_l = left[2] <= right[2]
        n_shape, n_prim = (np.where(near_is_l, a, b) for a, b in zip(left[:2], right[:2]))
        f_shape, f_prim = (np.where(near_is_l, b, a) for a, b in zip(left[:2], right[:2]))
        made = choices.get((name, "visibility"))
        if made is None:  # N's function where its sign differs between L and R, else F's
            near, far = Faces(table, n_shape, n_prim), Faces(table, f_shape, f_prim)
            n_edge = self.crossed_edge(table, ray, near)
            f_edge = self.crossed_edge(table, ray, far)
            with dr.suspend_grad():
                g_l, g_r = ([self.inside(table, rays, faces, edge)
                             for faces, edge in ((near, n_edge), (far, f_edge))]
                            for rays in at_l_and_r(ray, len(f_shape)))
            use_n = signs_differ(g_l[0], g_r[0])
            use_f = ~use_n & jit_array(mi.Bool, f_shape < STOP) & signs_differ(g_l[1], g_r[1])
            choices[(name, "visibility")] = (n_edge, f_edge, use_n, use_f)
        else:
            n_edge, f_edge, use_n, use_f = made
        near, far = (Faces(table, stacked(shape, lanes), stacked(prim, lanes))
                     for shape, prim in ((n_shape, n_prim), (f_shape, f_prim)))
        gn = self.inside(table, ray, near, on_lanes(n_edge, lanes))
        gf = self.inside(table, ray, far, on_lanes(f_edge, lanes))
        crease = self.depth(table, ray, near) - self.depth(table, ray, far)
        return dr.select(on_lanes(use_n, lanes), gn,
                         dr.select(on_lanes(use_f, lanes), gf, crease))

    def chain_crossing(self, table, terms, ray, si, ends, kind, depth, g, light, line,
                       choices):
        """g of the pairs whose edge is seen along the specular chain, at bounce ``depth``:
        each ray's chain replayed, attached, then the visibility, checker or shadow function
        there (``light``: per pair, the light of a shadow), or (total internal reflection
        switching) the refraction margin at the surface it leaves (the stacked rays
        ``ray``, hitting ``si``)."""
        lanes = dr.width(ray.d)
        bounce = stacked(depth, lanes)
        final_ray, final_si, margin = ray, si, mi.Float(0.0)
        for d in range(int(depth.max()) + 1):
            last = jit_array(mi.Bool, bounce == d)  # (the lanes whose chain ends here)
            margin = dr.select(last, self.refraction_margin(terms, si, ray), margin)
            ray, _, _ = self.chain_step(terms, si, ray)
            dr.eval(ray)
            si = _evaluated(self.tracer.intersect(self.scene, table, ray, coherent=False))
            final_ray = mi.Ray3f(dr.select(last, ray.o, final_ray.o),
                                 dr.select(last, ray.d, final_ray.d))
            final_si = _merge(last, si, final_si)
        d = np.maximum(depth, 0)
        L, R = ends.l, ends.r
        left = tuple(picked(a, d, L) for a in (self.chain_shape, self.chain_prim, self.chain_t))
        right = tuple(picked(a, d, R) for a in (self.chain_shape, self.chain_prim, self.chain_t))
        vis = self.visibility(table, final_ray, left, right, choices, "chain")
        g = dr.select(jit_array(mi.Bool, stacked(kind == CHAIN_VISIBILITY, lanes)), vis, g)
        g = dr.select(jit_array(mi.Bool, stacked(kind == CHAIN_TIR, lanes)), margin, g)
        if (kind == CHAIN_CHECKER).any():
            g = self.checker_crossing(terms, final_si, *line, kind == CHAIN_CHECKER, g,
                                      choices, "chain")
        if (kind == CHAIN_SHADOW).any():
            index = d * len(self.lights) + light
            blocker = self.blocker(self.chain_lit, self.chain_occluder, index, L, R)
            g = self.shadow_crossing(table, final_ray, final_si, light, blocker,
                                     kind == CHAIN_SHADOW, g, choices, "chain")
        return g

    def checker_crossing(self, terms, si, coord, line, which, g, choices, name):
        """g = u / size - m (or v) of the pairs ``which`` (numpy mask), at the hits ``si`` of
        the stacked rays (the size: at L's hit); coord (0: u, 1: v) and the line m per pair
        (numpy). ``choices``: see g_at (the size, under ``name``)."""
        lanes = dr.width(si.t)
        count = len(which)
        made = choices.get((name, "checker"))
        if made is None:  # (L's: the first point set's lanes; not a parameter)
            slot = terms.surfaces.slot(si.shape, si.prim_index, si.is_valid())
            size = dr.gather(mi.Float, terms.surfaces.layout.checker_size, slot)
            size = dr.gather(mi.Float, size, dr.arange(mi.UInt32, count))
            made = choices[(name, "checker")] = (dr.select(size > 0, size, 1.0),)
        size = on_lanes(made[0], lanes)
        u = dr.select(jit_array(mi.Bool, stacked(coord == 0, lanes)), si.uv.x, si.uv.y)
        return dr.select(jit_array(mi.Bool, stacked(which, lanes)),
                         u / size - jit_array(mi.Float, stacked(line, lanes)), g)

    def inside(self, table, ray, faces, edge=None):
        """The inside function of each ray's primitive (``faces``: :class:`Faces`): > 0 where
        the ray's line meets it (see the module docstring). For a triangle, ``edge`` (an
        Int32 per lane: 0, 1, 2, or -1 for the least of the three) picks the edge function."""
        valid, kind, row, prim = faces.valid, faces.kind, faces.row, faces.prim
        out = mi.Float(-1.0)
        d = dr.normalize(ray.d)
        if table.has_spheres:
            sphere = valid & ((kind & SPHERE) != 0)
            oc, d_local, r = self.sphere_frame(table, row, prim, ray.o, d, sphere)
            if table.has_ellipsoids:  # (an ellipsoid's direction in object space: not unit)
                d_local = dr.normalize(d_local)
            out = dr.select(sphere, r - dr.norm(dr.cross(oc, d_local)), out)
        if table.has_meshes:
            mesh = valid & ((kind & MESH) != 0)
            e = self.edge_functions(table, ray, d, row, prim, mesh)
            g = dr.minimum(dr.minimum(e[0], e[1]), e[2])
            if edge is not None:
                chosen = dr.select(edge == 0, e[0], dr.select(edge == 1, e[1], e[2]))
                g = dr.select(edge >= 0, chosen, g)
            out = dr.select(mesh, g, out)
        return out

    @staticmethod
    def sphere_frame(table, row, prim, o, d, sphere):
        """Each lane's ray (o, d) in the frame of its sphere (``HitTable.sphere_frame``):
        row ``row + prim`` (UInt32 ``prim``: 0 for a Mitsuba sphere, the sphere's index in a
        sphere set)."""
        return table.sphere_frame(row + prim, o, d, sphere)

    def edge_functions(self, table, ray, d, row, prim, mesh):
        """The three normalized edge functions of each lane's face, signed to be > 0 inside."""
        _, (p0, p1, p2) = table.corners(row, prim, mesh)
        side = dr.dot(dr.detach(dr.cross(p1 - p0, p2 - p0)), dr.detach(d))
        sigma = dr.select(side <= 0, 1.0, -1.0)
        return [sigma * dr.dot(dr.cross(a - ray.o, b - ray.o), d) / dr.norm(b - a)
                for a, b in ((p0, p1), (p1, p2), (p2, p0))]

    def crossed_edge(self, table, ray, faces):
        """Per pair (an Int32 of P lanes, on the device): the edge of its face (``faces``:
        :class:`Faces`, one per pair) whose function changes sign between the rays of L and
        R (of the stacked rays ``ray``; the first such; -1: none, or not a face)."""
        count = dr.width(faces.prim)
        if not table.has_meshes:
            return dr.full(mi.Int32, -1, count)
        with dr.suspend_grad():
            mesh = faces.valid & ((faces.kind & MESH) != 0)
            sides = []
            for rays in at_l_and_r(ray, count):  # (L's, then R's)
                d = dr.normalize(dr.detach(rays.d))
                rays = mi.Ray3f(dr.detach(rays.o), d)
                sides.append(self.edge_functions(table, rays, d, faces.row, faces.prim, mesh))
            edge = mi.Int32(-1)
            for i in (2, 1, 0):  # (the first edge that flips)
                edge = dr.select(signs_differ(sides[0][i], sides[1][i]), i, edge)
            return dr.select(mesh, edge, -1)

    def depth(self, table, ray, faces):
        """The distance along each ray to its primitive's (``faces``: :class:`Faces`) plane
        or sphere."""
        valid, kind, row, prim = faces.valid, faces.kind, faces.row, faces.prim
        out = mi.Float(0.0)
        if table.has_spheres:
            sphere = valid & ((kind & SPHERE) != 0)
            oc, d, r = self.sphere_frame(table, row, prim, ray.o, ray.d, sphere)
            a, b = dr.squared_norm(d), dr.dot(oc, d)
            root = dr.safe_sqrt(dr.square(b) - a * (dr.squared_norm(oc) - dr.square(r)))
            out = dr.select(sphere, (-b - root) / a, out)
        if table.has_meshes:
            mesh = valid & ((kind & MESH) != 0)
            _, (p0, p1, p2) = table.corners(row, prim, mesh)
            n = dr.cross(p1 - p0, p2 - p0)
            out = dr.select(mesh, dr.dot(n, p0 - ray.o) / dr.dot(n, ray.d), out)
        return out

    # -- the derivative ----------------------------------------------------------------------------
    def backward(self, grad_in):
        """Propagate the image's adjoint ``grad_in`` (numpy (H W, 3)) through the terms."""
        self.trace_keys()
        pairs = self.pairs()
        total = len(pairs["kind"])
        for lo in range(0, total, PAIRS_PER_CHUNK):
            hi = min(lo + PAIRS_PER_CHUNK, total)
            with dr.resume_grad():
                surrogate, (pixel, fraction) = self.surrogates(pairs, lo, hi)
                weight = spread_adjoint(grad_in, pixel, fraction)
                dr.backward_from(surrogate * mi.Color3f(
                    *(jit_array(mi.Float, weight[:, c]) for c in range(3))),
                    flags=dr.ADFlag.Default | dr.ADFlag.AllowNoGrad)

    def forward(self, grads, last):
        """Add the terms' tangents to ``grads`` (numpy (H W, 3)), the parameters' tangents
        set; ``last``: clear them after."""
        self.trace_keys()
        pairs = self.pairs()
        total = len(pairs["kind"])
        for lo in range(0, max(total, 1), PAIRS_PER_CHUNK):
            hi = min(lo + PAIRS_PER_CHUNK, total)
            if hi <= lo:
                break
            with dr.resume_grad():
                surrogate, (pixel, fraction) = self.surrogates(pairs, lo, hi)
                final = last and hi == total
                dr.forward_to(surrogate, flags=dr.ADFlag.AllowNoGrad | (
                    dr.ADFlag.Default if final else dr.ADFlag.ClearEdges | dr.ADFlag.ClearInterior))
                tangent = _host(dr.grad(surrogate))
            for j in range(3):
                np.add.at(grads, pixel[:, j], tangent * fraction[:, j:j + 1])
