"""``raychecker``: the .RAY checkerboard as a Mitsuba texture.

Evaluates to 1 on the "even" squares and 0 on the "odd" ones, for a plane's
texture coordinates, which are its object-space (x, z) (see ``plane.py``)::

    checker(u, v) = 1  if floor(u / s) + floor(v / s) is even,  else 0

so that the material's base color C times it gives C and black squares, as the
format says. :func:`checker` is the one implementation of this formula: the
Whitted integrator calls it with each hit's square size gathered from its surface
table, and this texture's ``eval`` with its own.

Parameters: ``size`` (float, > 0): the side s of a square, in the plane's object space.
"""

import drjit as dr
import mitsuba as mi


def checker(uv, size):
    """1 on the even squares of side ``size``, 0 on the odd ones (see the module docstring)."""
    cell = dr.floor(uv.x / size) + dr.floor(uv.y / size)
    return 1.0 - (cell - 2.0 * dr.floor(cell * 0.5))  # parity: exact on integers


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
