"""Boundary terms: the derivative of the pixel-integrated image where an edge moves.

A pixel's value is the integral of the Whitted tree's color f over the pixel (box filter),
estimated on the uniform k x k lattice of ``spp = k^2`` samples. Where f jumps along a curve
that moves with a parameter theta, the derivative of the integral has, besides the interior
term that automatic differentiation of the samples gives, a boundary term (Reynolds
transport) ``oint (f- - f+) v_n ds``. It is computed here, deterministically, on the same
lattice, for these discontinuities:

* **visibility** (``visibility.py``): silhouettes of analytic spheres, outlines of flat
  meshes (triangles), creases between two surfaces and between faces of a flat mesh that
  are not coplanar;
* **shadow edges** of point, spot and directional lights on the surface seen
  (``shadows.py``), the **terminator** (N.L = 0, where the specular term is cut off; no
  module of its own: a shadow pair whose unlit sample has no blocker, ``shadows.py``'s
  g there and ``samples.py``'s keys, which count N.L <= 0 as unlit) and a spot's **cone**
  (cos a = 0, where a spot of coefficient 0 ends; ``spot.py``);
* **checker lines** on the surface seen (``checker.py``);
* visibility edges, shadow edges and checker lines **seen along the specular chain**
  (``chain.py``), and **total internal reflection** switching on or off along it
  (``tir.py``): the path that follows, from the surface seen, the refracted ray where kt >
  0 (the reflected one under total internal reflection), else the reflected ray where kr >
  0, as many bounces as the tree traces, at most CHAIN_DEPTH (``chain.chain_depth``): so
  eta's derivative sees the checker lines seen through glass, and a mirror's reflection of
  an edge moves with the geometry and the camera.

**The modules.** One per kind of edge, as listed above (``visibility.py``, ``shadows.py``,
``spot.py``, ``checker.py``, ``chain.py``, ``tir.py``; the terminator has none), the rim
correction (``rim.py``), and what every kind shares:

* ``lattice.py``: the lattice's points and the readers of its arrays, the keys' sentinels
  (NO_HIT, STOP), the kinds of pairs (VISIBILITY ... CHAIN_SHADOW) and a pair's points
  (POINTS);
* ``samples.py``: the samples' keys and colors, recorded, traced and written into the
  lattice's arrays (the lattice, below), and the camera rays of lattice points;
* ``pairs.py``: which kinds the keys move, the pairs found and classified by kind, and
  which of them are formed (pairs, below);
* ``terms.py``: g evaluated at stacked rays and dispatched by kind, the crossing, its
  rate and the edge's normal, the jump, the zero-valued surrogates, the pixels a term is
  shared by, and the derivative in reverse and forward mode (the term, below).

:class:`Boundary` is these modules' mixins together (each holds the methods of its part;
the state, the lattice's arrays of keys, is the Boundary's, made here).

The lattice's own error where the interior derivative is singular -- a sphere's rim, when
the sphere or the camera moves -- is subtracted per pair
(``rim.py``: :meth:`Boundary.rim_correction`).

Not covered (left out, documented in docs/gradients.md): the branches of the tree other
than the specular chain, and another edge between the two samples of a visibility pair.
Edges of several kinds or lights between two samples of one surface (a checker line and a
shadow edge, two lights' shadow edges), and an edge on the surface seen with those seen
along the chain (a shadow on a mirror, and an outline in its reflection), are a crossing
each (:meth:`Pairs.classify`), and so are checker lines, however many
(:meth:`Boundary.one_crossing_per_line`).

**The lattice.** The samples of all pixels form one uniform grid over the image, spacing
1/k pixel (sample (sx, sy) of pixel (px, py) is lattice point X = px k + sx, Y = py k + sy).
Each sample's *key* is recorded as the adjoint pass traces it, from its own hits and shadow
rays, in the same kernel (:meth:`Boundary.recorder`: the keys cost no trace of their own;
the renderer's walk through glass finds the stopper too): the shape and face hit (and the face's
normal), the checker cell, for each light whether it is lit, what blocks it first and where
its light stops (``shadows.py``); the same of each bounce of the specular chain (with its total
internal reflection flag) is traced from there (:meth:`Boundary.trace_keys`); the sample's
color f is kept as the adjoint pass leaves it (:meth:`Boundary.collect`). The samples
nearest the border lie half a lattice spacing inside it: an edge between them and the border
would be straddled by no pair, so the lattice has a *ring* of samples outside the image,
half a spacing beyond its border all round (:func:`ring_points`, traced with their keys by
:meth:`Boundary.trace_ring`), paired with the border's; a crossing outside the image adds
nothing (the eye's per-pixel error at k = 4 on benchmarks/edges_bench.py's scene 14.1 % ->
10.4 %). The lattice's arrays hold the ring too: entry (Y + 1, X + 1) is lattice point (Y,
X). These keys take memory (``samples.bytes_per_sample``): a lattice whose keys exceed the
memory budget is refused (BudgetError) before anything is traced.

**Pairs.** Two lattice neighbours (in a row or a column) whose keys differ have an edge
between them. Only the edges that some key with its gradient enabled moves form pairs:
the kinds it moves (:func:`moving_kinds`), and, the camera still, an edge of what moves
(:meth:`Boundary.moving_edges`): any other's term is zero. For each such pair a smooth
signed *crossing function* g(ray, theta) is chosen, whose sign differs between the two
samples:

* a visibility edge of the nearer surface N (the other sample's ray misses N's primitive):
  N's inside function -- r - |(c - o) x d| for a sphere, the least of the three normalized
  edge functions for a triangle (signed by the side of its plane a camera ray starts on,
  or a chain's or shadow ray heads from; of a mesh seen by the camera, the face and edge
  where the segment between L and R leaves the mesh, followed across its faces by their
  neighbours where its look does not jump: a tessellated cap's fan of thin faces, a
  smooth mesh's foreshortened faces at its silhouette; ``Visibility.outline``), for an
  unbounded plane (``rayplane``: its
  outline is the horizon, not the edge of the ring face a ray hit) -(n . (o - p)) (n . d),
  zero at the horizon and where the ray's origin crosses the plane; else the other
  surface's; else (both rays meet both primitives: a crease) the difference of the two
  primitives' hit distances -- which also comes first, for two flat faces of two shapes,
  where its sign changes between L and R at a point that lies on both faces (a cone through
  the floor, whose thin side faces go on under it: the face's own edge, which R's line
  crosses beyond the crease, is not where the surface ends; ``Visibility.crease_first``);
* a shadow edge of light j: the blocking primitive's inside function on the two samples'
  shadow rays (from the attached hit point toward the attached light; a mesh's face
  followed to its outline, as above); where the unlit
  sample has no blocker, it faces away from the light or lies outside a spot's cone: N.L
  at the attached hit (the shading normal facing the ray), or the spot's cos a where its
  sign differs between the two samples;
* a checker line: u / size - m (or v), m the line between the two cells, of the attached
  texture coordinates;
* the same at bounce d of the specular chain (a visibility edge there: another shape, or
  two faces of a mesh across a crease, as at the first hit), each sample's chain replayed
  with derivatives (eta, the geometry, the camera) to that bounce; where total internal
  reflection switches at a surface of the chain, the refraction margin 1 - (eta_i /
  eta_t)^2 (1 - cos^2 theta_i) there.

g is evaluated at the two samples L, R, detached. Where L and R see one face of one shape
(every kind but a visibility edge of the surface seen), each of these rays' hits is solved
on that face, not traced (:meth:`Boundary.hits_at`, ``HitTable.known_hits``): g is then
that surface's own function, smooth where another surface hides a neighbour or the face ends
(the camera's per-pixel error at k = 4 on benchmarks/edges_bench.py's scene: eye 10.4 ->
9.6 %, fov 8.2 -> 7.2 %; and a fifth of the boundary pass's kernel time). With g linear
between L and R the crossing lies at the fraction w = g_L / (g_L - g_R) of the way from L to
R. Where edges crowd, g is seldom linear over a lattice unit (a checker seen through a glass
ball's rim, compressed), so g is evaluated
again, with derivatives (the camera's rays and the geometry as the keys attach them,
``geometry_ad.py``; the lights' own parameters), at two points either side of that
estimate, a quarter of its distance to the nearer sample away. The crossing moves at
du*/dtheta = -dg(u*)/dtheta / g' lattice units, with dg(u*)/dtheta their mean's derivative
and g' their slope where they bracket the crossing (which then lies between them),
elsewhere the secant g_R - g_L (eta through glass over a checkerboard: per-pixel error
20.9 % -> 11.0 % at k = 4 for the refinement; the terminator 3.6 % -> 1.9 %; where they do
not bracket it, L's and R's derivatives interpolated served until the pass with
derivatives was cut to these two points: the benchmark's errors relative to the sum of
sizes moved by at most 0.02 points, its per-pixel errors by less than 0.1 point). Where
they neither bracket it nor lie within g_L .. g_R, g is not monotone between the samples,
and neither the crossing nor its rate is known at the lattice's resolution: the pair adds no
term (``terms.within``; random scene seed 5's ball at k = 16 had one 30 times a pair's
size). The row (column) integral of f changes by (f_L - f_R)
du*/dtheta. Each pair adds, to the pixel in which the crossing lies,

    (f_L - f_R) du*/dtheta / k^2 * n_a^2

where n_a is the component, along the pair's axis, of the edge's unit normal in the lattice:
g's gradient at the crossing, its slope along the axis g' and across it from g at the two
points as far either side of the crossing across the axis, detached
(:meth:`Boundary.slope_across`; until 2026-12-07 the centred differences at L's and R's
neighbours, two lattice units wide, which weighed crowded edges wrongly: a mirror ball's
shadow seen in it near its rim, seed 5's fov at k = 16, per-pixel 7.3 % -> 3.7 %). The rows
estimate the boundary integral, and so do the columns; the
weights n_x^2 + n_y^2 = 1 combine them so that an edge parallel to an axis is counted by the
pairs across it only. The term enters as a zero-valued surrogate with that derivative, so the
primal image does not change by a bit. The crossing stands for the piece of edge in its
lattice band; the term is shared by the pixels that piece lies in (:meth:`Boundary.spread`).
f_L, f_R are the samples' colors (the one-sided limits
within O(1/k) of a pixel). Pairs are processed in chunks (memory bounded), in reverse mode
(``backward``) and forward mode (``forward``).
"""

