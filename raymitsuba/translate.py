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
* shapes ``{kind}_{line}`` (``{kind}_{line}_{n}`` for the n-th object when a MIT 6.837
  line holds several; ``triangles_{k}`` for merged triangles, ``mesh{k}``) and
  textured surfaces ``surface{k}`` (``raytextured`` wrapping ``mat{i}``).

Geometry choices (see the shape plugins for their tessellations):

* sphere: Mitsuba's analytic ``sphere`` when the transform is a similarity
  without mirroring (exact), else a ``rayellipsoid`` mesh;
* cylinder, cone: ``raycylinder`` / ``raycone`` meshes;
* plane: ``rayplane``, rings centred under the camera out past the horizon;
* triangles: one ``raytriangles`` mesh per surface (material and texture);
* MIT 6.837 mesh blocks: one ``raytriangles`` mesh ``mesh{k}`` per mesh of the model,
  its corners gathered in bulk with numpy (:func:`mesh_shapes`).

The camera's vertical field of view for the image's aspect comes from
``Camera.vertical_fov`` (the MIT 6.837 fov is horizontal).

Tessellation density follows the object's projected size: a curved object whose
bounding sphere spans r pixels gets m = pi sqrt(r / (2 e)) segments around, so its
polygonal silhouette is within e = 0.05 pixel of the true one (clamped to
[MIN_SEGMENTS, MAX_SEGMENTS]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from raymitsuba.model import Material, ObjectKind, Scene, SceneObject

SILHOUETTE_ERROR_PX = 0.05
MIN_SEGMENTS, MAX_SEGMENTS = 48, 768
PLANE_REACH = 1e6  # the plane mesh reaches this many camera heights away
NEAR_CLIP, FAR_CLIP = 1e-4, 1e12

# Mitsuba's analytic sphere has its pole on local +z; the format's sphere (and
# its texture coordinates) on +y. This rotation maps local z to object y.
Z_TO_Y = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=np.float64)


@dataclass(frozen=True)
class Options:
    width: int = 512
    height: int = 512
    spp: int = 1
    max_depth: int = 5
    srgb: bool = False  # decode 8-bit textures from sRGB (and encode 8-bit output)


def translate(model: Scene, options: Options | None = None, **kwargs) -> dict:
    """The Mitsuba scene dict for ``model`` (options as an Options or keywords)."""
    import mitsuba as mi  # the caller has set the variant (raymitsuba.backend)

    options = options or Options(**kwargs)
    scene = {"type": "scene",
             "integrator": {"type": "raywhitted", "max_depth": options.max_depth},
             "sensor": sensor(model, options, mi),
             "background": {"type": "raybackground", "color": rgb(model.background, mi)}}
    for material in model.materials:
        scene[f"mat{material.index}"] = bsdf(material, mi)
    for light in model.lights:
        scene[f"light{light.index}"] = emitter(light, mi)
    surfaces = Surfaces(options, mi)
    shapes, triangles = {}, {}
    for i, obj in enumerate(model.objects):
        ref = surfaces.ref(obj)
        if obj.kind is ObjectKind.TRIANGLE:
            triangles.setdefault(ref["id"], []).append(obj)
        else:
            name = f"{obj.kind.value}_{obj.line}"
            name = f"{name}_{i}" if name in shapes else name  # MIT 6.837: several on a line
            shapes[name] = shape(obj, model, options, mi) | {"bsdf": ref}
    for k, (surface_id, objs) in enumerate(triangles.items()):
        shapes[f"triangles_{k}"] = triangle_mesh(objs, mi) | {"bsdf": {"type": "ref", "id": surface_id}}
    shapes |= mesh_shapes(model, mi)
    # Textured surfaces reference the materials and are referenced by the shapes.
    return scene | surfaces.dicts | shapes


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
    out = {"type": "rayphong", "id": f"mat{material.index}", "color": rgb(material.color, mi)}
    for name in Material.FIELDS[1:]:
        out[name] = float(getattr(material, name))
    return out


def emitter(light, mi):
    out = {"type": "raylight", "kind": light.kind.value, "color": rgb(light.color, mi)}
    if light.position is not None:
        out["position"] = mi.ScalarPoint3f(*light.position)
    if light.direction is not None:
        out["direction"] = mi.ScalarVector3f(*light.direction)
    if light.shape is not None:
        out["shape_coefficient"] = float(light.shape)
    return out


