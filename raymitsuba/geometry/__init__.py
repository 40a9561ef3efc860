"""The geometry conventions the translator and the plugins share, as numpy arrays.

* :mod:`~raymitsuba.geometry.tessellation`: the .RAY quadrics' object-space templates, placed
  in the world in bulk (the translator's meshes and the shape plugins' own);
* :mod:`~raymitsuba.geometry.sphere_set`: the sphere set's data layout (many analytic
  spheres and ellipsoids as one Mitsuba shape) and its material table's columns.

Both are in the ``shared`` room (``tests/test_layers.py``): they need numpy, nothing of ours.
"""
