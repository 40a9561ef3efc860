"""``raychecker``: the .RAY checkerboard as a Mitsuba texture.

Evaluates to 1 on the "even" squares and 0 on the "odd" ones, for a plane's
texture coordinates, which are its object-space (x, z) (see ``plane.py``)::

    checker(u, v) = 1  if floor(u / s) + floor(v / s) is even,  else 0

so that the material's base color C times it gives C and black squares, as the
format says. :func:`checker` is the one implementation of this formula: the
Whitted integrator calls it with each hit's square size gathered from its surface
table, and this texture's ``eval`` with its own. :func:`checker_filtered` is its average
over a sample's footprint as perspective maps it (:func:`filtered_board`: that average with
what anti-aliasing asks of it, a :class:`BoardAverage`), which anti-aliasing's rays use,
from the camera and through mirrors and glass (``--aa``; a plain render keeps the value at
the point).

Parameters: ``size`` (float, > 0): the side s of a square, in the plane's object space.
"""

from typing import NamedTuple

import drjit as dr
import mitsuba as mi


def checker(uv, size):
    """1 on the even squares of side ``size``, 0 on the odd ones (see the module docstring)."""
    cell = dr.floor(uv.x / size) + dr.floor(uv.y / size)
    return 1.0 - (cell - 2.0 * dr.floor(cell * 0.5))  # parity: exact on integers


def checker_filtered(uv, size, duv_dx, duv_dy, distortion=None):
    """The checkerboard averaged over a footprint: the pixel (or sub-pixel) of a sample,
    the square (s, t) in [-1/2, 1/2]^2 of its share of the pixel, which maps to

        uv(s, t) = uv + (s duv_dx + t duv_dy) / (1 + s kx + t ky)

    in texture space: the image of a square of the screen on a plane seen in perspective
    (``duv_dx``, ``duv_dy``: the derivatives at the sample; ``distortion``: (kx, ky), the
    relative rates at which the distance to the plane falls across the footprint, or
    None: 0, a parallelogram).

    In square units x = u / s, y = v / s the board is (1 + q(x) q(y)) / 2 with q the square
    wave (+1 on even squares, -1 on odd ones). The footprint is cut along its longer edge
    into :func:`pieces` of equal share of the screen, each no longer than it is wide
    and no more distorted along that edge than FIRST_ORDER (as far as SPLIT pieces go):
    each piece is the parallelogram of its chord along that edge, between the images of
    its two ends, and of the derivative along the other edge, about the image of its
    middle; its average is the product of its averages along each axis. Along an axis a
    piece of edges a, b spreads as the sum of two uniform offsets, of widths |a_x| and
    |b_x|: a trapezoid, over which :func:`trapezoid_average` averages q exactly. The
    product is exact for an axis-aligned rectangle and, for any piece, wherever one axis's
    q is constant over it (along a single edge of the board). A footprint of width 0 gives
    :func:`checker`; one that reaches past the horizon (not finite) 1/2, the board's mean;
    one more distorted than MAX_DISTORTION is taken as if it were that distorted (an
    average of many squares all the same; ``footprint_resolved`` tells them apart)."""
    return filtered_board(uv, size, duv_dx, duv_dy, distortion).value


class BoardAverage(NamedTuple):
    """The checkerboard over a sample's footprint (:func:`filtered_board`), and what
    anti-aliasing needs to know of that average (``signature.py``)."""

    value: object  # Float: the average, :func:`checker_filtered`'s value
    corner: object  # Bool: a piece of the footprint holds a corner of the board (a square's
    # edges in both axes cross it: neither axis's average is +-1), where the product of its
    # two averages is not the exact average of a slanted piece
    resolved: object  # Bool: the footprint was averaged (:func:`footprint_resolved`)
    residual: object  # Float: how distorted its pieces still are (:func:`residual_distortion`)


