"""The translator: a parsed :class:`~raymitsuba.model.Scene` to one Mitsuba scene dict.

``translate(model, options) -> dict`` is pure bookkeeping over the model: it
decides *which Mitsuba object* stands for each .RAY construct, never what a
command means (the parser already did). The dict is inspectable and is what
``mi.load_dict`` receives. Its top-level ids are the public parameter names:

* ``mat{i}``: the i-th material in file order (``mat0``: the default), a
  ``rayphong`` BSDF shared by reference by every object declared under it;
* ``light{j}``: the j-th ``light`` line, a ``raylight`` emitter;
* ``background``: a ``raybackground`` emitter;
* ``sensor``, ``integrator`` (``raywhitted``);
* shapes ``sphere_{line}``, ``plane_{line}`` (``{kind}_{line}_{n}`` for the n-th object
  when a MIT 6.837 line holds several), ``triangles_{k}`` and ``quadrics_{k}`` (merged
  meshes, one per surface), ``mesh{k}`` (MIT 6.837 mesh blocks), and textured surfaces
  ``surface{k}`` (``raytextured`` wrapping ``mat{i}``).

Geometry choices (the work is linear in the number of objects, done in bulk with numpy
wherever there are many):

* sphere: Mitsuba's analytic ``sphere`` when the transform is a similarity
  without mirroring (exact), else tessellated (below); in a scene with at least
  ``Options.sphere_set`` (256) opaque spheres that may join it (analytic ones, and
  tessellated ones of an untextured surface), those are one shape, ``spheres``
  (:mod:`raymitsuba.geometry.sphere_set`: Mitsuba's ``ellipsoids``, exact spheres and ellipsoids);
* cylinder, cone, and the other spheres: tessellated (see :mod:`raymitsuba.geometry.tessellation`),
  all those of one surface merged into one smooth ``raytriangles`` mesh, ``quadrics_{k}``;
* plane: ``rayplane``, rings centred under the camera out past the horizon;
* triangles: one flat ``raytriangles`` mesh per surface, ``triangles_{k}``.
* MIT 6.837 mesh blocks: one ``raytriangles`` mesh ``mesh{k}`` per mesh of the model,
  its corners gathered in bulk with numpy (:func:`mesh_shapes`).

The camera's vertical field of view for the image's aspect comes from
``Camera.vertical_fov`` (the MIT 6.837 fov is horizontal).

Tessellation density follows the object's projected size: a curved object whose
bounding sphere spans r pixels gets m = pi sqrt(r / (2 e)) segments around, so its
polygonal silhouette is within e = 0.05 pixel of the true one (clamped to
[MIN_SEGMENTS, MAX_SEGMENTS], even).

The **tessellation budget** bounds the memory and the load time (Embree's BVH build is
the largest cost per triangle): when the tessellated objects together would have more
than ``Options.tessellation_budget`` triangles (TESSELLATION_BUDGET, 250,000: about 40 MB
of mesh arrays and BVH at BYTES_PER_TRIANGLE), every count is scaled down by one common factor,
the largest that fits, trading silhouette accuracy (about r pi^2 / (2 m^2) pixels for an
object of r pixels with m segments) for memory and time. In practice the budget first
removes the margin of MIN_SEGMENTS on small objects (a 5-pixel object needs 23 segments
for 0.05 px, and gets 48 without the budget). No count goes below BUDGET_MIN_SEGMENTS (8);
at that floor the budget gives way, up to ``Options.tessellation_limit`` triangles
(TESSELLATION_LIMIT, 8 million: about 1.3 GB), past which the scene is refused with a
:class:`GeometryTooLarge` error before any mesh is built.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import operator
from itertools import chain, compress, count, repeat
from dataclasses import dataclass
from typing import Optional

import numpy as np

from raymitsuba.geometry import sphere_set, tessellation
from raymitsuba.model import Material, ObjectKind, Scene, SceneObject
from raymitsuba.options import RenderOptions

SILHOUETTE_ERROR_PX = 0.05
MIN_SEGMENTS, MAX_SEGMENTS = 48, 768
TESSELLATION_BUDGET = 250_000  # triangles of all tessellated objects together (soft)
BUDGET_MIN_SEGMENTS = 8  # the budget never takes an object below this many segments around
TESSELLATION_LIMIT = 8_000_000  # triangles past which a scene is refused (hard)
# merged mesh arrays (~120: 3 unshared vertices, the faces' neighbours) and Embree's BVH
BYTES_PER_TRIANGLE = 160
PLANE_REACH = 1e6  # the plane mesh reaches this many camera heights away
NEAR_CLIP, FAR_CLIP = 1e-4, 1e12

# Mitsuba's analytic sphere has its pole on local +z; the format's sphere (and
# its texture coordinates) on +y. This rotation maps local z to object y.
Z_TO_Y = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=np.float64)


@dataclass(frozen=True)
class Options(RenderOptions):
    """The render options (:class:`raymitsuba.options.RenderOptions`, each explained there)
    and the translator's own: the tessellation budget and limit (see the module docstring).
    A size left None is the scene's (:meth:`~raymitsuba.model.Scene.image_size`)."""

    tessellation_budget: int = TESSELLATION_BUDGET
    tessellation_limit: int = TESSELLATION_LIMIT
    # The segment counts of the tessellated objects, fixed ((kind, counts) pairs in the order
    # the translation meets them: :func:`tessellation_segments`), or None: chosen from the
    # camera and the budget. The geometry keys fix them, so a moving object keeps its mesh.
    segments: Optional[tuple] = None


