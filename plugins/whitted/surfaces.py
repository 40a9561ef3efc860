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
  and the distinct surfaces (no JIT work) reads their materials, checker sizes and
  image textures (the ``Layout``, reused while the shapes are the same). A shape whose
  BSDF is a *surface set* (``protocol.SurfaceSet``: the sphere set, whose spheres each
  have their surface, some of them rows of its material table that are no Mitsuba
  objects) gives each primitive the slot of its surface: ``PrimitiveSlots``, by shape
  id the first row of a table by primitive;
* parameter values: the materials' ``host_values`` (kept on the host by each material),
  assembled by name into one numpy array per parameter and uploaded as one array. A value
  whose gradient is enabled is then *scattered* into the slots of its material (one
  scatter per such value: the materials being fitted), so that the gathers carry its
  derivative;
* textures: the checkerboard is one formula with a square size by slot; image
  textures are evaluated once per *distinct* texture object (a loop over the textures,
  not over the surfaces; a scene has a handful).

Lights stay unrolled (one shading term per light in the kernel: scenes have a
handful; see ``SceneTerms``).
"""

from itertools import compress, count, repeat
from operator import attrgetter, is_not, itemgetter
from typing import NamedTuple

import drjit as dr
import mitsuba as mi
import numpy as np

from .arrays import jit_array
from .hits import HitTable, shape_ids
from .protocol import SURFACE_PARAMETERS, SurfaceSet, check_emitter, check_surface
from ..checkerboard import FIRST_ORDER, checker, filtered_board

NO_SLOT = 0xFFFFFFFF  # a slot index that names no surface (e.g. an unused crossing record)
# Every table has at least this many rows: Dr.Jit folds a gather from a one-element array
# into a broadcast, so a scene with one surface would otherwise get kernels of its own.
MIN_ROWS = 2


class BaseColor(NamedTuple):
    """A surface's color C at each hit (:meth:`Surfaces.base_color`), and how it was read,
    which anti-aliasing's path signatures need (``signature.py``)."""

    color: object  # Color3f
    sampled: object  # Bool: a texture was read at the hit point only (an image texture, a
    # checkerboard without a footprint or with one ``footprint_resolved`` refuses: off the
    # table's meshes, towards the horizon), which cannot stand for the pixel's average
    distortion: object  # Float: how distorted the checkerboard's footprint still is
    # (``residual_distortion``; where it holds a corner of the board, at least twice
    # FIRST_ORDER; 0 off checkerboards), which asks for a grid of smaller footprints