def filtered_board(uv, size, duv_dx, duv_dy, distortion=None):
    """:func:`checker_filtered`'s value with what anti-aliasing asks of it: a
    :class:`BoardAverage`. The pieces are a loop, each lane running its own count (most
    footprints are one or two pieces); detached: the footprint is a filter's, its
    derivative is not computed (anti-aliasing, whose rays carry footprints, refuses the
    keys that move the geometry)."""
    with dr.suspend_grad():
        footprint = (dr.detach(duv_dx), dr.detach(duv_dy),
                     None if distortion is None else dr.detach(distortion))
        uv, size = dr.detach(uv), dr.detach(size)
        inv = 1.0 / size
        a, b, ka, kb = _longer_first(dr.detach(duv_dx) * inv, dr.detach(duv_dy) * inv,
                                     None if distortion is None else dr.detach(distortion))
        finite = dr.isfinite(dr.squared_norm(a) + dr.squared_norm(b) + ka + kb)
        a, b = dr.select(finite, a, 0.0), dr.select(finite, b, 0.0)
        excess = dr.maximum(0.5 * (dr.abs(ka) + dr.abs(kb)) / MAX_DISTORTION, 1.0)
        ka, kb = dr.select(finite, ka / excess, 0.0), dr.select(finite, kb / excess, 0.0)
        count = pieces(a, b, ka)
        x0, y0 = uv.x * inv, uv.y * inv
        one = 1.0 - CORNER_SHARE

        def body(k, total, corner):
            s0, s1 = k / count - 0.5, (k + 1.0) / count - 0.5
            middle = 0.5 * (s0 + s1)
            scale = dr.rcp(1.0 + ka * middle)
            centre = a * (middle * scale)  # the image of (middle, 0)
            chord = a * (s1 / (1.0 + ka * s1) - s0 / (1.0 + ka * s0))
            across = (b - a * (middle * kb * scale)) * scale  # d uv / dt at (middle, 0)
            # the piece's averages along each axis: two spreads each, of these half-widths
            qx = trapezoid_average(x0 + centre.x, 0.5 * dr.abs(chord.x), 0.5 * dr.abs(across.x))
            qy = trapezoid_average(y0 + centre.y, 0.5 * dr.abs(chord.y), 0.5 * dr.abs(across.y))
            return k + 1.0, total + qx * qy, corner | ((dr.abs(qx) < one) & (dr.abs(qy) < one))

        zero = dr.zeros(type(x0), dr.width(x0))
        _, total, corner = dr.while_loop((zero, zero, dr.zeros(dr.mask_t(x0), dr.width(x0))),
                                         lambda k, total, corner: k < count, body,
                                         label="checker pieces")
        return BoardAverage(dr.select(finite, 0.5 * (1.0 + total / count), 0.5),
                            finite & corner, footprint_resolved(*footprint),
                            residual_distortion(*footprint))


SPLIT = 8  # the most pieces a footprint is cut into (checker_filtered)
# A piece holds a corner of the board where both its averages are within this of +-1 off it
CORNER_SHARE = 1e-3
# A piece of a footprint distorted by at most this much along its length is averaged as a
# parallelogram (a taper of 2 %: its average off by a small share of an 8-bit step at a
# checker edge; tests/plugins/test_checkerboard.py measures it)
FIRST_ORDER = 0.02
# The most distortion (|kx| + |ky|) / 2 a footprint may have: its far corner then at most
# 2.5 times its centre's distance (a footprint that reaches the horizon is no footprint)
MAX_DISTORTION = 0.6


def _longer_first(a, b, distortion):
    """(a, b, ka, kb): the footprint's edges, the longer first, with their distortions."""
    ka, kb = (0.0, 0.0) if distortion is None else distortion
    swap = dr.squared_norm(b) > dr.squared_norm(a)
    return (dr.select(swap, b, a), dr.select(swap, a, b), dr.select(swap, kb, ka),
            dr.select(swap, ka, kb))