class GeometryTooLarge(ValueError):
    """The scene's curved objects cannot be tessellated within the hard limit."""


def translate(model: Scene, options: Options | None = None, **kwargs) -> dict:
    """The Mitsuba scene dict for ``model`` (options as an Options or keywords)."""
    import mitsuba as mi  # the caller has set the variant (raymitsuba.backend)

    options = options or Options(**kwargs)
    width, height = model.image_size(options.width, options.height)
    options = dataclasses.replace(options, width=width, height=height)
    scene = {"type": "scene",
             "integrator": {"type": "raywhitted", **options.integrator_properties()},
             "sensor": sensor(model, options, mi),
             "background": {"type": "raybackground", "color": rgb(model.background, mi)}}
    surfaces = Surfaces(options, mi)
    objects = shapes(model, options, surfaces, mi)
    objects |= mesh_shapes(model, mi)
    for material in model.materials:
        if material.index not in surfaces.tabled:
            scene[f"mat{material.index}"] = bsdf(material, mi)
    for light in model.lights:
        scene[f"light{light.index}"] = emitter(light, mi)
    # Textured surfaces reference the materials and are referenced by the shapes.
    return scene | surfaces.dicts | objects


def rgb(color, mi):
    return mi.ScalarColor3f(*color)


# -- camera -------------------------------------------------------------------------------------
def sensor(model, options, mi):
    camera = model.camera
    return {
        "type": "perspective",
        "fov": camera.vertical_fov(options.width, options.height), "fov_axis": "y",
        "near_clip": NEAR_CLIP, "far_clip": FAR_CLIP,
        # Mitsuba's look_at: image right = view x up, image top toward up; row 0 at the top.
        "to_world": mi.ScalarTransform4f().look_at(origin=camera.eye, target=camera.lookat,
                                                   up=camera.up),
        "sampler": {"type": "independent", "sample_count": options.spp},
        "film": {"type": "hdrfilm", "width": options.width, "height": options.height,
                 "rfilter": {"type": "box"}, "pixel_format": "rgb"},
    }


# -- materials, lights --------------------------------------------------------------------------
def bsdf(material: Material, mi):
    """The ``rayphong`` of ``material``: its color and the fields that differ from the
    plugin's default (the format's, ``Material()``'s), down to the sign of a zero
    (mi.load_dict parses every property it is given, for every material)."""
    out = {"type": "rayphong", "id": f"mat{material.index}", "index": material.index,
           "color": rgb(material.color, mi)}
    for name, default in MATERIAL_DEFAULTS:
        value = float(getattr(material, name))
        if value != default or math.copysign(1.0, value) != math.copysign(1.0, default):
            out[name] = value
    return out


MATERIAL_DEFAULTS = tuple((name, float(getattr(Material(), name))) for name in Material.FIELDS[1:])


def emitter(light, mi):
    out = {"type": "raylight", "id": f"light{light.index}", "index": light.index,
           "kind": light.kind.value, "color": rgb(light.color, mi)}
    if light.position is not None:
        out["position"] = mi.ScalarPoint3f(*light.position)
    if light.direction is not None:
        out["direction"] = mi.ScalarVector3f(*light.direction)
    if light.shape is not None:
        out["shape_coefficient"] = float(light.shape)
    return out


def untextured(obj: SceneObject) -> bool:
    """Whether ``obj``'s surface is its material's alone (no texture, no checkerboard): its
    BSDF is the material's own, and its uv are not read."""
    return obj.texture is None and obj.checker is None


