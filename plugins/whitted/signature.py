"""Path signatures: what a sample's ray tree saw, as one UInt32, so that anti-aliasing can
tell a pixel whose samples all saw the same things from a pixel an edge crosses.

A sample's value jumps only where its ray tree changes: another surface or primitive is
hit (a silhouette, a crease), a shadow ray is blocked by other surfaces (a shadow's
edge), a light's cone begins, a child ray appears or vanishes (total internal
reflection), a ray misses. Between such changes it varies smoothly, but for the
textures: a checkerboard averaged over the sample's footprint (``checker_filtered``) is
smooth as well; one point sampled, or an image texture, is not.

The signature of a ray tree is a hash of, at each of its hits, the surface (shape and
primitive, or a flat face's plane) and, for each light, whether it lights the point and
the transmittance of its shadow ray (a product of the kt of the surfaces crossed: the
same surfaces crossed, the same bits); of a miss, :data:`MISS`; mixed with its children's
signatures, each where the child exists and its path weight is above the tracer's cut
(``Tracer.trace``'s ``signed``). The hash is the low 29 bits. The top bit,
:data:`POINT_SAMPLED`, is set where some hit of the tree read a texture at a point: such
a tree's samples may differ with no change of signature. Bits 29 and 30
(:data:`GRID_BITS`) hold the finest grid the tree's checkerboard footprints need, where
perspective distorts them past first order or they hold a corner of the board
(:func:`grid_code`).

Two samples of equal hashes without POINT_SAMPLED saw the same surfaces, lit by the same
lights through the same blockers, and differ only smoothly (``antialias.py`` reads this).
Different trees could share a hash by a collision: one in 2^29.
"""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..checkerboard import FIRST_ORDER

POINT_SAMPLED = 0x80000000  # the top bit: a texture was read at a point somewhere in the tree
GRID_SHIFT = 29  # bits 29 and 30: the grid side, less 1, that the tree's footprints need
GRID_BITS = 0x3 << GRID_SHIFT
HASH_BITS = (1 << GRID_SHIFT) - 1  # the other bits: the hash
MISS = 0x0545F491  # the signature of a ray that hits nothing
MAX_GRID = 4  # the finest grid a footprint's distortion asks for


def mix(h, value):
    """``h`` (UInt32) mixed with ``value`` (UInt32): an avalanching integer hash of the two."""
    h = (h ^ value) * 0x9E3779B1
    h ^= h >> 15
    h *= 0x85EBCA77
    return h ^ (h >> 13)


def light_code(lit, transmittance, intensity):
    """What a light contributes to a hit's signature: 0 where it does not light the point
    (``lit``: the surface faces it; ``intensity`` (Color3f) > 0: inside a spotlight's
    cone), else the bits of the shadow ray's ``transmittance`` (1.0 unblocked)."""
    on = lit & (dr.max(intensity) > 0) & (transmittance > 0)
    bits = dr.reinterpret_array(mi.UInt32, dr.detach(mi.Float(transmittance)))
    return dr.select(on, bits | 1, mi.UInt32(0))


def grid_code(distortion):
    """The grid side, less 1, at which each sample's footprint is distorted by at most
    FIRST_ORDER where a footprint of the whole pixel's is by ``distortion``
    (``checkerboard.residual_distortion``; a sample of an n x n grid has 1/n of it), at
    most MAX_GRID, in the bits of GRID_BITS."""
    side = dr.clip(dr.ceil(distortion * (1.0 / FIRST_ORDER)), 1.0, float(MAX_GRID))
    return (mi.UInt32(side) - 1) << GRID_SHIFT


def local(hit, shape, surface, light_codes, point_sampled, grid=None):
    """The signature of each lane's own hit: its ``shape`` (a ShapePtr) and which
    ``surface`` of it (UInt32, ``HitTable.surface_key``: a primitive, a flat face's plane), the
    lights' codes (:func:`light_code`, in order), ``point_sampled`` (Bool: a texture read
    at a point) and ``grid`` (:func:`grid_code`, or None: 0); :data:`MISS` where there is no
    ``hit``."""
    h = mix(mi.UInt32(0x3C6EF372), dr.reinterpret_array(mi.UInt32, shape))
    h = mix(h, surface)
    for code in light_codes:
        h = mix(h, code)
    h = (h & HASH_BITS) | dr.select(point_sampled, mi.UInt32(POINT_SAMPLED), mi.UInt32(0))
    if grid is not None:
        h |= grid
    return dr.select(hit, h, mi.UInt32(MISS))


def with_children(own, children):
    """The signature of a tree from its root's ``own`` and its children's ``children``
    ((signature, exists) pairs, in order): those that exist mixed in (a root without
    children keeps its own: the same whether or not the batch traced any child at all);
    :data:`POINT_SAMPLED` if any of them has it, the finest grid any of them needs."""
    h, sampled, grid = own & HASH_BITS, own & POINT_SAMPLED, own & GRID_BITS
    for k, (signature, exists) in enumerate(children):
        # (+ k: a reflected child is not a refracted one)
        h = dr.select(exists, mix(h, (signature & HASH_BITS) + k), h)
        sampled |= dr.select(exists, signature & POINT_SAMPLED, 0)
        grid = dr.maximum(grid, dr.select(exists, signature & GRID_BITS, 0))
    return (h & HASH_BITS) | sampled | grid


def agree(centre, corners):
    """(H, W) bool, numpy: the pixels whose centre's signature (``centre``, (H, W) uint32)
    equals in its hash those of its four corners (``corners``, (H + 1, W + 1) uint32) and of
    the centres of its four neighbours (where ``centre`` has them), none of them
    :data:`POINT_SAMPLED`. (The neighbours: an edge that clips a pixel between two of its
    corners, a silhouette's curve along the pixel's side, passes between its centre and a
    neighbour's.)"""
    height, width = centre.shape
    own = centre & HASH_BITS
    same = (centre & POINT_SAMPLED) == 0
    for corner in _corners(corners, height, width):
        same &= (corner & (HASH_BITS | POINT_SAMPLED)) == own
    keys = centre & (HASH_BITS | POINT_SAMPLED)
    same[1:] &= keys[:-1] == own[1:]
    same[:-1] &= keys[1:] == own[:-1]
    same[:, 1:] &= keys[:, :-1] == own[:, 1:]
    same[:, :-1] &= keys[:, 1:] == own[:, :-1]
    return same


def one_path(centre, samples):
    """(count,) bool, numpy: the pixels whose samples' signatures (``samples``, (count, n)
    uint32) all equal its centre's (``centre``, (count,)) in their hash, none of them, nor
    the centre, :data:`POINT_SAMPLED`."""
    same = (centre & POINT_SAMPLED) == 0
    return same & ((samples & (HASH_BITS | POINT_SAMPLED))
                   == (centre & HASH_BITS)[:, None]).all(axis=1)


def grid_sides(centre, corners):
    """(H, W) int, numpy: the finest grid side (1 .. MAX_GRID) that the footprints of a
    pixel's five samples need (:func:`grid_code`)."""
    code = centre & GRID_BITS
    for corner in _corners(corners, *centre.shape):
        code = np.maximum(code, corner & GRID_BITS)
    return (code >> GRID_SHIFT).astype(np.int64) + 1


def _corners(corners, height, width):
    """The four (H, W) views of ``corners`` ((H + 1, W + 1)): each pixel's corner."""
    return [corners[dy:dy + height, dx:dx + width] for dy in (0, 1) for dx in (0, 1)]