class OpaqueSetError(ValueError):
    """A material of the sphere set's spheres became transparent (see Surfaces)."""


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
    parameters, the lights, the summed ambient light, the background, the geometry.

    The direct (non-ambient) lights stay a Python list: the shading kernel has one term
    per light (scenes have a handful; the kernel grows with their number)."""

    def __init__(self, scene, surfaces=None, geometry=None, geometry_ad=None):
        """The terms of ``scene``. ``surfaces``: the surface table of an earlier render, whose
        layout is reused for the same shapes (see Surfaces); ``geometry``: the HitTable to
        bring up to date with the scene (default: a new one)."""
        lights, backgrounds = [], []
        ids = shape_ids(scene)  # read once: both tables are keyed by them
        self.surfaces = Surfaces(scene, surfaces, ids)  # the surface table
        for emitter in scene.emitters():
            (lights if check_emitter(emitter) == "light" else backgrounds).append(emitter)
        # Color3f: the color of every ray that hits nothing
        self.background = backgrounds[0].background_color if backgrounds else mi.Color3f(0.0)
        ambient = mi.Color3f(0.0)
        for light in lights:
            if light.is_ambient:
                ambient += light.color
        self.ambient = ambient  # Color3f: the sum of the ambient lights
        self.direct = [light for light in lights if not light.is_ambient]  # the other lights
        geometry = HitTable() if geometry is None else geometry
        self.geometry = geometry.update(scene, self.surfaces.layout.uses_uv, ids)  # the hits' table
        if geometry_ad is not None:  # (issue 13) the table, its geometry attached to the keys
            self.geometry = geometry_ad.table(self.geometry)


class Layout:
    """What a surface table keeps from one render to the next of the same shapes (fixed once
    a scene is loaded): the slots, the materials, the checker sizes and the image textures,
    read from the scene's plugins by a Python pass over the shapes and the distinct
    surfaces -- but for a surface set's table rows, which are read as blocks (``tables``)."""

    def __init__(self, scene, key):
        """The layout of ``scene``, whose shapes have the registry ids ``key``."""
        bsdfs, tables, slot_of_shape, primitives = distinct_bsdfs(scene.shapes(), key)
        materials, material_of_slot = distinct_materials(bsdfs, tables)
        self.key = key  # the shapes' registry ids (scene.shapes() order): whose layout this is
        self.count = len(bsdfs) + sum(len(rows) for _, rows in tables)  # the slots
        self.slot_of_shape = slot_of_shape  # UInt32: the slot by shape registry id
        self.primitives = primitives  # PrimitiveSlots of the surface sets' shapes, or None
        self.materials = materials  # the distinct materials of the surfaces
        self.material_of_slot = material_of_slot  # by slot, the index of its material
        # The surface sets' table rows: [(set, its rows)], their slots following the others'
        # in this order (the rows have no checkerboard, no texture: their own material each)
        self.tables = tables
        self.checker_size = checker_sizes(bsdfs, self.count)  # Float by slot; None: none at all
        # The distinct image textures and, per position k in a surface's image_textures, the
        # texture at that position by slot (UInt32: its index + 1; 0: none)
        self.textures, self.texture_of_slot = image_textures(bsdfs, self.count)
        # Whether shading reads the hits' texture coordinates (HitTable.update's uv)
        self.uses_uv = self.checker_size is not None or bool(self.textures)


def distinct_bsdfs(shapes, shape_ids):
    """(The distinct surfaces of ``shapes`` that are no table row, in slot order (increasing
    registry id), each checked against the surface interface; the surface sets' table rows
    [(set, rows)], whose slots follow, in the order found; the slot by shape registry id,
    UInt32; the :class:`PrimitiveSlots` of the shapes whose BSDF is a surface set, or
    None)."""
    if not shapes:
        return [], [], dr.zeros(mi.UInt32, MIN_ROWS), None
    # (Not ``shapes_dr().bsdf()``: that getter is a kernel, folded to a constant when
    # all shapes share one BSDF, so its code would depend on the scene.)
    bsdfs, index_of_shape, sets, tables = {}, np.full(len(shapes), -1, np.int64), [], []
    rows_found = 0
    for i, shape in enumerate(shapes):
        bsdf = shape.bsdf()
        if isinstance(bsdf, SurfaceSet):  # a surface per primitive: its index, per primitive
            first = bsdf.table_from
            rows = bsdf.surfaces[first:]
            indices = np.empty(len(bsdf.surfaces), np.int64)
            indices[:first] = [bsdfs.setdefault(id(surface), (len(bsdfs), surface, shape))[0]
                               for surface in bsdf.surfaces[:first]]
            # a table row's index: -1 - its position among all the tables' rows
            indices[first:] = -1 - (rows_found + np.arange(len(rows)))
            rows_found += len(rows)
            tables.append((bsdf, rows, shape))
            sets.append((i, indices[bsdf.surface_of]))
            continue
        index_of_shape[i] = bsdfs.setdefault(id(bsdf), (len(bsdfs), bsdf, shape))[0]
    found = list(bsdfs.values())
    # Mitsuba's BSDFs by registry id, then any surface that is no Mitsuba object in the
    # order found; the tables' rows after them
    registry_ids = [dr.reinterpret_array(mi.UInt32, mi.BSDFPtr(bsdf))[0]
                    if isinstance(bsdf, mi.BSDF) else 0xFFFFFFFF for _, bsdf, _ in found]
    order = np.argsort(registry_ids, kind="stable")
    slot_of_index = np.empty(len(found), np.uint32)
    slot_of_index[order] = np.arange(len(found), dtype=np.uint32)
    table = np.zeros(max(int(shape_ids.max()) + 1, MIN_ROWS), dtype=np.uint32)
    own = index_of_shape >= 0  # (a surface set's shape: slot 0; its primitives' own follow)
    table[shape_ids[own]] = slot_of_index[index_of_shape[own]]
    primitives = PrimitiveSlots(sets, shape_ids, slot_of_index, len(table)) if sets else None
    # (a surface that is no Mitsuba object -- a table row -- is checked once per class)
    checked = set()
    surfaces = []
    for i in order:
        _, surface, shape = found[i]
        if isinstance(surface, mi.BSDF) or type(surface) not in checked:
            check_surface(surface, shape)
            checked.add(type(surface))
        surfaces.append(surface)
    for _, rows, shape in tables:
        if rows and type(rows[0]) not in checked:
            check_surface(rows[0], shape)
            checked.add(type(rows[0]))
    tables = [(surface_set, rows) for surface_set, rows, _ in tables]
    return surfaces, tables, jit_array(mi.UInt32, table), primitives


