"""``raychecker``: the .RAY checkerboard as a Mitsuba texture.

Evaluates to 1 on the "even" squares and 0 on the "odd" ones, for a plane's
texture coordinates, which are its object-space (x, z) (see ``plane.py``)::

    checker(u, v) = 1  if floor(u / s) + floor(v / s) is even,  else 0

so that the material's base color C times it gives C and black squares, as the
format says. :func:`checker` is the one implementation of this formula: the
Whitted integrator calls it with each hit's square size gathered from its surface
table, and this texture's ``eval`` with its own. :func:`checker_filtered` is its average
over a sample's footprint, which anti-aliasing's camera rays use (``--aa``; a plain
render keeps the value at the point).

Parameters: ``size`` (float, > 0): the side s of a square, in the plane's object space.
"""

import drjit as dr
import mitsuba as mi


def checker(uv, size):
    """1 on the even squares of side ``size``, 0 on the odd ones (see the module docstring)."""
    cell = dr.floor(uv.x / size) + dr.floor(uv.y / size)
    return 1.0 - (cell - 2.0 * dr.floor(cell * 0.5))  # parity: exact on integers


def checker_filtered(uv, size, duv_dx, duv_dy):
    """The checkerboard averaged over a footprint: the pixel (or sub-pixel) of a sample,
    whose edges map to the texture-space vectors ``duv_dx`` and ``duv_dy`` at ``uv``.

    In square units x = u / s, y = v / s the board is (1 + q(x) q(y)) / 2 with q the square
    wave (+1 on even squares, -1 on odd ones). Averaged over an axis-aligned box of
    half-widths (wx, wy) that is exactly (1 + Q(x, wx) Q(y, wy)) / 2, Q the box average of
    q: the difference of its integral, the triangle wave, at the box's two ends over its
    width. The footprint is a parallelogram, long and slanted where a plane is seen at a
    grazing angle: it is cut along its longer edge into up to SPLIT pieces no longer than
    they are wide, and each piece is taken as the box of the same variance along each axis
    (half-width sqrt(a^2 + b^2) / 2 for edges a, b; exact for an axis-aligned rectangle).
    A footprint of width 0 gives :func:`checker`."""
    inv = 1.0 / size
    a, b = duv_dx * inv, duv_dy * inv
    swap = dr.squared_norm(b) > dr.squared_norm(a)  # a: the longer edge
    a, b = dr.select(swap, b, a), dr.select(swap, a, b)
    ratio = dr.sqrt(dr.squared_norm(a) / dr.maximum(dr.squared_norm(b), 1e-30))
    pieces = dr.clip(dr.ceil(ratio), 1.0, float(SPLIT))
    piece = a / pieces
    wx = 0.5 * dr.sqrt(dr.square(piece.x) + dr.square(b.x))
    wy = 0.5 * dr.sqrt(dr.square(piece.y) + dr.square(b.y))
    x0, y0 = uv.x * inv, uv.y * inv
    total = dr.zeros(type(x0), dr.width(x0))
    for k in range(SPLIT):
        inside = k < pieces
        shift = (k + 0.5) / pieces - 0.5
        x, y = dr.fma(a.x, shift, x0), dr.fma(a.y, shift, y0)
        total += dr.select(inside, box_average(x, wx) * box_average(y, wy), 0.0)
    return 0.5 * (1.0 + total / pieces)


SPLIT = 8  # the most pieces a footprint is cut into (checker_filtered)


def square_wave(x):
    """+1 where floor(x) is even, -1 where it is odd."""
    return 1.0 - 2.0 * (dr.floor(x) - 2.0 * dr.floor(x * 0.5))


def triangle_wave(x):
    """The integral of ``square_wave`` from 0: 0 at even integers, 1 at odd ones."""
    return 1.0 - dr.abs(x - 2.0 * dr.floor(x * 0.5) - 1.0)


def box_average(x, w):
    """The average of ``square_wave`` over [x - w, x + w] (the wave itself where w is too
    small for the difference to be exact in float32)."""
    wide = w > 1e-4
    w_safe = dr.select(wide, w, 1.0)
    average = (triangle_wave(x + w_safe) - triangle_wave(x - w_safe)) / (2.0 * w_safe)
    return dr.select(wide, average, square_wave(x))


class Checkerboard(mi.Texture):
    def __init__(self, props):
        super().__init__(props)
        self.size = props.get("size", 1.0)
        if not self.size > 0:
            raise ValueError("raychecker: size must be > 0")

    def eval_1(self, si, active=True):
        return checker(si.uv, self.size)

    def eval(self, si, active=True):
        return mi.Color3f(self.eval_1(si, active))

    def mean(self):
        return 0.5

    def traverse(self, callback):
        pass

    def to_string(self):
        return f"Checkerboard[size={self.size}]"
