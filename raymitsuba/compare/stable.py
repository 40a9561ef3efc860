"""The reference image of a scene and the pixels where it is stable: where any correct
tracer must agree with it.

A pixel whose centre ray (or a secondary or shadow ray of its tree) passes within a hair of
a discontinuity -- a silhouette, a checker edge, a shadow edge -- is decided by float
rounding: a correct float32 or float64 tracer may land on either side. Such a pixel is
found by perturbing the render and seeing it change by more than the tolerance:

* the camera moved: eye and lookat each shifted by ``CAMERA_SHIFT`` of the scene's scale
  (the larger of its bounding box's diagonal and the eye's distance to lookat),
  perpendicular to the view, in two opposite ways (two renders);
* the secondary and shadow rays' offset off the surface grown ``OFFSET_FACTOR``-fold (the
  render option ``ray_offset_scale``: one render).

So a reference costs ``RENDERS`` = 4 renders of the scene, and the *unstable* pixels are
those where any of the three perturbed renders differs from the reference by more than
the tolerance (largest channel difference, values clamped to [0, 1]).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

CAMERA_SHIFT = 3e-5
OFFSET_FACTOR = 100.0
RENDERS = 4


@dataclass
class Reference:
    """A scene's reference image ((H, W, 3) float32, linear) and its unstable pixels
    ((H, W) bool; None when not computed); ``renders``: how many renders it took."""

    image: np.ndarray
    unstable: Optional[np.ndarray]
    renders: int


def scene_scale(model) -> float:
    """The scene's size: its bounding box's diagonal or the eye's distance to lookat,
    whichever is larger (planes have no box)."""
    from raymitsuba.format.summary import scene_bounds

    eye, lookat = np.asarray(model.camera.eye, float), np.asarray(model.camera.lookat, float)
    scale = float(np.linalg.norm(eye - lookat))
    box = scene_bounds(model)
    if box is not None:
        low, high = (np.asarray(corner, float) for corner in box)
        scale = max(scale, float(np.linalg.norm(high - low)))
    return scale if math.isfinite(scale) and scale > 0 else 1.0


def moved_cameras(model):
    """The two scenes of ``model`` with the camera moved (see the module docstring)."""
    camera = model.camera
    eye, lookat = np.asarray(camera.eye, float), np.asarray(camera.lookat, float)
    forward = (lookat - eye) / np.linalg.norm(lookat - eye)
    right = np.cross(forward, np.asarray(camera.up, float))
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    shift = CAMERA_SHIFT * scene_scale(model)
    scenes = []
    for sign in (1.0, -1.0):
        moved = dataclasses.replace(
            camera,
            eye=tuple(eye + sign * shift * (right + up) / math.sqrt(2)),
            lookat=tuple(lookat + sign * shift * (up - right) / math.sqrt(2)))
        scenes.append(dataclasses.replace(model, camera=moved))
    return scenes


def render(model, width: int, height: int, **options) -> np.ndarray:
    """One render of ``model`` at width x height as a float32 (H, W, 3) array."""
    from raymitsuba import api, backend

    backend.mitsuba(mitsuba_integrators=False)
    loaded = api.load(model, width=width, height=height, **options)
    return loaded.integrator.render_array(loaded.scene)


def reference(model, width: int, height: int, tolerance: float, stable: bool = True,
              **options) -> Reference:
    """The :class:`Reference` of ``model`` (a parsed Scene) at width x height with the
    render ``options`` (``stable=False``: the image only, one render)."""
    from raymitsuba.compare.score import difference

    image = render(model, width, height, **options)
    if not stable:
        return Reference(image, None, 1)
    renders = [render(moved, width, height, **options) for moved in moved_cameras(model)]
    renders.append(render(model, width, height, ray_offset_scale=OFFSET_FACTOR, **options))
    unstable = np.zeros(image.shape[:2], bool)
    for other in renders:
        unstable |= difference(other, image) > tolerance
    return Reference(image, unstable, 1 + len(renders))