class Surfaces:
    """One BSDF reference per distinct (material, texture, checker) of the objects."""

    def __init__(self, options, mi):
        self.options, self.mi = options, mi
        self.ids: dict = {}
        self.dicts: dict = {}
        self.tabled: set = set()  # the materials held by the sphere set's table (no rayphong)

    def of_groups(self, groups) -> list:
        """The id of each group's surface (:class:`Groups`: one look-up per group, its
        objects share it): the material's own where the group is untextured."""
        ids = list(map("mat{}".format, map(operator.itemgetter(1), groups.keys)))
        textured = ~(groups.is_(2, None) & groups.is_(3, None))  # (not untextured())
        for g, first in zip(np.flatnonzero(textured).tolist(), groups.first[textured].tolist()):
            ids[g] = self.id(groups.objs[first])
        return ids

    def id(self, obj: SceneObject) -> str:
        """The id of the BSDF of ``obj``'s surface (made on first use)."""
        if untextured(obj):
            return f"mat{obj.material}"
        key = (obj.material, obj.texture.path if obj.texture else None, obj.checker)
        if key not in self.ids:
            surface_id = f"surface{len(self.ids)}"
            self.ids[key] = surface_id
            surface = {"type": "raytextured", "id": surface_id,
                       "material": {"type": "ref", "id": f"mat{obj.material}"}}
            if obj.texture is not None:
                surface["texture"] = {"type": "bitmap", "filename": obj.texture.path,
                                      "raw": not self.options.srgb, "wrap_mode": "repeat",
                                      "filter_type": "bilinear",
                                      "to_uv": None if self.mi is HOST else uv_to_image(self.mi)}
            if obj.checker is not None:
                surface["checker"] = {"type": "raychecker", "size": float(obj.checker)}
            self.dicts[surface_id] = surface
        return self.ids[key]


# -- the geometry on the host: what the parameter keys move ------------------------------------
class HOST:
    """The translator's host mode, in place of the ``mitsuba`` module: the dict is built by the
    same code with numpy values (no Mitsuba object), so that a key's effect on every shape is
    read from the translation itself (:func:`shape_geometry`)."""

    Float = UInt32 = TensorXf = staticmethod(np.asarray)
    ScalarColor3f = ScalarPoint3f = ScalarVector3f = staticmethod(lambda *v: tuple(v))

    @staticmethod
    def ScalarTransform4f(m=None):  # noqa: N802 (Mitsuba's name)
        return np.asarray(m, dtype=np.float64)


def shape_geometry(model: Scene, options: Options) -> dict:
    """What each shape of the translation of ``model`` is, by shape id, as the parameter keys
    see it: ``("sphere", center (3,), radius, to_world (4, 4))`` for Mitsuba's analytic spheres
    (float64; the centre is the translation of to_world, the radius the length of its first
    column), ``("mesh", positions (3 V,) float32)`` for the flat ``raytriangles`` meshes of
    ``triangle`` lines and MIT 6.837 mesh blocks (their vertex positions, as the mesh holds
    them), ``("mesh", positions, normals (3 V,) float32)`` for the tessellated objects'
    smooth meshes (under ``options.segments``, fixed, their vertices move with the objects),
    and ``("fixed", kind, numbers)`` for the shapes that no key may move (planes: their
    rings are laid out from the camera; the sphere set).

    A transform key moves every object under it on the stack: the model the key's new value
    gives (the text rewritten, parsed again) is translated again and compared shape by shape."""
    width, height = model.image_size(options.width, options.height)
    options = dataclasses.replace(options, width=width, height=height)
    out = {}
    for name, shape in (shapes(model, options, Surfaces(options, HOST), HOST)
                        | mesh_shapes(model, HOST)).items():
        if shape["type"] == "sphere":
            m = shape["to_world"]
            out[name] = ("sphere", m[:3, 3].copy(), float(np.linalg.norm(m[:3, 0])), m)
        elif shape["type"] == "raytriangles":  # (tessellations: with their vertex normals)
            out[name] = ("mesh", np.asarray(shape["positions"], np.float32)) + \
                ((np.asarray(shape["normals"], np.float32),) if "normals" in shape else ())
        else:
            out[name] = ("fixed", shape["type"], _fingerprint(shape))
    return out


def _fingerprint(shape: dict) -> tuple:
    """The numbers of a shape's dict (to tell whether a key changed it)."""
    return tuple((k, np.asarray(v).tobytes()) for k, v in sorted(shape.items())
                 if isinstance(v, (np.ndarray, float, int)))


def camera_geometry(model: Scene, options: Options):
    """(eye, lookat, up, vertical fov in degrees) of the camera, as the sensor is built."""
    camera = model.camera
    width, height = model.image_size(options.width, options.height)
    return (np.array(camera.eye, np.float64), np.array(camera.lookat, np.float64),
            np.array(camera.up, np.float64), float(camera.vertical_fov(width, height)))


