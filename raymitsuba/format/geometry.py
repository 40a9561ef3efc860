"""Small vector and matrix helpers of the parser, on plain tuples.

A matrix is a 4x4 row-major affine matrix of tuples (see :mod:`raymitsuba.model`).
Each push of a transform multiplies it onto the *left* of the current composite M
(T is applied last). The products are written out per kind of T: cheaper than a
general 4x4 product, and exact where T is (a translation adds, a scale multiplies).
"""

from __future__ import annotations

import functools
import math
from typing import Optional, Tuple

from raymitsuba.model import Matrix4, Vec3


def translated(m: Matrix4, x: float, y: float, z: float) -> Matrix4:
    """``translation(x, y, z) @ m``."""
    r0, r1, r2, last = m
    return ((r0[0], r0[1], r0[2], r0[3] + x), (r1[0], r1[1], r1[2], r1[3] + y),
            (r2[0], r2[1], r2[2], r2[3] + z), last)


def scaled(m: Matrix4, x: float, y: float, z: float) -> Matrix4:
    """``scaling(x, y, z) @ m``."""
    r0, r1, r2, last = m
    return ((r0[0] * x, r0[1] * x, r0[2] * x, r0[3] * x),
            (r1[0] * y, r1[1] * y, r1[2] * y, r1[3] * y),
            (r2[0] * z, r2[1] * z, r2[2] * z, r2[3] * z), last)


_QUARTER_TURNS = ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))  # (cos, sin) of k * 90


@functools.lru_cache(maxsize=256)  # scenes repeat their angles
def cos_sin_degrees(theta: float) -> Tuple[float, float]:
    """cos and sin of ``theta`` degrees; exact for whole multiples of 90 degrees."""
    theta = math.fmod(theta, 360.0)
    if theta % 90.0 == 0.0:
        return _QUARTER_TURNS[int(theta // 90.0) % 4]
    rad = math.radians(theta)
    return math.cos(rad), math.sin(rad)


def rotated(m: Matrix4, axis: str, theta: float) -> Matrix4:
    """``rotation(axis, theta) @ m``: right-handed, ``theta`` in degrees, ``axis`` x, y or z.

    The rotation matrices are Rx = [[1,0,0],[0,c,-s],[0,s,c]],
    Ry = [[c,0,s],[0,1,0],[-s,0,c]] and Rz = [[c,-s,0],[s,c,0],[0,0,1]].
    """
    c, s = cos_sin_degrees(theta)
    r0, r1, r2, last = m
    if axis == "x":
        return (r0, _mix(c, r1, -s, r2), _mix(s, r1, c, r2), last)
    if axis == "y":
        return (_mix(c, r0, s, r2), r1, _mix(-s, r0, c, r2), last)
    return (_mix(c, r0, -s, r1), _mix(s, r0, c, r1), r2, last)


def _mix(a: float, u: Tuple[float, ...], b: float, v: Tuple[float, ...]) -> Tuple[float, ...]:
    """The row ``a * u + b * v``."""
    return (a * u[0] + b * v[0], a * u[1] + b * v[1], a * u[2] + b * v[2], a * u[3] + b * v[3])


def magnitude_if_usable(m: Matrix4) -> Optional[float]:
    """The largest |entry| of ``m`` if it is usable, else None.

    Usable: finite entries and an invertible (finite, non-zero determinant) linear part.
    """
    entries = m[0] + m[1] + m[2]
    total = sum(entries)
    if total - total != 0.0 and not all(map(math.isfinite, entries)):
        return None  # (a finite sum proves all entries finite; an infinite one may lie)
    (a, b, c, _), (d, e, f, _), (g, h, i, _) = m[0], m[1], m[2]
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    if det == 0.0 or not math.isfinite(det):
        return None
    return max(map(abs, entries))


def apply(m: Matrix4, p: Vec3) -> Vec3:
    x, y, z = p
    return tuple(r[0] * x + r[1] * y + r[2] * z + r[3] for r in m[:3])  # type: ignore[return-value]


def unit(v: Vec3) -> Vec3:
    """``v`` normalised without overflow or underflow; ``v`` must be finite and non-zero."""
    big = max(abs(c) for c in v)
    x, y, z = (c / big for c in v)
    n = math.sqrt(x * x + y * y + z * z)
    return (x / n, y / n, z / n)


def cross(a: Vec3, b: Vec3) -> Vec3:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def similarity(center: Vec3, radius: float) -> Matrix4:
    """The matrix of ``translate(center) @ scale(radius)``: a unit sphere to the sphere of
    that centre and radius (exactly what COMP 575's ``scale r r r`` then
    ``translate cx cy cz`` give)."""
    cx, cy, cz = center
    r = radius
    return ((r, 0.0, 0.0, cx), (0.0, r, 0.0, cy), (0.0, 0.0, r, cz), (0.0, 0.0, 0.0, 1.0))
