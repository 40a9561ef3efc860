"""``rayplane``: the infinite .RAY plane y = 0 (normal +y) as a mesh that reaches past the horizon.

Mitsuba 3.9.1 has no Python shape interface but ``mi.Mesh``, so the plane is a
finite mesh built to be indistinguishable from the infinite one:

* It is a set of nested square rings in object space, centred at ``center``
  (the foot of the camera on the plane, in the plane's object (x, z)); ring k
  has half-size ``inner`` * 2^k, up to ``outer``. A triangle's size is thus
  proportional to its distance from the camera, so the float32 error of the
  interpolated hit point and texture coordinates stays a fixed, tiny fraction
  of the pixel footprint everywhere: the checkerboard stays exact out to the
  horizon, which a single huge quad would not give.
* ``outer`` is chosen by the translator so far away (10^6 times the camera's
  height over the plane) that the horizon moves by far less than a pixel.

Texture coordinates: object-space (u, v) = (x, z), one repeat per unit; the
checkerboard uses them directly.

Parameters: ``to_world`` (transform); ``center_x``, ``center_z`` (float,
default 0); ``inner`` (float, default 1); ``outer`` (float, default 1e6).
"""

import numpy as np
import mitsuba as mi

from . import _mesh


def square(half):
    """Corners of the square of half-size ``half`` about the origin, counter-clockwise."""
    return np.array([[-half, -half], [half, -half], [half, half], [-half, half]])


class Plane(mi.Mesh):
    # what the Whitted integrator reads (plugins/whitted/protocol.py, UnboundedPlane): the
    # mesh's outline is the horizon, not its outer ring's edge
    unbounded_plane = True

    def __init__(self, props):
        cx, cz = props.get("center_x", 0.0), props.get("center_z", 0.0)
        inner, outer = props.get("inner", 1.0), props.get("outer", 1e6)
        levels = max(int(np.ceil(np.log2(max(outer / inner, 1.0)))), 0) + 1
        xz = np.concatenate([square(inner * 2.0 ** k) for k in range(levels)]) + [cx, cz]
        faces = [[0, 1, 2], [0, 2, 3]]
        for k in range(1, levels):
            a, b = 4 * (k - 1), 4 * k  # inner ring, outer ring
            for i in range(4):
                j = (i + 1) % 4
                faces += [[a + i, b + i, b + j], [a + i, b + j, a + j]]
        positions = np.stack([xz[:, 0], np.zeros(len(xz)), xz[:, 1]], -1)
        normals = np.tile([0.0, 1.0, 0.0], (len(xz), 1))
        _mesh.initialize(self, "plane", props, positions, normals, xz, np.array(faces), smooth=False)
