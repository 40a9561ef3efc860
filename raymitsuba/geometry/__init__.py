"""The geometry conventions the translator and the plugins share, as numpy arrays.

* :mod:`~raymitsuba.geometry.tessellation`: the .RAY quadrics' object-space templates, placed
  in the world in bulk (the translator's meshes and the shape plugins' own);
* :mod:`~raymitsuba.geometry.sphere_set`: the sphere set's data layout (many analytic
  spheres and ellipsoids as one Mitsuba shape) and its material table's columns;
* :mod:`~raymitsuba.geometry.topology`: which faces of a triangle mesh meet along an edge
  (the tessellations declare theirs; the boundary terms follow a mesh's outline by them).

All three are in the ``shared`` room (``tests/test_layers.py``): they need numpy, nothing of ours.
"""
