"""The surface table of the Whitted integrator: every surface's parameters as arrays
indexed by a *slot*, and the scene's lights and background as shading needs them.

A surface is one BSDF of the scene (anything that provides the surface interface of
``protocol.py``: ``rayphong``, ``raytextured``). Instead of a virtual call per hit,
the integrator maps the hit's *shape* pointer (its Dr.Jit registry id) to the slot of
the shape's BSDF and gathers the parameters from arrays built here at the start of
every render. (Not ``si.bsdf()``: that getter is a call over every shape whose code
names each shape's BSDF, so the kernels would change with the scene's contents.)

**Constant-size kernels.** Nothing here issues one JIT operation per surface, material
or texture of the scene, so no kernel's size depends on how many there are:

* slots: the distinct BSDFs of all shapes, in increasing registry id, and a table
  from shape id (read in one vectorized call) to slot; a Python pass over the shapes
  and the distinct surfaces (no JIT work)
  reads their materials, checker sizes and image textures;
* parameter values: each material's (width-1, evaluated) values are read on the host,
  assembled into one numpy array per parameter and uploaded as one array. A value
  whose gradient is enabled is then *scattered* into the slots of its material (one
  scatter per such value: the materials being fitted), so that the gathers carry its
  derivative;
* textures: the checkerboard is one formula with a square size by slot; image
  textures are evaluated once per *distinct* texture object (a loop over the textures,
  not over the surfaces; a scene has a handful).

Lights stay unrolled (one shading term per light in the kernel: scenes have a
handful; see ``SceneTerms``).
"""

import drjit as dr
import mitsuba as mi
import numpy as np

from .protocol import check_emitter, check_surface
from ..checkerboard import checker
from ..phong import FLOAT_PARAMS

NO_SLOT = 0xFFFFFFFF  # a slot index that names no surface (e.g. an unused crossing record)
# Every table has at least this many rows: Dr.Jit folds a gather from a one-element array
# into a broadcast, so a scene with one surface would otherwise get kernels of its own.
MIN_ROWS = 2


def with_kt_derivative(surfaces, transmittance, crossed_slots):
    """The shadow transmittance T = prod_i kt[slot_i] over the transparent crossings i of a
    shadow ray (computed detached), given its derivative with respect to the kt:
    T prod_i kt[slot_i] / detach(kt[slot_i]), whose value is exactly T.

    ``crossed_slots``: a fixed-size record (one UInt32 per possible crossing, up to
    max_shadow_crossings) of the slots crossed, NO_SLOT where there was no crossing;
    None when the kt have no gradient (then T is returned as is)."""
    if crossed_slots is None:
        return transmittance
    for slot in crossed_slots:
        crossed = slot != NO_SLOT
        kt = dr.gather(mi.Float, surfaces.refractivity, slot, crossed)
        ratio = kt / dr.select(crossed, dr.detach(kt), 1.0)
        transmittance = transmittance * dr.select(crossed, ratio, 1.0)
    return transmittance


class SceneTerms:
    """What shading needs from the scene, read from its plugins at the start of a render
    (each checked once against the interface of ``protocol.py``): the surfaces'
    parameters, the lights, the summed ambient light, the background.

    The direct (non-ambient) lights stay a Python list: the shading kernel has one term
    per light (scenes have a handful; the kernel grows with their number)."""

    def __init__(self, scene, previous=None):
        self.surfaces = Surfaces(scene, previous.surfaces if previous is not None else None)
        lights, backgrounds = [], []
        for emitter in scene.emitters():
            (lights if check_emitter(emitter) == "light" else backgrounds).append(emitter)
        self.background = backgrounds[0].background_color if backgrounds else mi.Color3f(0.0)
        self.ambient = mi.Color3f(0.0)
        for light in lights:
            if light.is_ambient:
                self.ambient += light.color
        self.direct = [light for light in lights if not light.is_ambient]


def shape_ids(scene):
    """The registry ids of the scene's shapes (one vectorized read), in ``scene.shapes()``
    order: they name the shapes while the scene lives."""
    if not scene.shapes():
        return np.zeros(0, np.uint32)
    return dr.reinterpret_array(mi.UInt32, scene.shapes_dr()).numpy()


# What a Surfaces table keeps from one render to the next of the same shapes (set_layout).
LAYOUT = ("key", "count", "slot_of_shape", "materials", "material_of_slot", "checker_size",
          "textures", "texture_of_slot", "uses_uv")