class PrimitiveSlots:
    """The slots of the primitives of the shapes whose BSDF is a surface set
    (``protocol.SurfaceSet``: the sphere set): ``first`` by shape registry id (UInt32:
    the shape's first row of ``slot``, NO_SLOT for the other shapes) and ``slot`` (UInt32:
    by row, the slot of that primitive's surface); ``slots`` (numpy): the slots they use."""

    def __init__(self, sets, shape_ids, slot_of_index, rows):
        first = np.full(rows, NO_SLOT, np.uint32)
        slots, start = [], 0
        for i, indices in sets:
            first[shape_ids[i]] = start
            # a table row's index -1 - k: its slot follows the other surfaces' slots
            slot = (len(slot_of_index) - 1 - indices).astype(np.uint32)
            own = indices >= 0
            slot[own] = slot_of_index[indices[own]]
            slots.append(slot)
            start += len(indices)
        by_row = np.concatenate(slots)
        self.first = jit_array(mi.UInt32, first)
        self.slot = jit_array(mi.UInt32, np.concatenate(
            [by_row, np.zeros(max(MIN_ROWS - len(by_row), 0), np.uint32)]))
        self.slots = np.unique(by_row)


def distinct_materials(bsdfs, tables):
    """(Each distinct material of ``bsdfs`` once, then the tables' rows, each its own
    material; by slot, the index of its material)."""
    materials = {}
    rows = sum(len(r) for _, r in tables)
    material_of_slot = np.zeros(len(bsdfs) + rows, np.int64)
    for slot, bsdf in enumerate(bsdfs):
        material_of_slot[slot] = materials.setdefault(id(bsdf.material),
                                                      (len(materials), bsdf.material))[0]
    material_of_slot[len(bsdfs):] = len(materials) + np.arange(rows)
    return [material for _, material in materials.values()] + \
        [row for _, r in tables for row in r], material_of_slot


def checker_sizes(bsdfs, count):
    """The checkerboard's square size by slot (Float; 0: none), None if no surface has one
    (``count`` slots: the table rows, after ``bsdfs``, have none)."""
    sizes = np.zeros(max(count, MIN_ROWS), np.float32)
    sizes[:len(bsdfs)] = [float(bsdf.checker_size) for bsdf in bsdfs]
    return jit_array(mi.Float, sizes) if np.any(sizes > 0) else None


