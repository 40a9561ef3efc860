"""Shared by the mesh shape plugins: an object-space tessellation to a world-space Mitsuba mesh.

The conventions (outward winding, the normals' inverse transpose, the winding reversed
under mirroring, the crack-avoiding overlap of faces) are decided once, in
``raymitsuba/geometry/tessellation.py``; this module applies them to one object and fills an
``mi.Mesh`` (the plane uses it; the translator places many objects at once itself).
"""

import numpy as np
import mitsuba as mi

from raymitsuba.geometry import tessellation
from raymitsuba.plugins.whitted.arrays import jit_array


def matrix(props):
    """The ``to_world`` property as a 4x4 numpy array (identity when absent)."""
    if "to_world" not in props:
        return np.eye(4)
    return np.array(props.get("to_world").matrix, dtype=np.float64).reshape(4, 4)


def initialize(mesh, name, props, positions, normals, texcoords, faces, smooth=True):
    """Fill ``mesh`` (an mi.Mesh being constructed) with an object-space tessellation."""
    faces = tessellation.orient_outward(positions, normals, faces)
    local = tessellation.overlapping(tessellation.Tessellation(positions, normals, texcoords, faces))
    world = tessellation.placed(local, matrix(props)[None])
    mi.Mesh.__init__(mesh, name, len(world.positions), len(world.faces), props,
                     has_vertex_normals=smooth, has_vertex_texcoords=True)
    params = mi.traverse(mesh)
    params["vertex_positions"] = jit_array(mi.Float, world.positions)
    params["faces"] = jit_array(mi.UInt32, world.faces)
    if smooth:
        params["vertex_normals"] = jit_array(mi.Float, world.normals)
    params["vertex_texcoords"] = jit_array(mi.Float, world.texcoords)
    params.update()