# -- shapes -------------------------------------------------------------------------------------
CURVED = (ObjectKind.SPHERE, ObjectKind.CYLINDER, ObjectKind.CONE)
BOUNDING_RADIUS = {ObjectKind.SPHERE: 1.0, ObjectKind.CYLINDER: math.sqrt(1.25),
                   ObjectKind.CONE: math.sqrt(1.25)}  # of the primitive in object space


def shapes(model, options, surfaces, mi) -> dict:
    """Every object's shape: analytic spheres and planes one by one, the rest merged per
    surface (objects grouped by (kind, surface) in one pass, then built in bulk)."""
    groups = Groups(model.objects)
    out, triangles = {}, []
    kinds, ids = groups.kinds(), surfaces.of_groups(groups)
    is_curved = list(map(CURVED.__contains__, kinds))
    curved = list(compress(enumerate(ids), is_curved))  # (a scene may hold 10^5 groups)
    for g in compress(range(len(kinds)), map(operator.not_, is_curved)):
        if kinds[g] is ObjectKind.PLANE:
            ref = {"type": "ref", "id": ids[g]}
            for obj in groups.objects(g):
                out[f"plane_{obj.line}"] = plane(obj, model, mi) | {"bsdf": ref}
        else:  # triangles
            triangles.append(triangle_mesh(groups.objects(g), mi) |
                             {"bsdf": {"type": "ref", "id": ids[g]}})
    objects, member = curved_objects(groups, curved, model, options)
    names = ShapeNames()
    single = np.flatnonzero(objects.exact & ~member)
    for i, rows in zip(single.tolist(), objects.sphere_to_world(single).tolist()):
        obj = objects.objs[i]
        out[names.next("sphere", obj.line)] = {
            "type": "sphere", "to_world": mi.ScalarTransform4f(rows),
            "bsdf": {"type": "ref", "id": objects.surface_id[objects.group[i]]}}
    if member.any():
        out["spheres"] = sphere_set_shape(objects, member, model, surfaces, mi)
    out |= {f"triangles_{k}": mesh for k, mesh in enumerate(triangles)}
    tessellated = objects.tessellated(~objects.exact & ~member)
    meshes = quadric_meshes(tessellated, segment_counts(tessellated, model, options), mi)
    return out | {f"quadrics_{k}": mesh for k, mesh in enumerate(meshes)}


def tessellation_segments(model: Scene, options: Options) -> tuple:
    """The segment counts the translation of ``model`` gives its tessellated objects, as
    ``Options.segments`` takes them: ((kind, counts), ...)."""
    width, height = model.image_size(options.width, options.height)
    options = dataclasses.replace(options, width=width, height=height)
    groups, surfaces = Groups(model.objects), Surfaces(options, HOST)
    curved = [(g, surface_id) for g, (kind, surface_id) in
              enumerate(zip(groups.kinds(), surfaces.of_groups(groups))) if kind in CURVED]
    objects, member = curved_objects(groups, curved, model, options)
    counts = segment_counts(objects.tessellated(~objects.exact & ~member), model, options)
    return tuple((kind.value, tuple(c.tolist())) for kind, c in counts.items())


def curved_objects(groups, curved, model, options):
    """(The :class:`CurvedObjects` of the groups ``curved`` ([(group, surface id)]), which
    of them the sphere set holds): what :func:`shapes` and :func:`tessellation_segments`
    both classify."""
    objects = CurvedObjects(groups, curved, model)
    return objects, set_members(objects, model, options)


_KIND_CODES = {id(kind): code for code, kind in enumerate(ObjectKind)}  # (see Groups)


