"""``rayellipsoid``: the unit sphere under any affine transform, as a smooth mesh.

Mitsuba's analytic ``sphere`` is exact but ignores non-uniform scale and shear;
the translator uses it for similarity transforms and this shape otherwise. The
unit sphere is tessellated in object space on a latitude/longitude grid with its
exact normals, then mapped by ``to_world`` (see ``_mesh.py``), so a scaled
sphere is a true ellipsoid up to the tessellation error.

Texture coordinates: u = longitude / 2pi (around +y, see ``_mesh.py``),
v = colatitude / pi (0 at +y, 1 at -y).

Parameters:

* ``to_world`` (transform): object to world
* ``segments`` (int, default 128): vertices around a latitude ring; there are
  segments / 2 rings. The silhouette error of a disk of radius r pixels drawn
  with m segments is r (1 - cos(pi / m)) ~ r pi^2 / (2 m^2) pixels.
"""

import numpy as np
import mitsuba as mi

from . import _mesh


class Ellipsoid(mi.Mesh):
    def __init__(self, props):
        segments = _mesh.segment_count(props)
        rings = segments // 2
        phi, u = _mesh.ring(segments)
        theta = np.linspace(0.0, np.pi, rings + 1)
        t, p = np.meshgrid(theta, phi, indexing="ij")
        positions = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], -1)
        positions = positions.reshape(-1, 3)
        uu, vv = np.meshgrid(u, theta / np.pi, indexing="ij")
        texcoords = np.stack([uu.T, vv.T], -1).reshape(-1, 2)
        faces = _mesh.grid_faces(rings, segments)
        # Drop the degenerate halves of the quads at the poles.
        p0, p1, p2 = (positions[faces[:, i]] for i in range(3))
        keep = np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1) > 1e-12
        _mesh.initialize(self, "ellipsoid", props, positions, positions.copy(), texcoords, faces[keep])
