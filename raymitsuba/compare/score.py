"""The figures of one image against its reference: what ``raymitsuba compare`` prints.

Both images are linear (H, W, 3) arrays, clamped to [0, 1] before anything is compared
(an 8-bit file cannot hold more). A pixel's difference is its *largest channel
difference*; a pixel *matches* when that is at most the tolerance (``TOLERANCE``, 2/255:
the rounding of an 8-bit file and a float32 tracer's noise both stay well inside it).

Pixels outside the ``scored`` mask (those whose reference value is not stable, see
``stable.py``) are counted apart and enter no figure:

* ``match``: percent of the scored pixels within the tolerance (the score ``--min-match``
  tests), ``within_2`` and ``within_8``: percent within 2/255 and 8/255;
* ``mean_abs``: mean absolute difference over the scored pixels' channels;
* ``psnr``: 10 log10(1 / mean squared difference) in dB (inf for identical images);
* ``worst``: the tile (``TILES`` x ``TILES`` grid of the image) holding the most pixels
  beyond the tolerance, as (x0, y0, x1, y1) pixel bounds, x1 and y1 excluded.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Optional, Tuple

import numpy as np

TOLERANCE = 2 / 255
#: Differences are compared with this slack: an 8-bit value decoded and re-encoded is off
#: by ~1e-7 from k/255, and k/255 exactly must count as within k/255.
SLACK = 1e-6
TILES = 8


class CompareError(ValueError):
    """Inputs that cannot be compared (sizes differ, not an RGB image)."""


@dataclass(frozen=True)
class Score:
    """See the module docstring; counts are pixels."""

    width: int
    height: int
    tolerance: float
    scored: int  # pixels scored
    left_out: int  # pixels left out (reference not stable)
    failed: int  # scored pixels beyond the tolerance
    match: float  # percent of the scored pixels within the tolerance
    within_2: float  # percent within 2/255
    within_8: float  # percent within 8/255
    mean_abs: float
    psnr: float
    worst: Optional[Tuple[int, int, int, int]]  # None: no pixel beyond the tolerance
    worst_count: int  # pixels beyond the tolerance in the worst tile

    def passed(self, min_match: float) -> bool:
        return self.match >= min_match

    def record(self) -> dict:
        """The figures as JSON-ready values (inf PSNR as None)."""
        out = asdict(self)
        out["psnr"] = None if math.isinf(self.psnr) else self.psnr
        out["worst"] = None if self.worst is None else list(self.worst)
        return out

    def lines(self) -> list:
        """The figures as lines of text, for people."""
        tol = f"{self.tolerance * 255:g}/255"
        psnr = "inf (identical)" if math.isinf(self.psnr) else f"{self.psnr:.2f} dB"
        lines = [f"match: {self.match:.3f} % of {self.scored} pixels within {tol} "
                 f"({self.failed} beyond)",
                 f"within 2/255: {self.within_2:.3f} %   within 8/255: {self.within_8:.3f} %",
                 f"mean abs difference: {self.mean_abs:.6f}   PSNR: {psnr}",
                 f"left out (reference not stable): {self.left_out} pixels"]
        if self.worst is not None:
            x0, y0, x1, y1 = self.worst
            lines.append(f"worst region: x {x0}..{x1 - 1}, y {y0}..{y1 - 1} "
                         f"({self.worst_count} pixels beyond {tol})")
        return lines


def as_rgb(image, name="image") -> np.ndarray:
    """``image`` as a float32 (H, W, 3) array clamped to [0, 1]."""
    array = np.asarray(image, dtype=np.float32)
    if array.ndim != 3 or array.shape[2] != 3:
        raise CompareError(f"{name}: expected an RGB image (H, W, 3), got shape {array.shape}")
    return np.clip(np.nan_to_num(array, nan=0.0), 0.0, 1.0)


def difference(image, reference) -> np.ndarray:
    """Each pixel's largest channel difference (H, W), both clamped to [0, 1]."""
    a, b = as_rgb(image), as_rgb(reference, "reference")
    if a.shape != b.shape:
        raise CompareError(f"sizes differ: image {a.shape[1]}x{a.shape[0]}, "
                           f"reference {b.shape[1]}x{b.shape[0]}")
    return np.abs(a - b).max(axis=-1)


def score(image, reference, tolerance: float = TOLERANCE, scored=None) -> Score:
    """The :class:`Score` of ``image`` against ``reference`` over the ``scored`` mask
    ((H, W) bool; None: every pixel)."""
    a, b = as_rgb(image), as_rgb(reference, "reference")
    diff = difference(a, b)
    height, width = diff.shape
    mask = np.ones(diff.shape, bool) if scored is None else np.asarray(scored, bool)
    count = int(mask.sum())
    d = diff[mask]
    channels = np.abs(a - b)[mask]
    beyond = (diff > tolerance + SLACK) & mask

    def share(limit):
        return 100.0 * float((d <= limit + SLACK).sum()) / count if count else 100.0

    mse = float(np.mean(np.square(channels, dtype=np.float64))) if count else 0.0
    worst, worst_count = worst_tile(beyond)
    return Score(width, height, float(tolerance), count, int(diff.size - count),
                 int(beyond.sum()), share(tolerance), share(2 / 255), share(8 / 255),
                 float(channels.mean(dtype=np.float64)) if count else 0.0,
                 math.inf if mse == 0 else 10.0 * math.log10(1.0 / mse), worst, worst_count)


def worst_tile(beyond):
    """((x0, y0, x1, y1), count) of the TILES x TILES tile with most True pixels (None, 0
    when there is none)."""
    if not beyond.any():
        return None, 0
    height, width = beyond.shape
    ys = np.linspace(0, height, min(TILES, height) + 1).astype(int)
    xs = np.linspace(0, width, min(TILES, width) + 1).astype(int)
    best, where = -1, None
    for y0, y1 in zip(ys[:-1], ys[1:]):
        for x0, x1 in zip(xs[:-1], xs[1:]):
            n = int(beyond[y0:y1, x0:x1].sum())
            if n > best:
                best, where = n, (int(x0), int(y0), int(x1), int(y1))
    return where, best