def image_textures(bsdfs, count):
    """(The distinct image textures; for each position k in a surface's tuple of image
    textures, the texture at that position by slot: UInt32, its index + 1, 0: none; of
    ``count`` slots: the table rows, after ``bsdfs``, have none)."""
    textures, rows = {}, []
    for slot, bsdf in enumerate(bsdfs):
        for k, texture in enumerate(bsdf.image_textures):
            if k == len(rows):
                rows.append(np.zeros(max(count, MIN_ROWS), np.uint32))
            rows[k][slot] = textures.setdefault(id(texture), (len(textures) + 1, texture))[0]
    return [texture for _, texture in textures.values()], [mi.UInt32(row) for row in rows]


# A material's host values as a numpy record: a field per parameter, in the order of
# SURFACE_PARAMETERS, the order in which host_parameters picks them by name.
HOST_RECORD = np.dtype([(name, np.float32, 3) if name == "color" else (name, np.float32)
                        for name in SURFACE_PARAMETERS])


def host_parameters(layout):
    """Each parameter's values by slot on the host ({name: float32 array}, ``color`` (rows,
    3)), from the materials' ``host_values`` (read in one pass) and the tables (read as
    arrays); rows past the last slot are zeros."""
    values_of = itemgetter(*SURFACE_PARAMETERS)
    rows = sum(len(r) for _, r in layout.tables)
    own = len(layout.materials) - rows  # the materials that are no table row
    records = np.empty(len(layout.materials), HOST_RECORD)
    records[:own] = [values_of(material.host_values) for material in layout.materials[:own]]
    if rows:  # the tables' columns: color's three, then the others in order (protocol.py)
        table = np.concatenate([surface_set.table for surface_set, _ in layout.tables])
        records["color"][own:] = table[:, 0:3]
        for k, name in enumerate(SURFACE_PARAMETERS[1:], start=3):
            records[name][own:] = table[:, k]
    slots = max(layout.count, MIN_ROWS)
    host = {}
    for name in SURFACE_PARAMETERS:
        by_slot = np.zeros((slots,) + records[name].shape[1:], np.float32)
        by_slot[:layout.count] = records[name][layout.material_of_slot]
        host[name] = by_slot
    return host


def attached_values(materials):
    """(Parameter name, material index, value) of every material value whose gradient is
    enabled (a value that is None: a table row's, not registered)."""
    values_of, attached = attrgetter(*SURFACE_PARAMETERS), []
    # (the materials with values found in C loops: a sphere set's 10^5 table rows hold None
    # until their keys are registered)
    firsts = list(map(attrgetter(SURFACE_PARAMETERS[0]), materials))
    for m in compress(count(), map(is_not, firsts, repeat(None))):
        values = values_of(materials[m])
        if dr.grad_enabled(values):  # (one call: most have none)
            attached += [(name, m, value) for name, value in zip(SURFACE_PARAMETERS, values)
                         if dr.grad_enabled(value)]
    return attached


def upload(name, by_slot):
    """The device array of a parameter's values by slot (``color``: Color3f; others: Float)."""
    if name == "color":
        return mi.Color3f(*(jit_array(mi.Float, by_slot[:, c]) for c in range(3)))
    return jit_array(mi.Float, by_slot)