class Groups:
    """The objects grouped by kind and surface, ``keys[g]`` = (kind, material, texture,
    checker) in order of first use: ``group[i]`` the group of object i, ``first[g]`` its
    first object, ``order`` the objects sorted by group (in file order within one),
    ``start[g]:start[g + 1]`` a group's span of ``order``. One dict look-up per object; no
    Python list per group (a scene of 10^5 spheres with their own materials has 10^5)."""

    def __init__(self, objs):
        self.objs = objs
        grouped = self._untextured(objs)
        if grouped is None:
            keys = list(map(operator.attrgetter("kind", "material", "texture", "checker"), objs))
            index = dict(zip(dict.fromkeys(keys), count()))  # (C loops: in first use)
            self.group = np.fromiter(map(index.__getitem__, keys), np.int64, len(objs))
            self.keys = list(index)
        else:
            self.group, self.keys = grouped
        self.first = np.unique(self.group, return_index=True)[1]
        self.order = np.argsort(self.group, kind="stable")
        self.start = np.concatenate([[0], np.cumsum(np.bincount(self.group,
                                                                minlength=len(self.keys)))])

    @staticmethod
    def _untextured(objs):
        """(group, keys) as ``__init__`` makes them, where no object has a texture or a
        checkerboard (the common case, and a generated scene's): the groups are then (kind,
        material) pairs, numbered in numpy (a third of the time of the keys' tuples hashed
        twice, at 10^5 objects); None otherwise, or where a kind is not an ObjectKind or a
        material not an index (the dict's path then groups them as it would anyway)."""
        n = len(objs)
        if list(map(operator.attrgetter("texture"), objs)).count(None) != n or \
                list(map(operator.attrgetter("checker"), objs)).count(None) != n:
            return None
        kinds = list(map(operator.attrgetter("kind"), objs))
        try:  # (the kinds by identity: an enum's members are singletons)
            kind = np.fromiter(map(_KIND_CODES.__getitem__, map(id, kinds)), np.int64, n)
        except KeyError:
            return None
        materials = list(map(operator.attrgetter("material"), objs))
        # (each an index, as the parsers make it: a Python int in int64's range, not negative)
        if not all(map(operator.is_, map(type, materials), repeat(int))):
            return None
        try:
            material = np.fromiter(materials, np.int64, n)
        except OverflowError:
            return None
        if n and (material.min() < 0 or material.max() >= 1 << 32):  # (pairs fit in int64)
            return None
        pair = kind * (int(material.max()) + 1 if n else 1) + material
        _, first, inverse = np.unique(pair, return_index=True, return_inverse=True)
        number = np.empty(len(first), np.int64)  # each pair's group: in order of first use
        number[np.argsort(first, kind="stable")] = np.arange(len(first))
        firsts = np.sort(first).tolist()
        keys = list(zip(map(kinds.__getitem__, firsts), map(materials.__getitem__, firsts),
                        repeat(None), repeat(None)))
        return number[inverse.reshape(-1)], keys

    def is_(self, field: int, value) -> np.ndarray:
        """Which groups' key has ``value`` (compared by identity) as its ``field``-th item:
        (n groups,) bool, read in a C loop (a scene may hold 10^5 groups)."""
        fields = map(operator.itemgetter(field), self.keys)
        return np.fromiter(map(operator.is_, fields, repeat(value)), bool, len(self.keys))

    def kinds(self) -> list:
        """Each group's kind of object."""
        return list(map(operator.itemgetter(0), self.keys))

    def objects(self, g) -> list:
        """The objects of group ``g``, in file order."""
        return [self.objs[i] for i in self.order[self.start[g]:self.start[g + 1]].tolist()]


class ShapeNames:
    """``{kind}_{line}`` for the first object of a kind on a line, ``{kind}_{line}_{n}`` for
    the n-th after it (a MIT 6.837 line may hold several spheres)."""

    def __init__(self):
        self.seen = collections.Counter()

    def next(self, kind, line):
        n = self.seen[kind, line]
        self.seen[kind, line] += 1
        return f"{kind}_{line}" if n == 0 else f"{kind}_{line}_{n}"


class CurvedObjects:
    """The curved objects (spheres, cylinders, cones) of the scene in one set of arrays,
    group by group (``curved``: [(group, surface id)] in group order), classified all at
    once: per object its ``to_world`` (n, 4, 4) float64, its ``group`` (an index of
    ``groups``), ``material``, whether it is ``untextured`` and a ``sphere``, and whether
    it is ``exact``: a sphere under a similarity without mirroring (Mitsuba's analytic
    sphere, or the sphere set); ``objs`` the objects, ``surface_id`` by group. No Python
    work per object beyond reading its fields once: a scene has up to millions of them."""

    def __init__(self, groups: Groups, curved, model):
        self.groups = groups
        self.surface_id = dict(curved)
        # the objects of the groups of ``curved`` (in group order), as groups.order has them
        taken = np.zeros(len(groups.keys), bool)
        taken[[g for g, _ in curved]] = True
        index = groups.order[taken[groups.group[groups.order]]]
        self.objs = list(map(groups.objs.__getitem__, index.tolist()))
        self.group = groups.group[index]
        self.to_world = matrices(self.objs)
        self.material = np.fromiter(map(operator.attrgetter("material"), self.objs), np.int64,
                                    len(self.objs))
        self.sphere = groups.is_(0, ObjectKind.SPHERE)[self.group]
        self.untextured = (groups.is_(2, None) & groups.is_(3, None))[self.group]
        self.exact = self.sphere & sphere_set.is_similarity(self.to_world[:, :3, :3])

    def sphere_to_world(self, which) -> np.ndarray:
        """Mitsuba's sphere's to_world of the exact spheres ``which`` (its pole on local +z)."""
        return self.to_world[which] @ Z_TO_Y

    def tessellated(self, which) -> list:
        """[(surface id, kind, transforms (n, 4, 4), objects)] of the objects ``which`` (a
        mask), by group in group order: what :func:`quadric_meshes` takes."""
        index = np.flatnonzero(which)
        starts = np.flatnonzero(np.diff(self.group[index], prepend=-1))
        out = []
        for start, stop in zip(starts.tolist(), starts[1:].tolist() + [len(index)]):
            group = int(self.group[index[start]])
            picked = index[start:stop]
            out.append((self.surface_id[group], self.groups.keys[group][0], self.to_world[picked],
                        [self.objs[i] for i in picked.tolist()]))
        return out


