"""``raysurfaceset``: the surfaces of a shape whose primitives have surfaces of their own,
and the table of the materials that only they use.

The sphere set (:mod:`raymitsuba.geometry.sphere_set`) is one Mitsuba shape holding many spheres,
each drawn with the surface of its object; Mitsuba gives a shape one BSDF. This BSDF is
that one. It holds, for each primitive in order, which of its *surfaces* it has:

* the surfaces shared with other shapes, or textured: references to ``rayphong`` or
  ``raytextured`` BSDFs of the scene, ``surface_{j}``, j = 0 .. J - 1;
* the materials that only the set's untextured spheres use (a scene of 10^4 spheres
  each with its own material has 10^4 of them): not Mitsuba objects but rows of one
  table, ``materials`` (10 floats a row: color r g b, then ka kd ks n kr kt eta, the
  order of ``Material.FIELDS``: ``raymitsuba.geometry.sphere_set.material_table``), so loading them
  costs one array, not 10^4 plugins.
  Row m is surface J + m, a :class:`TableRow`, with the surface interface
  (``whitted/protocol.py``) like a ``rayphong``.

Their keys stay ``mat{i}.{field}`` (``material_ids``: i of each row): the set *registers*
them in a scene's parameters (``register``, called by ``raymitsuba.api``; ``mi.traverse``
alone does not list them), as Dr.Jit values made then, so that gradients, updates and fits
work on them as on a ``rayphong``'s (``parameters_changed`` brings the table's host values up
to date). The Whitted integrator gives each primitive the slot of its surface
(``whitted/surfaces.py``). Nothing here has an ``eval``, like the surfaces it names.

Parameters:

* ``surface_{j}`` (reference to a surface BSDF), j = 0 .. J - 1;
* ``materials`` (TensorXf, M * 10), ``material_ids`` (TensorXf, M): the table (optional);
* ``surface_of`` (TensorXf, one per primitive): the index of each primitive's surface.
"""

from itertools import repeat

import drjit as dr
import mitsuba as mi
import numpy as np

from raymitsuba.model import Material
from raymitsuba.geometry.sphere_set import MATERIAL_COLUMNS, material_column

PREFIX = "surface_"
FIELDS = Material.FIELDS  # color, then the floats


class SurfaceSet(mi.BSDF):
    def __init__(self, props):
        super().__init__(props)
        count = sum(1 for name in props.keys()
                    if name.startswith(PREFIX) and name[len(PREFIX):].isdigit())
        shared = [props.get(f"{PREFIX}{j}") for j in range(count)]
        table = props.get("materials").numpy().reshape(-1, MATERIAL_COLUMNS) \
            if "materials" in props else np.zeros((0, MATERIAL_COLUMNS), np.float32)
        ids = props.get("material_ids").numpy().astype(np.int64) if "material_ids" in props \
            else np.zeros(0, np.int64)
        self.table = np.array(table, np.float32)  # host values by row (kept current)
        self.material_ids = ids  # the i of each row's key mat{i}
        self.row_of = dict(zip(ids.tolist(), range(len(ids))))  # mat{i}'s row, by i
        self.rows = tuple(map(TableRow, repeat(self, len(ids)), range(len(ids))))  # (C loops)
        # The distinct surfaces (shared ones, then the table's rows) and, per primitive, the
        # index of its surface
        self.surfaces = tuple(shared) + self.rows
        self.table_from = len(shared)  # (the rows, read in bulk from self.table)
        self.surface_of = props.get("surface_of").numpy().astype(np.uint32)
        self.m_flags = mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection \
            | mi.BSDFFlags.FrontSide | mi.BSDFFlags.BackSide
        self.m_components = [self.m_flags]

    # -- the keys of the table's materials ---------------------------------------------------
    def register(self, params):
        """Add ``mat{i}.{field}`` of every row to ``params`` (a SceneParameters), this object
        as their node; the values are made at the first registration and kept."""
        params.hierarchy[self] = (None, 0)
        for m, i in enumerate(self.material_ids):
            for field in FIELDS:
                params.properties[f"mat{i}.{field}"] = (self.value(m, field), None, self,
                                                        mi.ParamFlags.Differentiable)

    def value(self, row, field):
        """The Dr.Jit value of ``field`` of table row ``row`` (made on first use, then kept
        as the row's attribute)."""
        surface = self.rows[row]
        if getattr(surface, field) is None:
            values = self.table[row, material_column(field)]
            value = mi.Color3f(*map(float, values)) if field == "color" \
                else mi.Float(float(values))
            dr.make_opaque(value)
            setattr(surface, field, value)
        return getattr(surface, field)

    def parameters_changed(self, keys=None):
        """Bring the host table up to date with the values of ``keys`` (``mat{i}.{field}``)."""
        for key in keys or ():
            owner, _, field = key.partition(".")
            row = self.row_of.get(int(owner[3:])) if owner[3:].isdigit() else None
            value = getattr(self.rows[row], field, None) if row is not None else None
            if value is None:
                continue
            dr.make_opaque(value)  # data, not a constant of the kernels
            self.table[row, material_column(field)] = \
                [value.x[0], value.y[0], value.z[0]] if field == "color" else value[0]
            self.rows[row].host = None  # (read again from the table when next asked)

    def traverse(self, callback):
        pass  # the shared surfaces' parameters are under their own ids; the table: register

    def to_string(self):
        return f"SurfaceSet[{len(self.surface_of)} primitives, {len(self.material_ids)} materials]"


class TableRow:
    """Row ``row`` of a surface set's table as a surface and its own material (the surface
    interface of ``whitted/protocol.py``, as a ``rayphong``): no checkerboard, no image
    texture; its parameters (``color``, ``ambient_mix``, ...) are None until the set's keys
    are registered, then their Dr.Jit values."""

    checker_size = 0.0
    image_textures = ()

    def __init__(self, surface_set, row):
        self.set, self.row = surface_set, row
        self.host = None  # the host values, read from the set's table on first use

    @property
    def material(self):
        return self

    @property
    def host_values(self):
        if self.host is None:
            values = self.set.table[self.row]
            self.host = {field: tuple(values[material_column(field)]) if field == "color"
                         else values[material_column(field)] for field in FIELDS}
        return self.host


for _field in FIELDS:  # a row's parameters: None (class attributes) until registered
    setattr(TableRow, _field, None)
