"""``raywhitted``, the .RAY format's recursive (Whitted) ray tracer, and its parts.

=================  ===================================================================
module             what it owns
=================  ===================================================================
``integrator``     the ``mi.Integrator``: a render's steps, its gradients
``protocol``       what the integrator reads from surfaces, lights, background
``camera``         which rays leave the camera for each pixel; the box filter
``surfaces``       the surface table: every surface's parameters by slot
``hits``           surface interactions by lookup in one geometry table
``lift``           where shadow rays leave smooth meshes near the terminator
``tree``           the ray tree, traced generation by generation
``differentials``  a sample's footprint carried through mirror and glass bounces
``signature``      a hash of what a sample's ray tree saw: one path or several
``replay``         a primal render's first-generation ray queries, replayed by its adjoint
``bailout``        which rays of the tree are not traced; the bound that makes it safe
``chunks``         which camera rays are traced together, within a budget; the probe
``guards``         what a ray costs; the requests refused before tracing (BudgetError)
``antialias``      which pixels adaptive anti-aliasing refines, and how; its plan
``geometry_ad``    the geometry and camera keys' derivatives, attached to hits and rays
``boundary``       the boundary terms of moving edges on the k x k lattice (a package:
                   a module per kind of edge, its docstring maps them)
``support``        which pixels of an adjoint pass can have an interior derivative
``arrays``         host arrays handed to Dr.Jit: private, aligned copies (one kernel each)
=================  ===================================================================
"""

from raymitsuba.plugins.whitted.integrator import Whitted

__all__ = ["Whitted"]
