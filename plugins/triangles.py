"""``raytriangles``: the .RAY triangles that share one surface, merged into one mesh.

The translator gives world-space corners already oriented: the front side of
each triangle (right-hand rule on its object-space corners, carried to the
world by the inverse transpose of its transform) is the side its world-space
winding points to. Faces are flat (no vertex normals).

Texture coordinates: (0, 0), (1, 0), (0, 1) at the first, second and third
corner as written in the file.

Parameters: ``positions`` (mi.Float, x y z of each corner, 9 per triangle, world
space); ``texcoords`` (mi.Float, u v of each corner, 6 per triangle).
"""

import numpy as np
import mitsuba as mi


class Triangles(mi.Mesh):
    def __init__(self, props):
        positions = np.asarray(props.get("positions").numpy(), np.float32).reshape(-1, 3)
        texcoords = np.asarray(props.get("texcoords").numpy(), np.float32).reshape(-1, 2)
        count = len(positions) // 3
        mi.Mesh.__init__(self, "triangles", len(positions), count, props,
                         has_vertex_normals=False, has_vertex_texcoords=True)
        params = mi.traverse(self)
        params["vertex_positions"] = mi.Float(positions.ravel())
        params["faces"] = mi.UInt32(np.arange(3 * count, dtype=np.uint32))
        params["vertex_texcoords"] = mi.Float(texcoords.ravel())
        params.update()
