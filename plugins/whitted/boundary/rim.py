"""The rim correction (the package docstring): the lattice's own error where the interior
derivative is singular -- a sphere's rim, when the sphere or the camera moves -- subtracted
per visibility pair of a sphere (:meth:`Rim.rim_correction`; Hurwitz's zeta(1/2, q),
:func:`hurwitz_zeta_half`)."""

import copy

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..hits import SPHERE, traversed_values
from .lattice import NO_HIT, VISIBILITY, at, flat


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


class Rim:
    """The rim correction of :class:`Boundary`'s terms (a mixin of Boundary)."""

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
        sphere = (kind == VISIBILITY) & (shape != NO_HIT) & (normal2 > 0)
        if not self.camera_moves:  # (a sphere that stays, seen by a still camera)
            sphere &= self.moves(shape)
        sphere &= (self.kinds(shape) & SPHERE) != 0
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
