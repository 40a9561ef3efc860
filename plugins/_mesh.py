"""Shared by the mesh shape plugins: object-space tessellations to world-space Mitsuba meshes.

Conventions, decided here once for every tessellated shape:

* A tessellation is built in the primitive's **object space**, with the exact
  unit normal of the primitive at each vertex and the format's texture
  coordinates (see ``docs/format.md``).
* Longitude: the angle phi around +y, counter-clockwise seen from +y, starting
  at +x, so the ring point at phi is (cos phi, ., -sin phi) and u = phi / 2pi.
  (The same convention as Mitsuba's analytic sphere, rotated so its pole is +y.)
* Winding: each triangle is oriented so that its geometric normal (right-hand
  rule) agrees with the exact normals of its corners: the **outward** side of
  a closed object. ``to_world`` then maps positions by M and normals by the
  inverse transpose of M; when det M < 0 the winding is reversed, so a
  mirroring transform does not turn a surface inside out.
* No cracks: Mitsuba runs Embree in its non-robust mode, whose float32 edge
  tests can reject a ray that passes exactly through an edge shared by two
  triangles *on both sides*, leaving a background-colored pixel (it happens
  systematically in symmetric views: a plane facing the camera, an ellipsoid's
  equator ring at an odd resolution). So every face gets its own three vertices,
  pushed away from its centroid by ``OVERLAP`` of its size, with texture
  coordinates extrapolated alike: neighbours overlap by a sliver far wider than
  the edge test's rounding error and far narrower than anything visible.
"""

import numpy as np
import mitsuba as mi


OVERLAP = 1e-4  # relative growth of each face about its centroid (see "No cracks")


def overlapping(positions, normals, texcoords, faces, grow=OVERLAP):
    """Unshared vertices, each face grown about its centroid by ``grow`` (positions and
    texture coordinates alike, so the texture mapping stays the same affine map)."""
    def grown(values):
        corners = np.asarray(values, np.float64)[faces]
        centroid = corners.mean(axis=1, keepdims=True)
        return (centroid + (corners - centroid) * (1.0 + grow)).reshape(-1, corners.shape[-1])

    flat = np.arange(3 * len(faces)).reshape(-1, 3)
    return grown(positions), normals[faces].reshape(-1, 3), grown(texcoords), flat


def matrix(props):
    """The ``to_world`` property as a 4x4 numpy array (identity when absent)."""
    if "to_world" not in props:
        return np.eye(4)
    return np.array(props.get("to_world").matrix, dtype=np.float64).reshape(4, 4)


def orient_outward(positions, normals, faces):
    """Flip the faces whose right-hand-rule normal disagrees with their vertex normals."""
    p0, p1, p2 = (positions[faces[:, i]] for i in range(3))
    face_n = np.cross(p1 - p0, p2 - p0)
    vertex_n = normals[faces].sum(axis=1)
    wrong = np.einsum("ij,ij->i", face_n, vertex_n) < 0
    faces = faces.copy()
    faces[wrong] = faces[wrong][:, ::-1]
    return faces


def to_world(to_world, positions, normals, faces):
    """Positions by M, normals by M^-T (renormalised), winding reversed when det M < 0."""
    linear, offset = to_world[:3, :3], to_world[:3, 3]
    world_p = positions @ linear.T + offset
    world_n = normals @ np.linalg.inv(linear)  # (M^-T n) for row vectors
    world_n /= np.maximum(np.linalg.norm(world_n, axis=1, keepdims=True), 1e-30)
    if np.linalg.det(linear) < 0:
        faces = faces[:, ::-1]
    return world_p, world_n, faces


def initialize(mesh, name, props, positions, normals, texcoords, faces, smooth=True):
    """Fill ``mesh`` (an mi.Mesh being constructed) with an object-space tessellation."""
    faces = orient_outward(positions, normals, faces)
    positions, normals, texcoords, faces = overlapping(positions, normals, texcoords, faces)
    world_p, world_n, faces = to_world(matrix(props), positions, normals, faces)
    mi.Mesh.__init__(mesh, name, len(world_p), len(faces), props,
                     has_vertex_normals=smooth, has_vertex_texcoords=True)
    params = mi.traverse(mesh)
    params["vertex_positions"] = mi.Float(world_p.astype(np.float32).ravel())
    params["faces"] = mi.UInt32(faces.astype(np.uint32).ravel())
    if smooth:
        params["vertex_normals"] = mi.Float(world_n.astype(np.float32).ravel())
    params["vertex_texcoords"] = mi.Float(np.asarray(texcoords, np.float32).ravel())
    params.update()


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


def disk(segments, y, normal_y, start):
    """A cap at height y: centre vertex then a ring; planar (x, z) texture coordinates."""
    phi, _ = ring(segments)
    x, z = np.cos(phi), -np.sin(phi)
    positions = np.concatenate([[[0.0, y, 0.0]], np.stack([x, np.full_like(x, y), z], -1)])
    normals = np.tile([0.0, normal_y, 0.0], (len(positions), 1))
    texcoords = (positions[:, [0, 2]] + 1.0) * 0.5
    k = np.arange(segments)
    faces = np.stack([np.zeros_like(k), k + 1, k + 2], -1) + start
    return positions, normals, texcoords, faces


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
    return positions, normals, texcoords, faces


def closed(parts):
    """Concatenate (positions, normals, texcoords, faces) parts, offsetting face indices."""
    out, start = [[], [], [], []], 0
    for positions, normals, texcoords, faces in parts:
        for i, a in enumerate((positions, normals, texcoords, faces + start)):
            out[i].append(a)
        start += len(positions)
    return [np.concatenate(a) for a in out]


def segment_count(props):
    """The ``segments`` property of a curved shape (default 128, at least 8)."""
    return max(int(props.get("segments", 128)), 8)
