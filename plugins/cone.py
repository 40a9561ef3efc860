"""``raycone``: the .RAY cone, closed, under any affine transform, as a mesh.

Object space: axis y, base disk of radius 1 at y = -0.5, apex at (0, 0.5, 0).
The side has exact smooth normals, (cos phi, 1, -sin phi) / sqrt 2 at
longitude phi, all the way up: the apex is one vertex per segment, each with the
normal of its segment's middle longitude, so shading does not pinch there.

Texture coordinates: side (longitude / 2pi, y + 0.5); base ((x + 1) / 2, (z + 1) / 2).

Parameters: ``to_world`` (transform); ``segments`` (int, default 128) around the axis.
"""

import numpy as np
import mitsuba as mi

from . import _mesh
from .cylinder import closed, side


def apex_fan(segments):
    """The top row of the side: per-segment apex vertices with mid-segment normals."""
    phi, u = _mesh.ring(segments)
    mid = 0.5 * (phi[:-1] + phi[1:])
    positions = np.tile([0.0, 0.5, 0.0], (segments, 1))
    normals = np.stack([np.cos(mid), np.ones_like(mid), -np.sin(mid)], -1) / np.sqrt(2.0)
    texcoords = np.stack([0.5 * (u[:-1] + u[1:]), np.ones(segments)], -1)
    return positions, normals, texcoords


class Cone(mi.Mesh):
    def __init__(self, props):
        segments = max(int(props.get("segments", 128)), 8)
        base = side(segments, lambda y: 0.5 - y,
                    lambda x, y, z: np.stack([x, np.ones_like(y), z], -1) / np.sqrt(2.0),
                    np.array([-0.5]))
        top_p, top_n, top_t = apex_fan(segments)
        k = np.arange(segments)
        fan = np.stack([k, k + 1, segments + 1 + k], -1)
        wall = (np.concatenate([base[0], top_p]), np.concatenate([base[1], top_n]),
                np.concatenate([base[2], top_t]), fan)
        parts = closed([wall, _mesh.disk(segments, -0.5, -1.0, 0)])
        _mesh.initialize(self, "cone", props, *parts)
