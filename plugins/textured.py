"""``raytextured``: a ``rayphong`` material seen through per-object textures.

The format attaches textures and the checkerboard to *objects*, while a
material is shared by every object declared under it (and its parameters,
``mat{i}.*``, must stay one set). So an object that has a texture gets this
small BSDF, which holds a reference to the shared material and multiplies its
base color by the texels::

    C(si) = material.color * texture(si) * checker(si)

Everything else is the material's (see ``phong.py``). The Whitted integrator
reads ``material`` and ``textures`` directly.

Parameters:

* ``material`` (reference to a ``rayphong`` BSDF, required)
* ``texture`` (mi.Texture, optional): an image texture (Mitsuba's ``bitmap``)
* ``checker`` (mi.Texture, optional): a ``raychecker`` texture (1 or 0)
"""

import mitsuba as mi



class Textured(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        self.material = props.get("material")
        self.textures = tuple(props.get(name) for name in ("texture", "checker") if name in props)
        self.m_flags = self.material.m_flags
        self.m_components = [self.m_flags]

    def color(self, si, active=True):
        color = mi.Color3f(self.material.color)
        for texture in self.textures:
            color = color * texture.eval(si, active)
        return color

    def eval(self, ctx, si, wo, active=True):
        return self.material.eval_local(si, wo, self.color(si, active), active)

    def eval_attribute_3(self, name, si, active=True):
        if name == "ambient_reflectance":
            return self.material.ambient_mix * self.color(si, active)
        if name == "color":
            return self.color(si, active)
        return mi.Color3f(0.0)

    def eval_attribute_1(self, name, si, active=True):
        return self.material.eval_attribute_1(name, si, active)

    def has_attribute(self, name, active=True):
        return self.material.has_attribute(name, active)

    def sample(self, ctx, si, sample1, sample2, active=True):
        return mi.BSDFSample3f(), mi.Color3f(0.0)

    def pdf(self, ctx, si, wo, active=True):
        return mi.Float(0.0)

    def traverse(self, callback):
        pass  # the material's parameters are listed under its own id; textures are fixed

    def to_string(self):
        return f"Textured[material={self.material}]"
