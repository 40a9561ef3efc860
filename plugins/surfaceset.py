"""``raysurfaceset``: the surfaces of a shape whose primitives have surfaces of their own.

The sphere set (:mod:`raymitsuba.sphere_set`) is one Mitsuba shape holding many spheres,
each drawn with the surface of its object; Mitsuba gives a shape one BSDF. This BSDF is
that one: it names, for each primitive in order, its surface (a ``rayphong`` or
``raytextured`` BSDF of the scene, by reference: materials stay shared and keep their
keys ``mat{i}.*``). The Whitted integrator reads it through the surface-set interface
(``whitted/protocol.py``) and gives each primitive the slot of its surface
(``whitted/surfaces.py``). It has no ``eval``, like the surfaces it names.

Parameters:

* ``surface_{k}`` (reference to a surface BSDF), for k = 0 .. n - 1: primitive k's surface.
"""

import mitsuba as mi

PREFIX = "surface_"


class SurfaceSet(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        count = sum(1 for name in props.keys() if name.startswith(PREFIX))
        # (primitive k's surface; by name, so the order of the properties does not matter)
        self.surfaces = tuple(props.get(f"{PREFIX}{k}") for k in range(count))
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection \
            | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.m_components = [self.m_flags]

    def traverse(self, callback):
        pass  # the surfaces' parameters are listed under their own ids

    def to_string(self):
        return f"SurfaceSet[{len(self.surfaces)} surfaces]"
