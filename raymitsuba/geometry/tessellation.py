"""Tessellations of the .RAY quadrics: object-space templates, placed in the world in bulk.

A curved object (sphere, cylinder, cone) under an affine transform M is drawn as a
triangle mesh: the primitive's object-space tessellation with ``segments`` vertices
around its axis (:func:`template`), mapped by M. All the objects that share a
template are placed at once with numpy (:func:`placed`), so the cost is a few
array operations per (kind, segment count), not Python work per object or vertex.

Conventions, decided here once for every tessellated shape:

* A template is built in the primitive's **object space**, with the exact unit
  normal of the primitive at each vertex and the format's texture coordinates
  (see ``docs/format.md``).
* Longitude: the angle phi around +y, counter-clockwise seen from +y, starting
  at +x, so the ring point at phi is (cos phi, ., -sin phi) and u = phi / 2pi.
  (The same convention as Mitsuba's analytic sphere, rotated so its pole is +y.)
* Winding: each triangle is oriented so that its geometric normal (right-hand
  rule) agrees with the exact normals of its corners: the **outward** side of
  a closed object. Placing maps positions by M and normals by the inverse
  transpose of M; when det M < 0 the winding is reversed, so a mirroring
  transform does not turn a surface inside out.
* No cracks: Mitsuba runs Embree in its non-robust mode, whose float32 edge
  tests can reject a ray that passes exactly through an edge shared by two
  triangles *on both sides*, leaving a background-colored pixel (it happens
  systematically in symmetric views: a plane facing the camera, an ellipsoid's
  equator ring at an odd resolution). So every face gets its own three vertices,
  pushed away from its centroid by ``OVERLAP`` of its size, with texture
  coordinates extrapolated alike: neighbours overlap by a sliver far wider than
  the edge test's rounding error and far narrower than anything visible. (An
  affine map keeps centroids and ratios, so growing in object space is growing
  in the world.) Which faces meet is then no longer told by equal positions: a
  template's faces' neighbours (``Tessellation.neighbours``, ``topology.py``) are
  matched before they grow, and carried with the faces into the world's meshes (the
  edge derivatives follow a mesh's outline by them).

The primitives' object spaces and texture coordinates:

* sphere: the unit sphere on a latitude/longitude grid of ``segments / 2`` rings;
  u = longitude / 2pi, v = colatitude / pi (0 at +y, 1 at -y).
* cylinder: axis y, radius 1, y from -0.5 to 0.5, closed by flat caps; side
  (longitude / 2pi, y + 0.5), caps ((x + 1) / 2, (z + 1) / 2).
* cone: base disk of radius 1 at y = -0.5, apex (0, 0.5, 0), closed by a flat base.
  The side's normals are exact, (cos phi, 1, -sin phi) / sqrt 2, all the way up: the
  apex is one vertex per segment, with the normal of its segment's middle longitude.
  The side is a stack of rings whose radii shrink by ``RING_RATIO`` down to about one
  segment's width, then the fan to the apex (a single fan from the base would
  interpolate the apex's mid-segment normal into the whole height; between rings
  of ratio 0.8 the normal's longitude is off by < 6% of a segment, and the fan's
  error is confined to the tip). Texture coordinates as the cylinder's.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np

from . import topology

OVERLAP = 1e-4  # relative growth of each face about its centroid (see "No cracks")
RING_RATIO = 0.8  # the cone's ring radii 1, 0.8, 0.64, ...


class Tessellation(NamedTuple):
    positions: np.ndarray  # (V, 3) float64
    normals: np.ndarray  # (V, 3) float64, unit
    texcoords: np.ndarray  # (V, 2) float64
    faces: np.ndarray  # (F, 3) int64 indices into the vertices
    # (F, 3) int: the face across each edge (topology.face_neighbours, topology.NONE: none),
    # of a template and what is made of it; None: not known (a template's pieces)
    neighbours: object = None


# -- pieces of the templates ---------------------------------------------------------------------
def ring(segments):
    """Longitudes phi_k = 2 pi k / segments, k = 0..segments (the seam repeated), and u = phi / 2pi."""
    u = np.linspace(0.0, 1.0, segments + 1)
    return 2.0 * np.pi * u, u


def grid_faces(rows, cols, start=0):
    """Two triangles per cell of a (rows+1) x (cols+1) vertex grid stored row by row."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = start + r * (cols + 1) + c
    b, d = a + 1, a + cols + 1
    quads = np.stack([a, b, d + 1, d], axis=-1).reshape(-1, 4)
    return np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def disk(segments, y, normal_y):
    """A flat cap at height y: centre vertex then a ring; planar (x, z) texture coordinates."""
    phi, _ = ring(segments)
    x, z = np.cos(phi), -np.sin(phi)
    positions = np.concatenate([[[0.0, y, 0.0]], np.stack([x, np.full_like(x, y), z], -1)])
    normals = np.tile([0.0, normal_y, 0.0], (len(positions), 1))
    texcoords = (positions[:, [0, 2]] + 1.0) * 0.5
    k = np.arange(segments)
    faces = np.stack([np.zeros_like(k), k + 1, k + 2], -1)
    return Tessellation(positions, normals, texcoords, faces)