def set_members(objects: CurvedObjects, model, options) -> np.ndarray:
    """Which of the curved ``objects`` are the sphere set's members (a mask): the opaque
    spheres that do not contain the eye -- the exact ones and the untextured others
    (ellipsoids) -- when there are at least ``options.sphere_set`` of them (see
    :mod:`raymitsuba.geometry.sphere_set`); none otherwise."""
    member = np.zeros(len(objects.objs), bool)
    if not options.sphere_set:
        return member
    refractivity = np.fromiter(map(operator.attrgetter("refractivity"), model.materials),
                               np.float64, len(model.materials))
    may_join = objects.sphere & (objects.exact | objects.untextured) & \
        (refractivity[objects.material] == 0)
    m = objects.to_world[may_join]
    eye = np.asarray(model.camera.eye, np.float64)
    eye_local = np.linalg.solve(m[:, :3, :3], (eye - m[:, :3, 3])[:, :, None])[:, :, 0]
    member[may_join] = np.linalg.norm(eye_local, axis=1) > 1.001
    if np.count_nonzero(member) < options.sphere_set:
        member[:] = False
    return member


def sphere_set_shape(objects: CurvedObjects, member, model, surfaces, mi) -> dict:
    """The shape of the sphere set, whose members are ``objects[member]``: Mitsuba's
    ``ellipsoids`` holding the exact spheres then the ellipsoids, each in object order, its
    BSDF a ``raysurfaceset`` giving each one's surface: a reference to a shared or textured
    surface, or a row of its table of the materials that only its untextured spheres use
    (recorded in ``surfaces.tabled``: they get no ``rayphong`` of their own). Built in bulk:
    the rows and the shared surfaces are numbered in order of first use."""
    exact, ellipsoids = np.flatnonzero(member & objects.exact), \
        np.flatnonzero(member & ~objects.exact)
    order = np.concatenate([exact, ellipsoids])
    data = sphere_set.pack(np.concatenate([objects.sphere_to_world(exact),
                                           objects.to_world[ellipsoids]]),
                           ellipsoid=np.arange(len(order)) >= len(exact))
    material, untextured_member = objects.material[order], objects.untextured[order]
    # a material is used elsewhere by a curved object outside the set, by a textured member,
    # by an object of another kind (a plane, a triangle) or by a mesh
    used_elsewhere = np.zeros(len(model.materials), bool)
    used_elsewhere[objects.material[~member]] = True
    used_elsewhere[material[~untextured_member]] = True
    used_elsewhere[[obj.material for obj in model.objects if obj.kind not in CURVED]] = True
    used_elsewhere[[mesh.material for mesh in model.meshes]] = True
    tabled = untextured_member & ~used_elsewhere[material]
    # the table's rows: its materials in order of first use
    row_materials, first = np.unique(material[tabled], return_index=True)
    row_materials = row_materials[np.argsort(first, kind="stable")]
    row_of_material = np.zeros(len(model.materials), np.int64)
    row_of_material[row_materials] = np.arange(len(row_materials))
    # the shared surfaces, in order of first use: read once per run of members of a group
    # (a group's objects share their surface)
    shared_surfaces = {}
    others = np.flatnonzero(~tabled)
    new_run = np.diff(objects.group[order[others]], prepend=-1) != 0
    index_of_run = np.array(
        [shared_surfaces.setdefault(objects.surface_id[g], len(shared_surfaces))
         for g in objects.group[order[others[new_run]]].tolist()], np.int64)
    surface_of = np.empty(len(order), np.float32)
    surface_of[others] = index_of_run[np.cumsum(new_run) - 1]
    surface_of[tabled] = row_of_material[material[tabled]] + len(shared_surfaces)
    surfaces.tabled |= set(row_materials.tolist())
    bsdf = {"type": "raysurfaceset", "surface_of": mi.TensorXf(surface_of)} | {
        f"surface_{j}": {"type": "ref", "id": surface_id}
        for surface_id, j in shared_surfaces.items()}
    if len(row_materials):
        table = sphere_set.material_table([model.materials[i] for i in row_materials.tolist()])
        bsdf |= {"materials": mi.TensorXf(table.ravel()),
                 "material_ids": mi.TensorXf(row_materials.astype(np.float32))}
    return {"type": "ellipsoids", "data": mi.TensorXf(data), "extent": sphere_set.EXTENT,
            "bsdf": bsdf}


