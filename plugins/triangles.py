"""``raytriangles``: a world-space triangle mesh given as arrays; the translator's merged meshes.

The translator builds every mesh in bulk (all the ``triangle`` lines of one surface;
all the tessellated spheres, cylinders and cones of one surface) and hands the
arrays over; this plugin only wraps them in an ``mi.Mesh``, without copying.

The winding is the translator's: for ``triangle`` lines the front side of each
triangle (right-hand rule on its object-space corners, carried to the world by the
inverse transpose of its transform) is the side its world-space winding points to;
for tessellations, the outward side (see ``raymitsuba/geometry/tessellation.py``).

Parameters:

* ``positions`` (mi.Float): x y z of each vertex, world space;
* ``texcoords`` (mi.Float): u v of each vertex;
* ``faces`` (mi.UInt32, optional): three vertex indices per triangle; default: the
  vertices taken three by three (0 1 2, 3 4 5, ...);
* ``normals`` (mi.Float, optional): x y z unit vertex normals; given, the mesh is
  smooth-shaded; absent, its faces are flat;
* ``neighbours`` (mi.UInt32, optional): per face, the face across each of its edges
  (``raymitsuba/geometry/topology.py``; 0xFFFFFFFF: none), where the positions alone do
  not tell (a tessellation's faces, grown apart); kept as ``self.neighbours`` (None:
  not given) for the integrator (``whitted/protocol.py``'s MeshTopology).
"""

import drjit as dr
import mitsuba as mi


class Triangles(mi.Mesh):
    def __init__(self, props):
        positions = props.get("positions")
        vertex_count = dr.width(positions) // 3
        faces = props.get("faces") if "faces" in props else dr.arange(mi.UInt32, vertex_count)
        smooth = "normals" in props
        self.neighbours = props.get("neighbours") if "neighbours" in props else None
        mi.Mesh.__init__(self, "triangles", vertex_count, dr.width(faces) // 3, props,
                         has_vertex_normals=smooth, has_vertex_texcoords=True)
        params = mi.traverse(self)
        params["vertex_positions"] = positions
        params["faces"] = faces
        if smooth:
            params["vertex_normals"] = props.get("normals")
        params["vertex_texcoords"] = props.get("texcoords")
        params.update()
