"""Which faces of a triangle mesh meet along an edge: each face's neighbours.

Faces meet where their corners' *positions* are equal, whatever their vertex indices: a
mesh may repeat a vertex to give it two normals or texture coordinates (a cylinder's
rim, a sphere's seam), or give every face its own three vertices (``tessellation.py``).
Edge i of a face runs from its corner i to corner i + 1 (mod 3). The neighbour across it
is the one other face with that edge; an edge no other face has (the mesh's border), or
more than one has (a non-manifold fan), has none: NONE (-1; 0xFFFFFFFF as the plugins'
uint32).
"""

import numpy as np

NONE = -1


def face_neighbours(faces: np.ndarray, positions: np.ndarray, decimals=None) -> np.ndarray:
    """The neighbours of the faces ``faces`` ((F, 3) vertex indices) of one mesh, vertices at
    ``positions`` ((V, 3)): an (F, 3) int64 array of face indices, NONE where none.
    ``decimals``: positions are equal when equal rounded to this many decimals (a template
    in double precision, whose seam is computed twice); None: when their float32 values are
    (-0.0 = 0.0)."""
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    out = np.full(faces.shape, NONE, np.int64)
    if not len(faces):
        return out
    positions = np.asarray(positions).reshape(-1, 3)
    if decimals is None:
        exact = positions.astype(np.float32) + np.float32(0.0)
    else:
        exact = np.round(np.asarray(positions, np.float64), decimals) + 0.0
    _, place = np.unique(exact, axis=0, return_inverse=True)
    corner = place.ravel()[faces]
    a, b = corner, np.roll(corner, -1, axis=1)  # edge i: corners i, i + 1
    key = (np.minimum(a, b) * (int(place.max()) + 1) + np.maximum(a, b)).ravel()
    key[(a == b).ravel()] = -1  # (a degenerate face's collapsed edge: no neighbour)
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    starts = np.flatnonzero(np.r_[True, sorted_key[1:] != sorted_key[:-1]])
    sizes = np.diff(np.r_[starts, len(key)])
    two = starts[(sizes == 2) & (sorted_key[starts] >= 0)]
    first, second = order[two], order[two + 1]  # (half-edges: face * 3 + edge)
    flat = out.ravel()
    flat[first], flat[second] = second // 3, first // 3
    return out


def shifted(neighbours: np.ndarray, faces: int) -> np.ndarray:
    """``neighbours`` (face indices, NONE where none) of a mesh whose faces come ``faces``
    later in a larger one: the indices moved by ``faces``, NONE kept."""
    return np.where(neighbours == NONE, NONE, neighbours + faces)
