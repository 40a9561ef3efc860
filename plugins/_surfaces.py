"""The surface table of the Whitted integrator: every surface's parameters as arrays
indexed by a *slot*, and the scene's lights and background as shading needs them.

A surface is one BSDF of the scene (a ``rayphong`` material or a ``raytextured``
one). Instead of a virtual call per hit, the integrator maps the hit's BSDF
pointer (its Dr.Jit registry id) to a slot and gathers the parameters from
arrays built here at the start of every render.
"""

import drjit as dr
import mitsuba as mi
import numpy as np

from .background import Background
from .light import Light
from .phong import FLOAT_PARAMS


def with_kt_derivative(surfaces, transmittance, counts):
    """The shadow transmittance T = prod_s kt_s^n_s (n_s crossings of transparent surface s),
    computed detached, given its derivative with respect to the kt: dT = T sum_s n_s dkt_s / kt_s.
    Written as T prod_s (kt_s / detach(kt_s))^n_s, whose value is exactly T."""
    if not dr.grad_enabled(surfaces.refractivity):
        return transmittance
    for s, count in zip(surfaces.transparent_slots, counts):
        kt = dr.gather(mi.Float, surfaces.refractivity, mi.UInt32(s))
        transmittance = transmittance * dr.power(kt / dr.detach(kt), mi.Float(count))
    return transmittance


class SceneTerms:
    """What shading needs from the scene, read from its plugins at the start of a render:
    the surfaces' parameters, the lights, the summed ambient light, the background."""

    def __init__(self, scene):
        self.surfaces = Surfaces(scene)
        self.smooth_meshes = [shape for shape in scene.shapes()
                              if shape.is_mesh() and shape.has_vertex_normals()]
        lights = [e for e in scene.emitters() if isinstance(e, Light)]
        backgrounds = [e for e in scene.emitters() if isinstance(e, Background)]
        self.background = backgrounds[0].color if backgrounds else mi.Color3f(0.0)
        self.ambient = mi.Color3f(0.0)
        for light in lights:
            if light.is_ambient:
                self.ambient += light.color
        self.direct = [light for light in lights if not light.is_ambient]


class Surfaces:
    """The parameters of every surface of a scene as arrays indexed by a *slot*.

    A surface is one BSDF of the scene: a ``rayphong`` material or a
    ``raytextured`` one. Instead of dispatching a virtual call per hit, the
    integrator maps the hit's BSDF pointer (its Dr.Jit registry id) to a slot and
    gathers the parameters from arrays built here from the materials' own
    (differentiable) values, at the start of every render. Only the textures are
    evaluated per surface, masked to the lanes that hit it.
    """

    def __init__(self, scene):
        bsdfs = {}
        for shape in scene.shapes():
            bsdf = shape.bsdf()
            bsdfs.setdefault(dr.reinterpret_array(mi.UInt32, mi.BSDFPtr(bsdf))[0], bsdf)
        ids = list(bsdfs)
        table = np.zeros(max(ids, default=0) + 1, dtype=np.uint32)
        table[ids] = np.arange(len(ids), dtype=np.uint32)
        self.slot_of_id = mi.UInt32(table)
        materials = [bsdf.material for bsdf in bsdfs.values()]
        self.textures = [(mi.UInt32(slot), bsdf.textures)
                         for slot, bsdf in enumerate(bsdfs.values()) if bsdf.textures]
        if not materials:  # a scene with no objects: one slot of zeros, never gathered from
            self.color = dr.zeros(mi.Color3f, 1)
            for name in FLOAT_PARAMS:
                setattr(self, name, dr.zeros(mi.Float, 1))
        else:
            self.color = mi.Color3f(*(dr.concat([mi.Float(m.color[c]) for m in materials])
                                      for c in range(3)))
            for name in FLOAT_PARAMS:
                setattr(self, name, dr.concat([mi.Float(getattr(m, name)) for m in materials]))
        # Surfaces that let shadow rays through (kt > 0), by slot.
        self.transparent_slots = [int(i) for i in np.flatnonzero(self.refractivity.numpy() > 0)]

    def slot(self, si, active):
        return self.slot_of(si.bsdf(), active)

    def slot_of(self, bsdf, active):
        """The slot of each lane's BSDF (a BSDFPtr: its values are Dr.Jit registry ids)."""
        return dr.gather(mi.UInt32, self.slot_of_id, dr.reinterpret_array(mi.UInt32, bsdf), active)

    def get(self, name, slot, active):
        return dr.gather(mi.Float, getattr(self, name), slot, active)

    def base_color(self, si, slot, active):
        """C at each hit: the material's color times the surface's textures."""
        color = dr.gather(mi.Color3f, self.color, slot, active)
        for surface_slot, textures in self.textures:
            mask = active & (slot == surface_slot)
            for texture in textures:
                color = dr.select(mask, color * texture.eval(si, mask), color)
        return color
