"""``raycone``: the .RAY cone, closed, under any affine transform, as a mesh.

Object space: axis y, base disk of radius 1 at y = -0.5, apex at (0, 0.5, 0).
The side has exact smooth normals, (cos phi, 1, -sin phi) / sqrt 2 at
longitude phi, all the way up: the apex is one vertex per segment, each with the
normal of its segment's middle longitude, so shading does not pinch there.

The side is a stack of rings whose radii shrink by ``RING_RATIO`` up to about one
segment's width, then the fan to the apex. (A single fan from the base ring to the
apex would interpolate the apex's mid-segment normal into the whole height: at a
fraction h of the way up, the normal's longitude would be off by up to h / 2 of a
segment. Between rings of radius ratio 0.8 it is off by < 6% of a segment, and the
fan's error is confined to the tip.)

Texture coordinates: side (longitude / 2pi, y + 0.5); base ((x + 1) / 2, (z + 1) / 2).

Parameters: ``to_world`` (transform); ``segments`` (int, default 128) around the axis.
"""

import numpy as np
import mitsuba as mi

from . import _mesh

RING_RATIO = 0.8


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
        segments = _mesh.segment_count(props)
        # ring radii 1, 0.8, 0.64, ... down to about one segment's width 2 pi / segments
        rings = max(int(np.ceil(np.log(2.0 * np.pi / segments) / np.log(RING_RATIO))), 0) + 1
        heights = 0.5 - RING_RATIO ** np.arange(rings)
        base = _mesh.side(segments, lambda y: 0.5 - y,
                          lambda x, y, z: np.stack([x, np.ones_like(y), z], -1) / np.sqrt(2.0),
                          heights)
        top_p, top_n, top_t = apex_fan(segments)
        k = np.arange(segments)
        top_ring = (rings - 1) * (segments + 1)
        fan = np.stack([top_ring + k, top_ring + k + 1, len(base[0]) + k], -1)
        wall = (np.concatenate([base[0], top_p]), np.concatenate([base[1], top_n]),
                np.concatenate([base[2], top_t]), np.concatenate([base[3], fan]))
        parts = _mesh.closed([wall, _mesh.disk(segments, -0.5, -1.0, 0)])
        _mesh.initialize(self, "cone", props, *parts)
