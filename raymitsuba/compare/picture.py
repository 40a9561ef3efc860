"""The pictures of a comparison: 8-bit views of the images and the heat map of their
difference, side by side (``--diff``) or one by one (the HTML report).

The heat map is matplotlib's ``inferno`` colormap of each pixel's largest channel
difference over [0, ``HEAT_RANGE``] (black: equal; yellow: ``HEAT_RANGE`` or more), pixels
left out of the score (reference not stable) in ``LEFT_OUT`` gray-blue.
"""

from __future__ import annotations

import numpy as np

HEAT_RANGE = 32 / 255
LEFT_OUT = (70, 90, 130)
GAP = 4  # pixels between the side-by-side panels (white)


def view(image, srgb: bool = False) -> np.ndarray:
    """A linear image as the uint8 (H, W, 3) values an 8-bit file of it holds."""
    from raymitsuba.images import encode_8bit

    return encode_8bit(np.asarray(image, np.float32), srgb)


def heat_map(diff, unstable=None) -> np.ndarray:
    """uint8 (H, W, 3) heat map of the (H, W) differences (see the module docstring)."""
    from matplotlib import colormaps

    rgba = colormaps["inferno"](np.clip(np.asarray(diff) / HEAT_RANGE, 0.0, 1.0), bytes=True)
    heat = np.ascontiguousarray(rgba[..., :3])
    if unstable is not None:
        heat[np.asarray(unstable, bool)] = LEFT_OUT
    return heat


def side_by_side(image, reference, diff, unstable=None, srgb: bool = False) -> np.ndarray:
    """uint8 picture: the image | the reference | the heat map."""
    panels = [view(image, srgb), view(reference, srgb), heat_map(diff, unstable)]
    height = panels[0].shape[0]
    gap = np.full((height, GAP, 3), 255, np.uint8)
    return np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)


def png_bytes(pixels) -> bytes:
    """uint8 (H, W, 3) pixels as PNG file contents."""
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(pixels), "RGB").save(buffer, format="PNG")
    return buffer.getvalue()
