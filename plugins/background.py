"""``raybackground``: the color of every ray, primary or secondary, that hits nothing.

Parameters: ``color`` (Color3f, default black; differentiable). Read by the
Whitted integrator as ``background_color`` (the background interface, see
``whitted/protocol.py``); not a radiometric emitter.
"""

import drjit as dr
import mitsuba as mi


class Background(mi.Emitter):
    def __init__(self, props):
        super().__init__(props)
        self.color = mi.Color3f(props.get("color", mi.ScalarColor3f(0.0)))
        self.parameters_changed([])
        self.m_flags = mi.EmitterFlags.Empty

    @property
    def background_color(self):
        return self.color

    def traverse(self, callback):
        callback.put("color", self.color, mi.ParamFlags.Differentiable)

    def parameters_changed(self, keys):
        dr.make_opaque(self.color)  # a new value is not a new kernel (see phong.py)

    def to_string(self):
        return f"Background[color={self.color}]"