def side(segments, radius_at, normal_at, heights):
    """A surface of revolution about y sampled at ``heights`` (bottom to top)."""
    phi, u = ring(segments)
    y, p = np.meshgrid(heights, phi, indexing="ij")
    r = radius_at(y)
    positions = np.stack([r * np.cos(p), y, -r * np.sin(p)], -1).reshape(-1, 3)
    normals = normal_at(np.cos(p), y, -np.sin(p)).reshape(-1, 3)
    uu, vv = np.meshgrid(u, heights + 0.5, indexing="xy")
    texcoords = np.stack([uu, vv], -1).reshape(-1, 2)
    faces = grid_faces(len(heights) - 1, segments)
    return Tessellation(positions, normals, texcoords, faces)


def concatenated(parts):
    """One tessellation of several parts (face indices offset)."""
    starts = np.cumsum([0] + [len(p.positions) for p in parts[:-1]])
    return Tessellation(*(np.concatenate([getattr(p, f) for p in parts])
                          for f in ("positions", "normals", "texcoords")),
                        np.concatenate([p.faces + s for p, s in zip(parts, starts)]))


# -- the primitives ------------------------------------------------------------------------------
def sphere(segments):
    rings = segments // 2
    phi, u = ring(segments)
    theta = np.linspace(0.0, np.pi, rings + 1)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    positions = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    uu, vv = np.meshgrid(u, theta / np.pi, indexing="ij")
    texcoords = np.stack([uu.T, vv.T], -1).reshape(-1, 2)
    faces = grid_faces(rings, segments)
    # Drop the degenerate halves of the quads at the poles.
    p0, p1, p2 = (positions[faces[:, i]] for i in range(3))
    keep = np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1) > 1e-12
    return Tessellation(positions, positions.copy(), texcoords, faces[keep])


def cylinder(segments):
    wall = side(segments, np.ones_like, lambda x, y, z: np.stack([x, np.zeros_like(y), z], -1),
                np.array([-0.5, 0.5]))
    return concatenated([wall, disk(segments, -0.5, -1.0), disk(segments, 0.5, 1.0)])


def cone_rings(segments):
    """Rings of the cone's side below the apex fan: radii 1, 0.8, ... down to about one
    segment's width 2 pi / segments."""
    return max(int(np.ceil(np.log(2.0 * np.pi / segments) / np.log(RING_RATIO))), 0) + 1


def cone(segments):
    rings = cone_rings(segments)
    heights = 0.5 - RING_RATIO ** np.arange(rings)
    wall = side(segments, lambda y: 0.5 - y,
                lambda x, y, z: np.stack([x, np.ones_like(y), z], -1) / np.sqrt(2.0), heights)
    # The apex: one vertex per segment, with its segment's mid-longitude normal.
    phi, u = ring(segments)
    mid = 0.5 * (phi[:-1] + phi[1:])
    apex = Tessellation(np.tile([0.0, 0.5, 0.0], (segments, 1)),
                        np.stack([np.cos(mid), np.ones_like(mid), -np.sin(mid)], -1) / np.sqrt(2.0),
                        np.stack([0.5 * (u[:-1] + u[1:]), np.ones(segments)], -1),
                        np.zeros((0, 3), np.int64))
    k = np.arange(segments)
    top_ring = (rings - 1) * (segments + 1)
    fan = np.stack([top_ring + k, top_ring + k + 1, len(wall.positions) + k], -1)
    wall = concatenated([wall, apex])._replace(faces=np.concatenate([wall.faces, fan]))
    return concatenated([wall, disk(segments, -0.5, -1.0)])


PRIMITIVES = {"sphere": sphere, "cylinder": cylinder, "cone": cone}


def triangle_count(kind, segments):
    """Triangles of ``template(kind, segments)``, in closed form (the budget needs it for
    every candidate segment count). ``segments`` may be an array."""
    m = np.asarray(segments, dtype=np.int64)
    if kind == "sphere":  # segments/2 rings of 2 m triangles, less the m degenerate at each pole
        return m * m - 2 * m
    if kind == "cylinder":  # side 2 m, caps m each
        return 4 * m
    if kind == "cone":  # (rings - 1) bands of 2 m, the apex fan m, the base m
        rings = np.maximum(np.ceil(np.log(2.0 * np.pi / m) / np.log(RING_RATIO)), 0).astype(np.int64) + 1
        return 2 * m * rings
    raise ValueError(f"no tessellation for {kind}")


# -- outward, overlapping, placed ----------------------------------------------------------------
def orient_outward(positions, normals, faces):
    """Flip the faces whose right-hand-rule normal disagrees with their vertex normals."""
    p0, p1, p2 = (positions[faces[:, i]] for i in range(3))
    face_n = np.cross(p1 - p0, p2 - p0)
    vertex_n = normals[faces].sum(axis=1)
    wrong = np.einsum("ij,ij->i", face_n, vertex_n) < 0
    faces = faces.copy()
    faces[wrong] = faces[wrong][:, ::-1]
    return faces