class Surfaces:
    """One BSDF reference per distinct (material, texture, checker) of the objects."""

    def __init__(self, options, mi):
        self.options, self.mi = options, mi
        self.ids: dict = {}
        self.dicts: dict = {}

    def ref(self, obj: SceneObject) -> dict:
        if obj.texture is None and obj.checker is None:
            return {"type": "ref", "id": f"mat{obj.material}"}
        key = (obj.material, obj.texture.path if obj.texture else None, obj.checker)
        if key not in self.ids:
            surface_id = f"surface{len(self.ids)}"
            self.ids[key] = surface_id
            surface = {"type": "raytextured", "id": surface_id,
                       "material": {"type": "ref", "id": f"mat{obj.material}"}}
            if obj.texture is not None:
                surface["texture"] = {"type": "bitmap", "filename": obj.texture.path,
                                      "raw": not self.options.srgb, "wrap_mode": "repeat",
                                      "filter_type": "bilinear", "to_uv": uv_to_image(self.mi)}
            if obj.checker is not None:
                surface["checker"] = {"type": "raychecker", "size": float(obj.checker)}
            self.dicts[surface_id] = surface
        return {"type": "ref", "id": self.ids[key]}


# -- shapes -------------------------------------------------------------------------------------
def matrix(obj):
    return np.array(obj.to_world, dtype=np.float64)


def is_similarity(linear):
    """Rotation times a positive uniform scale (no mirroring, no shear)."""
    gram = linear.T @ linear
    scale2 = np.trace(gram) / 3.0
    return np.linalg.det(linear) > 0 and np.allclose(gram, scale2 * np.eye(3), rtol=0, atol=1e-9 * scale2)


def segments(obj, model, options, radius):
    """Segments around a curved object so its silhouette is within SILHOUETTE_ERROR_PX."""
    m = matrix(obj)
    center = m[:3, 3]
    extent = radius * np.linalg.norm(m[:3, :3], 2)  # world bounding-sphere radius
    distance = max(np.linalg.norm(center - np.array(model.camera.eye)) - extent, 1e-3 * extent)
    tan_half = math.tan(math.radians(model.camera.vertical_fov(options.width, options.height)) / 2.0)
    pixels = extent / distance / tan_half * options.height / 2.0
    wanted = math.pi * math.sqrt(max(pixels, 1.0) / (2.0 * SILHOUETTE_ERROR_PX))
    count = int(min(max(math.ceil(wanted), MIN_SEGMENTS), MAX_SEGMENTS))
    return count + count % 2


def shape(obj: SceneObject, model, options, mi) -> dict:
    m = matrix(obj)
    if obj.kind is ObjectKind.SPHERE:
        if is_similarity(m[:3, :3]):
            return {"type": "sphere", "to_world": mi.ScalarTransform4f(m @ Z_TO_Y)}
        return {"type": "rayellipsoid", "to_world": mi.ScalarTransform4f(m),
                "segments": segments(obj, model, options, 1.0)}
    if obj.kind in (ObjectKind.CYLINDER, ObjectKind.CONE):
        return {"type": "ray" + obj.kind.value, "to_world": mi.ScalarTransform4f(m),
                "segments": segments(obj, model, options, math.sqrt(1.25))}
    if obj.kind is ObjectKind.PLANE:
        eye = np.linalg.solve(m, np.array([*model.camera.eye, 1.0]))  # the eye in object space
        height = max(abs(eye[1]), 1e-3)
        return {"type": "rayplane", "to_world": mi.ScalarTransform4f(m),
                "center_x": float(eye[0]), "center_z": float(eye[2]),
                "inner": height / 4.0, "outer": height * PLANE_REACH}
    raise ValueError(f"no shape for {obj.kind}")


def uv_to_image(mi):
    """Texture coordinates to Mitsuba's bitmap lookup: v = 0 is the image's *bottom* row
    (as in OpenGL and OBJ; Mitsuba's bitmap has v = 0 at the top), u = 0 its left column."""
    return mi.ScalarTransform3f().translate([0.0, 1.0]) @ mi.ScalarTransform3f().scale([1.0, -1.0])


TRIANGLE_UV = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])


def triangle_mesh(objs, mi) -> dict:
    """World-space corners of triangles, wound so the format's front side is preserved."""
    positions, texcoords = [], []
    for obj in objs:
        m = matrix(obj)
        corners = np.array(obj.vertices, dtype=np.float64) @ m[:3, :3].T + m[:3, 3]
        order = [0, 2, 1] if np.linalg.det(m[:3, :3]) < 0 else [0, 1, 2]
        positions.append(corners[order])
        texcoords.append(TRIANGLE_UV[order])
    positions = np.concatenate(positions).astype(np.float32)
    texcoords = np.concatenate(texcoords).astype(np.float32)
    return {"type": "raytriangles", "positions": mi.Float(positions.ravel()),
            "texcoords": mi.Float(texcoords.ravel())}


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