def matrices(objs) -> np.ndarray:
    """The objects' to_world matrices, (n, 4, 4) float64 (read as one stream of floats)."""
    rows = chain.from_iterable(map(operator.attrgetter("to_world"), objs))
    return np.fromiter(chain.from_iterable(rows), np.float64, 16 * len(objs)).reshape(-1, 4, 4)


def plane(obj, model, mi) -> dict:
    m = np.array(obj.to_world, dtype=np.float64)
    eye = np.linalg.solve(m, np.array([*model.camera.eye, 1.0]))  # the eye in object space
    height = max(abs(eye[1]), 1e-3)
    return {"type": "rayplane", "to_world": mi.ScalarTransform4f(m),
            "center_x": float(eye[0]), "center_z": float(eye[2]),
            "inner": height / 4.0, "outer": height * PLANE_REACH}


# -- tessellated objects: segment counts, the budget, merged meshes ----------------------------
def wanted_segments(m, kind, model, options):
    """Segments around each object (transforms m, (n, 4, 4)) so its silhouette is within
    SILHOUETTE_ERROR_PX, clamped to [MIN_SEGMENTS, MAX_SEGMENTS] (not yet even)."""
    center = m[:, :3, 3]
    extent = BOUNDING_RADIUS[kind] * np.linalg.norm(m[:, :3, :3], 2, axis=(1, 2))  # world bounding radius
    distance = np.maximum(np.linalg.norm(center - np.array(model.camera.eye), axis=1) - extent,
                          1e-3 * extent)
    tan_half = math.tan(math.radians(model.camera.vertical_fov(options.width, options.height)) / 2.0)
    pixels = extent / distance / tan_half * options.height / 2.0
    wanted = np.ceil(math.pi * np.sqrt(np.maximum(pixels, 1.0) / (2.0 * SILHOUETTE_ERROR_PX)))
    return np.clip(wanted, MIN_SEGMENTS, MAX_SEGMENTS)


def scaled_segments(wanted, factor):
    """The counts ``wanted`` scaled by ``factor`` <= 1, at least BUDGET_MIN_SEGMENTS, even."""
    count = np.clip(np.ceil(wanted * factor), BUDGET_MIN_SEGMENTS, MAX_SEGMENTS).astype(np.int64)
    return count + count % 2


def within_budget(wanted: dict, budget: int, limit: int) -> dict:
    """Segment counts per kind ({kind: wanted counts}) for a total of at most ``budget``
    triangles: ``wanted`` itself if it fits, else every count scaled by the largest common
    factor that fits (bisection: the total only grows with the factor), down to
    BUDGET_MIN_SEGMENTS; at that floor the budget gives way up to ``limit``, past which
    the scene is refused."""
    def total(factor):
        return sum(int(tessellation.triangle_count(kind.value, scaled_segments(w, factor)).sum())
                   for kind, w in wanted.items())

    if total(1.0) <= budget:
        return {kind: scaled_segments(w, 1.0) for kind, w in wanted.items()}
    fits, over = 0.0, 1.0
    if total(0.0) > limit:
        count = sum(len(w) for w in wanted.values())
        raise GeometryTooLarge(
            f"too much geometry: the {count} curved objects (cylinders, cones, spheres under "
            f"non-uniform scales) need {total(0.0)} triangles even at {BUDGET_MIN_SEGMENTS} "
            f"segments each (about {total(0.0) * BYTES_PER_TRIANGLE / 1e9:.1f} GB), more than "
            f"the limit of {limit}")
    if total(0.0) <= budget:
        for _ in range(30):
            mid = 0.5 * (fits + over)
            fits, over = (mid, over) if total(mid) <= budget else (fits, mid)
    return {kind: scaled_segments(w, fits) for kind, w in wanted.items()}


def segment_counts(curved, model, options) -> dict:
    """{kind: the segments around each tessellated object of that kind, in the order of
    ``curved`` ([(surface id, kind, transforms (n, 4, 4), objects)])}: ``options.segments``
    where given and they are as many as the objects (else other objects are tessellated: a
    key changed how one is drawn, which the keys' owner finds from the shapes), else as the
    silhouette error asks within the budget."""
    needed = collections.Counter()
    for _, kind, m, _ in curved:
        needed[kind] += len(m)
    fixed = {ObjectKind(kind): np.asarray(counts, np.int64)
             for kind, counts in options.segments or ()}
    if options.segments is not None and fixed.keys() == needed.keys() and \
            all(len(fixed[kind]) == n for kind, n in needed.items()):
        return fixed
    wanted = {}
    for _, kind, m, _ in curved:
        wanted.setdefault(kind, []).append(wanted_segments(m, kind, model, options))
    wanted = {kind: np.concatenate(w) for kind, w in wanted.items()}
    return within_budget(wanted, options.tessellation_budget, options.tessellation_limit)