class Surfaces:
    """The parameters of every surface of a scene as arrays indexed by a *slot* (see the
    module docstring): one attribute per name of ``protocol.SURFACE_PARAMETERS`` (``color``
    a Color3f, the others Float), with the slots, checker sizes and image textures of its
    ``layout``."""

    def __init__(self, scene, previous=None, ids=None):
        """The table of ``scene``; ``previous``: the table of an earlier render, whose
        layout (slots, materials, textures, checker sizes: fixed once a scene is loaded) is
        reused when the scene's shapes are the same ones. The values are read anew.
        ``ids``: the shapes' registry ids (``hits.shape_ids``), if already read."""
        key = shape_ids(scene) if ids is None else ids
        same_shapes = previous is not None and np.array_equal(previous.layout.key, key)
        self.layout = previous.layout if same_shapes else Layout(scene, key)  # (see Layout)
        attached = attached_values(self.layout.materials)
        self.host = host_parameters(self.layout)  # each parameter's values by slot (numpy)
        # One array by slot per parameter, uploaded once; a value whose gradient is enabled
        # is then scattered into the slots of its material, so that the gathers carry it.
        for name in SURFACE_PARAMETERS:
            setattr(self, name, upload(name, self.host[name]))
        for name, m, value in attached:
            slots = jit_array(mi.UInt32, np.flatnonzero(self.layout.material_of_slot == m))
            dr.scatter(getattr(self, name), value, slots)
        self.any_transparent = bool(np.any(self.host["refractivity"] > 0))  # any kt > 0
        # any kt != 0 (a negative one is warned of, not refused: under total internal
        # reflection it still adds to the reflected child's weight)
        self.any_kt = bool(np.any(self.host["refractivity"] != 0))
        # whether some ray may have a child (some kr or kt > 0): else the tree is one generation
        self.any_specular = self.any_transparent or bool(np.any(self.host["reflectivity"] > 0))
        primitives = self.layout.primitives
        if primitives is not None and np.any(self.host["refractivity"][primitives.slots] > 0):
            raise OpaqueSetError(
                "raywhitted: a material of the sphere set has kt > 0, but the set's spheres "
                "must stay opaque (Mitsuba's ellipsoids cull the hits of rays from inside); "
                "load the scene with --sphere-set 0 (sphere_set=0) to make them transparent "
                "(raymitsuba/geometry/sphere_set.py)")

    def slot(self, shape, prim_index, active):
        """The slot of the surface of each lane's shape and primitive (a ShapePtr, e.g.
        ``si.shape``: its values are Dr.Jit registry ids; ``si.prim_index``): the shape's,
        or the primitive's for a shape whose BSDF is a surface set."""
        shape_id = dr.reinterpret_array(mi.UInt32, shape)
        slot = dr.gather(mi.UInt32, self.layout.slot_of_shape, shape_id, active)
        primitives = self.layout.primitives
        if primitives is None:
            return slot
        first = dr.gather(mi.UInt32, primitives.first, shape_id, active)
        in_set = active & (first != NO_SLOT)
        return dr.select(in_set, dr.gather(mi.UInt32, primitives.slot, first + prim_index,
                                           in_set), slot)

    def get(self, name, slot, active):
        """The float parameter ``name`` of each lane's slot."""
        return dr.gather(mi.Float, getattr(self, name), slot, active)

    def base_color(self, si, slot, active, footprint=None):
        """C at each hit: the material's color times the surface's image textures (in
        order), times its checkerboard, with how it was read (a :class:`BaseColor`);
        ``footprint``: (duv_dx, duv_dy, distortion), each sample's footprint in texture
        space (anti-aliasing's rays, ``HitTable.uv_footprint``), over which the checkerboard
        is averaged (``filtered_board``), or None: its value at the point."""
        layout = self.layout
        color = dr.gather(mi.Color3f, self.color, slot, active)
        sampled, distortion = mi.Bool(False), mi.Float(0.0)
        for texture_of_slot in layout.texture_of_slot:
            which = dr.gather(mi.UInt32, texture_of_slot, slot, active)
            sampled |= active & (which != 0)
            for index, texture in enumerate(layout.textures, start=1):
                mask = active & (which == index)
                color = dr.select(mask, color * texture.eval(si, mask), color)
        if layout.checker_size is not None:
            size = dr.gather(mi.Float, layout.checker_size, slot, active)
            board = active & (size > 0)
            size = dr.select(board, size, 1.0)
            if footprint is None:
                value = checker(si.uv, size)
                sampled |= board
            else:
                average = filtered_board(si.uv, size, *footprint)
                value = average.value
                sampled |= board & ~average.resolved
                # (where it holds a corner the average is not exact; a 2 x 2 grid of quarter
                # footprints, each with a quarter of the error, is)
                distortion = dr.select(board, dr.maximum(average.residual, dr.select(
                    average.corner, 2.0 * FIRST_ORDER, 0.0)), 0.0)
            color = dr.select(board, color * value, color)
        return BaseColor(color, sampled, distortion)

