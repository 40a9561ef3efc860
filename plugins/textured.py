"""``raytextured``: a ``rayphong`` material seen through per-object textures.

The format attaches textures and the checkerboard to *objects*, while a
material is shared by every object declared under it (and its parameters,
``mat{i}.*``, must stay one set). So an object that has a texture gets this
small BSDF, which holds a reference to the shared material; the Whitted
integrator multiplies the material's base color by the texels::

    C(si) = material.color * texture(si) * checker(si)

Everything else is the material's (see ``phong.py``). Like the material, this
plugin only provides the surface interface (``whitted/protocol.py``): ``material``,
``image_textures`` (the ``texture``, if any) and ``checker_size`` (the
``checker``'s square size, 0 without one); it has no ``eval``.

Parameters:

* ``material`` (reference to a ``rayphong`` BSDF, required)
* ``texture`` (mi.Texture, optional): an image texture (Mitsuba's ``bitmap``)
* ``checker`` (a ``raychecker`` texture, optional): the checkerboard (1 or 0)
"""

import mitsuba as mi


class Textured(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        self.material = props.get("material")
        self.image_textures = (props.get("texture"),) if "texture" in props else ()
        self.checker_size = 0.0
        if "checker" in props:
            checker = props.get("checker")
            if not hasattr(checker, "size"):
                raise ValueError("raytextured: the checker must be a raychecker texture")
            self.checker_size = float(checker.size)
        self.m_flags = self.material.m_flags
        self.m_components = [self.m_flags]

    def traverse(self, callback):
        pass  # the material's parameters are listed under its own id; textures are fixed

    def to_string(self):
        return f"Textured[material={self.material}]"