import drjit as dr
import numpy as np

from raymitsuba.options import GIB

from ..chunks import MAX_CHUNK_LANES
from ..guards import BudgetError
from .chain import CHAIN_DEPTH, Chain, chain_depth
from .checker import Checker
from .lattice import (CHAIN_CHECKER, CHAIN_SHADOW, CHAIN_TIR, CHAIN_VISIBILITY, CHECKER,
                      KINDS, SHADOW, VISIBILITY, lattice_side)
from .pairs import Pairs, light_moves, moving_kinds
from .rim import Rim
from .samples import Samples, bytes_per_sample
from .shadows import Shadows
from .terms import Terms
from .tir import Tir
from .visibility import Visibility

# (what the integrator, the benchmarks and the docs name as ``boundary.X``)
__all__ = ["Boundary", "moving_kinds", "lattice_side", "CHAIN_DEPTH", "chain_depth", "KINDS",
           "VISIBILITY", "SHADOW", "CHECKER", "CHAIN_VISIBILITY", "CHAIN_CHECKER", "CHAIN_TIR",
           "CHAIN_SHADOW"]


class Boundary(Samples, Pairs, Terms, Visibility, Shadows, Checker, Chain, Tir, Rim):
    """The boundary terms of one adjoint pass over a ``width`` x ``height`` image sampled on
    the k x k lattice (``spp`` = k^2) of ``sensor`` (see the package docstring), forming the
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
        self.chain_depth = chain_depth(tracer.max_depth)  # the chain's bounces followed
        surfaces = self.terms.surfaces
        # glass: the lights' keys hold where each light stops (shadows.py), else the first
        # blocker stops it (the stopper arrays are the occluder's)
        self.glass = surfaces is not None and surfaces.any_transparent
        specular = surfaces is not None and surfaces.any_specular  # (a chain at all)
        per_sample = bytes_per_sample(self.chain_depth if specular else 0, len(self.lights),
                                      self.glass)
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
        # shape and face hit, its distance, the face's normal (x, y, z planes: index d * 3 +
        # c), the checker cell there and whether the bounce was a total internal reflection;
        # lit, what blocks it and where it stops, per bounce and light (index d * lights + j)
        self.shape = self.prim = self.t = self.cell = None
        self.normal, self.lit, self.occluder, self.stopper = [], [], [], []  # (normal: x, y, z)
        # the samples' colors as the adjoint pass left them: (first lane, Color3f) per chunk,
        # a lane per camera ray in pixel order (read where a pair's jump needs them)
        self.colors = []
        # the first hits' keys recorded by the adjoint pass (recorder), or by the primal
        # render before it (adopt), and the ring's (trace_ring): {name: Dr.Jit array, an
        # entry per lattice point, row-major}
        self.recorded = {}
        self.adopted = False  # whether they are those a primal render recorded (adopt)
        self.chain_shape, self.chain_prim, self.chain_t, self.chain_cell = [], [], [], []
        self.chain_tir, self.chain_lit, self.chain_occluder, self.chain_stopper = [], [], [], []
        self.chain_normal = []

    def kinds(self, shapes):
        """HitTable's kind bits (MESH, SMOOTH, SPHERE, ...) of the shapes ``shapes`` (numpy
        registry ids, as the lattice holds them): 0 for NO_HIT, STOP and any id the table
        does not hold."""
        known = shapes < len(self.kind_of)
        return np.where(known, self.kind_of[np.where(known, shapes, 0)], 0)