class Surfaces:
    """The parameters of every surface of a scene as arrays indexed by a *slot* (see the
    module docstring): ``color`` (Color3f) and one mi.Float per name of FLOAT_PARAMS,
    ``checker_size`` (None if no surface has a checkerboard), the distinct image
    ``textures`` and, per slot, which of them apply (``texture_of_slot``)."""

    def __init__(self, scene, previous=None):
        """The table of ``scene``; ``previous``: the table of an earlier render, whose
        layout (slots, materials, textures, checker sizes: fixed once a scene is loaded) is
        reused when the scene's shapes are the same ones. The values are read anew."""
        key = shape_ids(scene)
        if previous is not None and np.array_equal(previous.key, key):
            self.__dict__.update({name: getattr(previous, name) for name in LAYOUT})
        else:
            self.set_layout(scene, key)
        self.set_parameters(self.materials, self.material_of_slot)
        # Whether any surface lets shadow rays through (kt > 0).
        self.any_transparent = bool(np.any(self.host["refractivity"] > 0))

    def set_layout(self, scene, key):
        """Slots, materials, checker sizes and textures: what a render reads from the
        scene's plugins besides the parameter values."""
        self.key = key
        bsdfs = self.distinct_bsdfs(scene, scene.shapes(), key)
        self.count = len(bsdfs)

        # Materials: each distinct one once, with the slots that use it.
        materials, material_of_slot = {}, np.zeros(len(bsdfs), np.int64)
        for slot, bsdf in enumerate(bsdfs):
            material_of_slot[slot] = materials.setdefault(id(bsdf.material),
                                                          (len(materials), bsdf.material))[0]
        self.materials = [material for _, material in materials.values()]
        self.material_of_slot = material_of_slot

        sizes = np.zeros(max(len(bsdfs), MIN_ROWS), np.float32)
        sizes[:len(bsdfs)] = [float(bsdf.checker_size) for bsdf in bsdfs]
        self.checker_size = mi.Float(sizes) if np.any(sizes > 0) else None
        self.set_textures(bsdfs)
        # Whether shading reads the hits' texture coordinates (HitTable.update's uv).
        self.uses_uv = self.checker_size is not None or bool(self.textures)

    def distinct_bsdfs(self, scene, shapes, shape_ids):
        """The scene's distinct BSDFs in slot order (increasing registry id), each checked
        against the surface interface; sets ``slot_of_shape`` (by shape registry id)."""
        if not shapes:
            self.slot_of_shape = dr.zeros(mi.UInt32, MIN_ROWS)
            return []
        # (Not ``shapes_dr().bsdf()``: that getter is a kernel, folded to a constant when
        # all shapes share one BSDF, so its code would depend on the scene.)
        bsdfs, index_of_shape = {}, np.empty(len(shapes), np.int64)
        for i, shape in enumerate(shapes):
            bsdf = shape.bsdf()
            index_of_shape[i] = bsdfs.setdefault(id(bsdf), (len(bsdfs), bsdf, shape))[0]
        found = list(bsdfs.values())
        registry_ids = [dr.reinterpret_array(mi.UInt32, mi.BSDFPtr(bsdf))[0] for _, bsdf, _ in found]
        order = np.argsort(registry_ids, kind="stable")
        slot_of_index = np.empty(len(found), np.uint32)
        slot_of_index[order] = np.arange(len(found), dtype=np.uint32)
        table = np.zeros(max(int(shape_ids.max()) + 1, MIN_ROWS), dtype=np.uint32)
        table[shape_ids] = slot_of_index[index_of_shape]
        self.slot_of_shape = mi.UInt32(table)
        return [check_surface(found[i][1], found[i][2]) for i in order]

    def set_parameters(self, materials, material_of_slot):
        """One array per parameter, by slot: host values (each material's ``host_values``)
        uploaded once, then a scatter per value whose gradient is enabled."""
        rows = max(len(material_of_slot), MIN_ROWS)  # rows past the last slot: zeros
        values = np.array([material.host_values for material in materials],
                          np.float32).reshape(len(materials), 3 + len(FLOAT_PARAMS))
        host = {"color": values[:, :3]}
        host.update({name: values[:, 3 + k] for k, name in enumerate(FLOAT_PARAMS)})
        attached = []
        for m, material in enumerate(materials):
            params = [material.color] + [getattr(material, name) for name in FLOAT_PARAMS]
            if dr.grad_enabled(params):  # (one call: most materials have none)
                attached += [(name, m, value) for name, value in
                             zip(("color",) + tuple(FLOAT_PARAMS), params)
                             if dr.grad_enabled(value)]
        by_slot = {name: np.zeros((rows,) + values.shape[1:], np.float32)
                   for name, values in host.items()}
        for name, values in host.items():
            by_slot[name][:len(material_of_slot)] = values[material_of_slot]
        self.host = by_slot
        self.color = mi.Color3f(*(mi.Float(np.ascontiguousarray(by_slot["color"][:, c]))
                                  for c in range(3)))
        for name in FLOAT_PARAMS:
            setattr(self, name, mi.Float(by_slot[name]))
        for name, m, value in attached:
            slots = mi.UInt32(np.flatnonzero(material_of_slot == m).astype(np.uint32))
            dr.scatter(getattr(self, name), value, slots)

    def set_textures(self, bsdfs):
        """The distinct image textures and, for each position k in a surface's tuple of
        image textures, the texture at that position by slot (its index + 1; 0: none)."""
        textures, rows = {}, []
        for slot, bsdf in enumerate(bsdfs):
            for k, texture in enumerate(bsdf.image_textures):
                if k == len(rows):
                    rows.append(np.zeros(max(len(bsdfs), MIN_ROWS), np.uint32))
                rows[k][slot] = textures.setdefault(id(texture), (len(textures) + 1, texture))[0]
        self.textures = [texture for _, texture in textures.values()]
        self.texture_of_slot = [mi.UInt32(row) for row in rows]

    def slot(self, shape, active):
        """The slot of the BSDF of each lane's shape (a ShapePtr, e.g. ``si.shape``: its
        values are Dr.Jit registry ids)."""
        return dr.gather(mi.UInt32, self.slot_of_shape, dr.reinterpret_array(mi.UInt32, shape),
                         active)

    def get(self, name, slot, active):
        return dr.gather(mi.Float, getattr(self, name), slot, active)

    def base_color(self, si, slot, active):
        """C at each hit: the material's color times the surface's image textures (in
        order), times its checkerboard."""
        color = dr.gather(mi.Color3f, self.color, slot, active)
        for texture_of_slot in self.texture_of_slot:
            which = dr.gather(mi.UInt32, texture_of_slot, slot, active)
            for index, texture in enumerate(self.textures, start=1):
                mask = active & (which == index)
                color = dr.select(mask, color * texture.eval(si, mask), color)
        if self.checker_size is not None:
            size = dr.gather(mi.Float, self.checker_size, slot, active)
            mask = active & (size > 0)
            color = dr.select(mask, color * checker(si.uv, dr.select(mask, size, 1.0)), color)
        return color
