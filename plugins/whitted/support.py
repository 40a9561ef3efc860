"""Which pixels of an adjoint pass can have an interior derivative.

The interior derivative of a sample (what automatic differentiation of its ray tree gives,
edges apart: ``geometry_ad.py``) is that of its color with respect to the keys whose
gradients are enabled. Where only shapes move -- no key of the camera, of a light, of a
material, texture or background has its gradient enabled -- and no surface has kr or kt > 0
(the tree is one generation: the camera ray's hit and its shadow rays), a sample's color
reads a moving key only through its own hit: one on a shape that stays keeps its point,
normal and shading, and a shadow ray's answer is a visibility, which has no derivative (its
edges are the boundary terms'). The derivative of every other sample is exactly zero, so
the adjoint pass traces only the pixels with a sample on a moving shape, as the primal
render before it saw them (its recorded first hits, ``replay.py``): a fit of an object's
pose, the camera still, traces that object's pixels, not the image (at 256 x 192, k = 4,
the ball of benchmarks/edges_bench.py's scene: a sixth of the pixels).

That pass then records none of the boundary terms' keys: the primal render recorded them
(``Whitted._keys``), which is what lets it skip samples. Elsewhere the adjoint pass records
them, in its kernel, as before: recorded by the primal render they would cost it as much
as they save the adjoint pass.
"""

import drjit as dr
import numpy as np

from .hits import traversed_values
from .surfaces import attached_values


def only_shapes_move(tracer, scene, surfaces):
    """Whether the keys whose gradients are enabled move shapes only, none of them the
    camera's, a light's, a material's, a texture's or the background's, and no surface of
    the table ``surfaces`` (its values read on the host) has kr or kt > 0: then a sample's
    interior derivative is zero unless its first hit is on a moving shape."""
    ad = tracer.geometry_ad
    if ad is None or ad.camera_moves() or not ad.attached() or surfaces.any_specular:
        return False
    return not attached_values(surfaces.layout.materials) and not any(
        dr.grad_enabled(value) for plugin in (*scene.emitters(), *surfaces.layout.textures)
        for value in traversed_values(plugin))


def interior_pixels(recording, edges, spp):
    """The pixels (numpy uint32, increasing) with a sample whose first hit, as
    ``recording`` (replay.Recording) holds it, is on a shape that the boundary terms
    ``edges`` (boundary.Boundary) see moving."""
    shape = recording.answers()[0][3].numpy()  # (each sample's first hit; NO_SHAPE: none)
    return np.flatnonzero(edges.moves(shape).reshape(-1, spp).any(axis=1)).astype(np.uint32)
