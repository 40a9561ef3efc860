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


class Cylinder(mi.Mesh):
    def __init__(self, props):
        segments = _mesh.segment_count(props)
        wall = _mesh.side(segments, lambda y: np.ones_like(y),
                          lambda x, y, z: np.stack([x, np.zeros_like(y), z], -1),
                          np.array([-0.5, 0.5]))
        caps = (_mesh.disk(segments, -0.5, -1.0, 0), _mesh.disk(segments, 0.5, 1.0, 0))
        parts = _mesh.closed([wall, *caps])
        _mesh.initialize(self, "cylinder", props, *parts)
