"""``raycylinder``: the .RAY cylinder, closed, under any affine transform, as a mesh.

Object space: axis y, radius 1, y from -0.5 to 0.5, side and both caps.
(Mitsuba's ``cylinder`` is open, runs along z and refuses non-uniform scale.)
The side has exact smooth normals; the caps are flat.

Texture coordinates: side (longitude / 2pi, y + 0.5); caps ((x + 1) / 2, (z + 1) / 2).

Parameters: ``to_world`` (transform); ``segments`` (int, default 128) around the axis.
"""

import numpy as np
import mitsuba as mi

from . import _mesh


def side(segments, radius_at, normal_at, heights):
    """A surface of revolution about y sampled at ``heights`` (bottom to top)."""
    phi, u = _mesh.ring(segments)
    y, p = np.meshgrid(heights, phi, indexing="ij")
    r = radius_at(y)
    positions = np.stack([r * np.cos(p), y, -r * np.sin(p)], -1).reshape(-1, 3)
    normals = normal_at(np.cos(p), y, -np.sin(p)).reshape(-1, 3)
    uu, vv = np.meshgrid(u, heights + 0.5, indexing="xy")
    texcoords = np.stack([uu, vv], -1).reshape(-1, 2)
    faces = _mesh.grid_faces(len(heights) - 1, segments)
    return positions, normals, texcoords, faces


def closed(parts):
    """Concatenate (positions, normals, texcoords, faces) parts, offsetting face indices."""
    out, start = [[], [], [], []], 0
    for positions, normals, texcoords, faces in parts:
        for i, a in enumerate((positions, normals, texcoords, faces + start)):
            out[i].append(a)
        start += len(positions)
    return [np.concatenate(a) for a in out]


class Cylinder(mi.Mesh):
    def __init__(self, props):
        segments = max(int(props.get("segments", 128)), 8)
        wall = side(segments, lambda y: np.ones_like(y),
                    lambda x, y, z: np.stack([x, np.zeros_like(y), z], -1),
                    np.array([-0.5, 0.5]))
        parts = closed([wall, _mesh.disk(segments, -0.5, -1.0, 0), _mesh.disk(segments, 0.5, 1.0, 0)])
        _mesh.initialize(self, "cylinder", props, *parts)