def pieces(a, b, ka):
    """How many pieces a footprint of edges ``a`` (the longer) and ``b`` is cut into along
    ``a``, whose distortion is ``ka``: enough for each to be no longer than it is wide and
    distorted by at most FIRST_ORDER along it, at most SPLIT (Float, >= 1)."""
    ratio = dr.sqrt(dr.squared_norm(a) / dr.maximum(dr.squared_norm(b), 1e-30))
    return dr.clip(dr.ceil(dr.maximum(ratio, dr.abs(ka) * (1.0 / FIRST_ORDER))), 1.0,
                   float(SPLIT))


def footprint_resolved(duv_dx, duv_dy, distortion=None):
    """Bool: where :func:`checker_filtered` averages the footprint: not a point (width 0),
    finite, and short of the horizon (distortion at most MAX_DISTORTION)."""
    long = dr.maximum(dr.squared_norm(duv_dx), dr.squared_norm(duv_dy))
    resolved = (long > 0) & dr.isfinite(long)
    if distortion is not None:
        kx, ky = distortion
        resolved &= 0.5 * (dr.abs(kx) + dr.abs(ky)) <= MAX_DISTORTION
    return resolved


def residual_distortion(duv_dx, duv_dy, distortion):
    """How distorted the pieces of :func:`checker_filtered` still are, the most along
    either edge (Float): where it exceeds FIRST_ORDER a grid of samples, each with its
    share of it, averages the footprint instead (anti-aliasing, ``signature.grid_code``)."""
    a, b, ka, kb = _longer_first(duv_dx, duv_dy, distortion)
    return dr.maximum(dr.abs(ka) / pieces(a, b, ka), dr.abs(kb))


def square_wave(x):
    """+1 where floor(x) is even, -1 where it is odd."""
    return 1.0 - 2.0 * (dr.floor(x) - 2.0 * dr.floor(x * 0.5))


def triangle_wave(x):
    """The integral of ``square_wave`` from 0: 0 at even integers, 1 at odd ones."""
    return 1.0 - dr.abs(x - 2.0 * dr.floor(x * 0.5) - 1.0)


def wave_second_integral(x):
    """An integral of ``triangle_wave`` less its mean 1/2 (so periodic, of period 2):
    z (1 - |z|) / 2 with z = (x mod 2) - 1."""
    z = x - 2.0 * dr.floor(x * 0.5) - 1.0
    return 0.5 * z * (1.0 - dr.abs(z))


def trapezoid_average(x, w1, w2):
    """The average of ``square_wave`` about ``x`` over the sum of two uniform offsets of
    half-widths ``w1`` and ``w2`` (a trapezoid): the second difference of its second
    integral, (S(x + w1 + w2) - S(x + w1 - w2) - S(x - w1 + w2) + S(x - w1 - w2)) / (4 w1
    w2), S = :func:`wave_second_integral` (its linear part cancels). Where the narrower
    spread is below TRAPEZOID_MIN (the second difference would lose to float32 round-off)
    it is the box of the same variance, half-width sqrt(w1^2 + w2^2) (:func:`box_average`:
    off near an edge by a share of the contrast that falls as the narrower spread does
    against the wider)."""
    wide, narrow = dr.maximum(w1, w2), dr.minimum(w1, w2)
    exact = narrow > TRAPEZOID_MIN
    n = dr.select(exact, narrow, 1.0)
    x = x - 2.0 * dr.floor(x * 0.5)  # (the wave's period: small arguments, fewer bits lost)
    second = (wave_second_integral(x + wide + n) - wave_second_integral(x + wide - n)
              - wave_second_integral(x - wide + n) + wave_second_integral(x - wide - n))
    return dr.select(exact, second / (4.0 * wide * n),
                     box_average(x, dr.sqrt(dr.square(wide) + dr.square(narrow))))


TRAPEZOID_MIN = 1e-2  # squares: the narrowest spread trapezoid_average takes exactly


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