def overlapping(mesh: Tessellation, grow=OVERLAP) -> Tessellation:
    """Unshared vertices, three per face in face order, each face grown about its centroid
    by ``grow`` (positions and texture coordinates alike, so the texture mapping stays the
    same affine map). The faces are then (0 1 2), (3 4 5), ..."""
    def grown(values):
        corners = np.asarray(values, np.float64)[mesh.faces]
        centroid = corners.mean(axis=1, keepdims=True)
        return (centroid + (corners - centroid) * (1.0 + grow)).reshape(-1, corners.shape[-1])

    flat = np.arange(3 * len(mesh.faces)).reshape(-1, 3)
    return Tessellation(grown(mesh.positions), mesh.normals[mesh.faces].reshape(-1, 3),
                        grown(mesh.texcoords), flat, mesh.neighbours)


@functools.lru_cache(maxsize=None)
def template(kind: str, segments: int) -> Tessellation:
    """The object-space tessellation of a primitive with ``segments`` around its axis:
    outward, overlapping, three vertices per face (read-only arrays, shared)."""
    mesh = PRIMITIVES[kind](segments)
    faces = orient_outward(mesh.positions, mesh.normals, mesh.faces)
    # (neighbours where the faces meet before they grow apart; the seam's and the rim's
    # vertices, computed twice in double precision, equal to 9 decimals)
    mesh = overlapping(mesh._replace(faces=faces, neighbours=topology.face_neighbours(
        faces, mesh.positions, decimals=9)))
    for a in mesh:
        a.setflags(write=False)
    return mesh


def placed(mesh: Tessellation, to_world: np.ndarray) -> Tessellation:
    """Copies of an overlapping ``mesh`` under each of the k transforms ``to_world`` (k, 4, 4):
    positions by M, normals by M^-T (renormalised), winding reversed where det M < 0.
    Returns (k V) vertices and (k F) faces, the copies one after another."""
    linear, offset = to_world[:, :3, :3], to_world[:, :3, 3]
    positions = mesh.positions @ linear.transpose(0, 2, 1) + offset[:, None, :]  # (k, V, 3)
    normals = mesh.normals @ np.linalg.inv(linear)  # (M^-T n) as rows
    normals /= np.maximum(np.sqrt(np.square(normals).sum(axis=-1, keepdims=True)), 1e-30)
    count = len(mesh.positions)
    corner_order = np.where(np.linalg.det(linear)[:, None] < 0, [0, 2, 1], [0, 1, 2])  # (k, 3)
    first = 3 * np.arange(len(mesh.faces))  # each face's first vertex (faces are 0 1 2, 3 4 5, ...)
    faces = (first[None, :, None] + corner_order[:, None, :]
             + (count * np.arange(len(to_world)))[:, None, None])
    texcoords = np.broadcast_to(mesh.texcoords, (len(to_world),) + mesh.texcoords.shape)
    neighbours = None
    if mesh.neighbours is not None:  # each copy's, its faces offset; a mirrored copy's edges
        # run the other way round (corners 0 2 1: its edges 0, 1, 2 are the template's 2, 1, 0)
        edge_order = np.where(np.linalg.det(linear)[:, None] < 0, [2, 1, 0], [0, 1, 2])
        across = mesh.neighbours[:, edge_order].transpose(1, 0, 2)  # (k, F, 3)
        neighbours = topology.shifted(
            across, (len(mesh.faces) * np.arange(len(to_world)))[:, None, None]).reshape(-1, 3)
    return Tessellation(positions.reshape(-1, 3), normals.reshape(-1, 3),
                        texcoords.reshape(-1, 2), faces.reshape(-1, 3), neighbours)


def merged(batches, chunk_vertices=1 << 20) -> Tessellation:
    """One float32 mesh of many placed copies: ``batches`` is [(overlapping template, transforms
    (k, 4, 4))]. Placed a chunk of objects at a time into preallocated arrays, so the float64
    intermediates stay below ``chunk_vertices`` vertices whatever the scene's size."""
    vertices = sum(len(t.positions) * len(m) for t, m in batches)
    faces = sum(len(t.faces) * len(m) for t, m in batches)
    out = Tessellation(np.empty((vertices, 3), np.float32), np.empty((vertices, 3), np.float32),
                       np.empty((vertices, 2), np.float32), np.empty((faces, 3), np.uint32),
                       np.empty((faces, 3), np.int32))
    v0 = f0 = 0
    for mesh, to_world in batches:
        step = max(chunk_vertices // len(mesh.positions), 1)
        for i in range(0, len(to_world), step):
            part = placed(mesh, to_world[i:i + step])
            v1, f1 = v0 + len(part.positions), f0 + len(part.faces)
            out.positions[v0:v1], out.normals[v0:v1] = part.positions, part.normals
            out.texcoords[v0:v1], out.faces[f0:f1] = part.texcoords, part.faces + v0
            out.neighbours[f0:f1] = topology.shifted(part.neighbours, f0)
            v0, f0 = v1, f1
    return out