def quadric_meshes(curved, counts, mi) -> list:
    """One smooth ``raytriangles`` mesh per surface holding every tessellated object of it.
    ``curved``: [(surface id, kind, transforms (n, 4, 4), objects)]; ``counts``: their
    segments, by kind (:func:`segment_counts`)."""
    taken = {kind: 0 for kind in counts}
    batches = {}  # surface id -> [(template, transforms)]
    for surface_id, kind, m, _ in curved:
        segments = counts[kind][taken[kind]:taken[kind] + len(m)]
        taken[kind] += len(m)
        for count in np.unique(segments):
            batches.setdefault(surface_id, []).append(
                (tessellation.template(kind.value, int(count)), m[segments == count]))
    return [world_mesh(tessellation.merged(batch), mi) | {"bsdf": {"type": "ref", "id": surface_id}}
            for surface_id, batch in batches.items()]


def world_mesh(mesh, mi) -> dict:
    """A ``raytriangles`` dict of a world-space float32 tessellation (smooth: with vertex normals)."""
    return {"type": "raytriangles", "positions": mi.Float(mesh.positions.ravel()),
            "normals": mi.Float(mesh.normals.ravel()), "texcoords": mi.Float(mesh.texcoords.ravel()),
            "faces": mi.UInt32(mesh.faces.ravel()),
            "neighbours": mi.UInt32(mesh.neighbours.ravel().astype(np.uint32))}


def uv_to_image(mi):
    """Texture coordinates to Mitsuba's bitmap lookup: v = 0 is the image's *bottom* row
    (as in OpenGL and OBJ; Mitsuba's bitmap has v = 0 at the top), u = 0 its left column."""
    return mi.ScalarTransform3f().translate([0.0, 1.0]) @ mi.ScalarTransform3f().scale([1.0, -1.0])


TRIANGLE_UV = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def triangle_mesh(objs, mi) -> dict:
    """World-space corners of triangles, wound so the format's front side is preserved
    (built per transform in bulk: corners (n, 3, 3) mapped by one matrix)."""
    transforms = list(map(operator.attrgetter("to_world"), objs))
    vertices = list(map(operator.attrgetter("vertices"), objs))
    if transforms.count(transforms[0]) == len(transforms):  # the common case: one transform
        by_transform = {transforms[0]: vertices}
    else:
        by_transform = {}
        for to_world, corners in zip(transforms, vertices):
            by_transform.setdefault(to_world, []).append(corners)
    positions, texcoords = [], []
    for to_world, vertices in by_transform.items():
        m = np.array(to_world, dtype=np.float64)
        corners = np.fromiter(chain.from_iterable(chain.from_iterable(vertices)), np.float64,
                              count=9 * len(vertices)).reshape(-1, 3, 3)
        corners = corners @ m[:3, :3].T + m[:3, 3]
        # Mirroring maps the front side's normal by the inverse transpose, so the world
        # winding must be reversed to keep it: the corners (0, 2, 1).
        order = [0, 2, 1] if np.linalg.det(m[:3, :3]) < 0 else [0, 1, 2]
        positions.append(corners[:, order].astype(np.float32))
        texcoords.append(np.broadcast_to(TRIANGLE_UV[order].astype(np.float32), (len(corners), 3, 2)))
    return {"type": "raytriangles", "positions": mi.Float(np.concatenate(positions).ravel()),
            "texcoords": mi.Float(np.concatenate(texcoords).ravel())}


def mesh_shapes(model: Scene, mi) -> dict:
    """A ``raytriangles`` shape per MIT 6.837 mesh (world-space corners, faces as written)."""
    shapes = {}
    for k, mesh in enumerate(model.meshes):
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        corners = vertices[np.asarray(mesh.faces, dtype=np.int64)]  # (faces, 3, 3)
        texcoords = np.broadcast_to(TRIANGLE_UV, (len(mesh.faces), 3, 2))
        shapes[f"mesh{k}"] = {
            "type": "raytriangles",
            "positions": mi.Float(corners.astype(np.float32).ravel()),
            "texcoords": mi.Float(texcoords.astype(np.float32).ravel()),
            "bsdf": {"type": "ref", "id": f"mat{mesh.material}"}}
    return shapes
