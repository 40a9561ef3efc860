"""A tiny, independent, pure-numpy Whitted ray tracer for the test suite.

It implements the format (``docs/format.md``) for a subset of it -- spheres, horizontal planes (optionally checkered), ambient,
point and directional lights -- in float64, sharing no code with the renderer. The
renderer's image of the same scene must agree with it (see test_whitted.py).

For whole scenes (``scenes/``, read by :func:`from_model` from the parser's model: the
transforms' composition is the parser's, everything after it -- camera, intersection,
shading, the ray tree -- is this file's) it also traces spheres under any affine
transform (exact ellipsoids), planes under any transform (checkers in object space) and
flat triangles (``triangle`` lines and MIT 6.837 meshes). ``render(..., bugs=...)`` makes
the mistakes students make: ``fov_horizontal`` (the fov taken as horizontal),
``directional_reversed`` (a directional light's direction taken as pointing to the
light), ``no_shadows`` (no shadow rays).

Besides the image it returns, per pixel, whether the pixel is *fragile*: some ray of
the pixel's ray tree (with a weight that matters) passes so close to a discontinuity
-- a sphere's silhouette, a checker square's edge, the onset of total internal
reflection, the edge of a shadow, or the plane near the horizon -- that a float32
renderer may legitimately decide it the other way. Those are the only pixels where
the two tracers may disagree.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

# Secondary and shadow rays start off the surface, by RAY_EPSILON (1 + max|p_i|) along the
# geometric normal toward the side they leave to, exactly as Mitsuba's spawn_ray does
# (math::RayEpsilon = 1500 * 2^-24 in single precision). Without it the two tracers would
# differ by ~1e-4 at secondary hits on curved surfaces: a start point moved by ~2e-4 moves
# the next hit point, hence its normal, by about as much.
RAY_EPSILON = 1500.0 * 2.0 ** -24
T_MIN = 0.0
# Relative closeness to a discontinuity that makes a ray fragile (float32 renderer:
# hit points are accurate to ~1e-6 relative, offsets are ~1e-4; 1e-3 leaves margin).
FRAGILE = 1e-3
# Plane hits farther than this (in units of the scene) are near the horizon.
FAR = 1e4
# Rays with a smaller weight cannot change a pixel by more than the test's tolerance.
NEGLIGIBLE = 1e-6


@dataclass
class Material:
    color: tuple = (1.0, 1.0, 1.0)
    ka: float = 1.0
    kd: float = 1.0
    ks: float = 0.0
    n: float = 1.0
    kr: float = 0.0
    kt: float = 0.0
    eta: float = 1.0


@dataclass
class Sphere:
    center: tuple
    radius: float
    material: Material


@dataclass
class Plane:
    """The plane y = height, normal +y; object space is world space shifted by ``offset``."""

    height: float
    material: Material
    checker: float | None = None
    offset: tuple = (0.0, 0.0)  # object (x, z) = world (x, z) - offset


@dataclass
class Light:
    kind: str  # ambient | point | directional
    color: tuple
    vector: tuple | None = None  # position (point) or direction of travel (directional)


@dataclass
class Scene:
    eye: tuple = (0.0, 0.0, 5.0)
    lookat: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 45.0
    background: tuple = (0.0, 0.0, 0.0)
    objects: list = field(default_factory=list)
    lights: list = field(default_factory=list)


def _affine(to_world):
    m = np.asarray(to_world, float)
    linear = m[:3, :3]
    return linear, m[:3, 3], np.linalg.inv(linear)


class Ellipsoid:
    """The unit sphere under the affine ``to_world`` (4 x 4), traced exactly."""

    def __init__(self, to_world, material):
        self.material = material
        self.linear, self.shift, self.inverse = _affine(to_world)

    def _local(self, o, d):
        return (o - self.shift) @ self.inverse.T, d @ self.inverse.T

    def _roots(self, o, d):
        lo, ld = self._local(o, d)
        a = np.sum(ld * ld, axis=1)
        b = np.sum(lo * ld, axis=1)
        c = np.sum(lo * lo, axis=1) - 1.0
        disc = b * b - a * c
        root = np.sqrt(np.where(disc >= 0, disc, np.nan))
        closest = np.sqrt(np.maximum(c + 1.0 - b * b / a, 0.0))  # object-space miss distance
        return (-b - root) / a, (-b + root) / a, np.abs(closest - 1.0), -b / a

    def hit(self, o, d):
        t0, t1, graze, tangent = self._roots(o, d)
        t = np.where(t0 > T_MIN, t0, np.where(t1 > T_MIN, t1, np.inf))
        return t, [(tangent, (graze < FRAGILE) & (tangent > T_MIN))]

    def crossings(self, p, wi, dist):
        t0, t1, graze, _ = self._roots(p, wi)
        count = ((t0 > T_MIN) & (t0 < dist)).astype(int) + ((t1 > T_MIN) & (t1 < dist))
        return count, (graze < FRAGILE) & (t1 > T_MIN) & (t0 < dist)

    def surface(self, p, o, d):
        local = (p - self.shift) @ self.inverse.T
        normal = _normalize(local @ self.inverse)  # A^-T applied to the object-space normal
        return normal, np.tile(np.asarray(self.material.color, float), (len(p), 1)), \
            np.zeros(len(p), bool)


class AnyPlane:
    """The plane y = 0 (front +y) under ``to_world``; checkers of side ``checker`` in object
    space (x, z)."""

    def __init__(self, to_world, material, checker=None):
        self.material, self.checker = material, checker
        self.linear, self.shift, self.inverse = _affine(to_world)
        self.normal = _normalize(self.inverse.T @ np.array([0.0, 1.0, 0.0]))

    def _t(self, o, d):
        lo, ld = (o - self.shift) @ self.inverse.T, d @ self.inverse.T
        with np.errstate(divide="ignore", invalid="ignore"):
            return -lo[:, 1] / ld[:, 1]

    def hit(self, o, d):
        t = self._t(o, d)
        t = np.where(t > T_MIN, t, np.inf)
        return t, [(t, np.isfinite(t) & (t > FAR))]

    def crossings(self, p, wi, dist):
        t = self._t(p, wi)
        crossed = (t > T_MIN) & (t < dist)
        return crossed.astype(int), crossed & (t > FAR)

    def surface(self, p, o, d):
        color = np.tile(np.asarray(self.material.color, float), (len(p), 1))
        fragile = np.zeros(len(p), bool)
        if self.checker is not None:
            local = (p - self.shift) @ self.inverse.T
            x, z = local[:, 0] / self.checker, local[:, 2] / self.checker
            color = color * ((np.floor(x) + np.floor(z)) % 2 == 0)[:, None]
            edge = np.minimum(np.abs(x - np.round(x)), np.abs(z - np.round(z)))
            fragile = edge * self.checker < FRAGILE * (1.0 + np.linalg.norm(p, axis=1))
        return np.tile(self.normal, (len(p), 1)), color, fragile


class Triangles:
    """Flat triangles (corners (n, 3, 3), world space; front (p1 - p0) x (p2 - p0)) of one
    material, intersected all at once (Moller-Trumbore), rays in blocks."""

    BLOCK = 1 << 20  # rays x triangles per block

    def __init__(self, corners, material):
        self.material = material
        c = np.asarray(corners, float).reshape(-1, 3, 3)
        self.p0, self.e1, self.e2 = c[:, 0], c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]
        self.normals = _normalize(np.cross(self.e1, self.e2))

    def _all(self, o, d):
        """(t, u, v) of every ray against every triangle: (rays, triangles) each."""
        pv = np.cross(d[:, None, :], self.e2[None])
        det = np.sum(self.e1[None] * pv, axis=2)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = o[:, None, :] - self.p0[None]
            u = np.sum(tv * pv, axis=2) * inv
            qv = np.cross(tv, self.e1[None])
            v = np.sum(d[:, None, :] * qv, axis=2) * inv
            t = np.sum(self.e2[None] * qv, axis=2) * inv
        return t, u, v

    def _blocks(self, n):
        step = max(1, self.BLOCK // len(self.p0))
        return [slice(i, min(n, i + step)) for i in range(0, n, step)]

    @staticmethod
    def _inside(u, v, margin=0.0):
        return (u >= -margin) & (v >= -margin) & (u + v <= 1.0 + margin)

    def _nearest(self, o, d):
        t_best = np.full(len(o), np.inf)
        prim = np.full(len(o), -1)
        near = np.full(len(o), np.inf)  # nearest t of a triangle the ray passes near an edge of
        for b in self._blocks(len(o)):
            t, u, v = self._all(o[b], d[b])
            ok = np.isfinite(t) & (t > T_MIN)
            tt = np.where(ok & self._inside(u, v), t, np.inf)
            prim[b] = np.where(np.isfinite(tt.min(axis=1)), tt.argmin(axis=1), -1)
            t_best[b] = tt.min(axis=1)
            edge = ok & self._inside(u, v, FRAGILE) & ~self._inside(u, v, -FRAGILE)
            near[b] = np.where(edge, t, np.inf).min(axis=1)
        return t_best, prim, near

    def hit(self, o, d):
        t, _, near = self._nearest(o, d)
        return t, [(near, np.isfinite(near))]

    def crossings(self, p, wi, dist):
        count = np.zeros(len(p), int)
        fragile = np.zeros(len(p), bool)
        for b in self._blocks(len(p)):
            t, u, v = self._all(p[b], wi[b])
            ok = np.isfinite(t) & (t > T_MIN) & (t < dist[b][:, None])
            count[b] = (ok & self._inside(u, v)).sum(axis=1)
            fragile[b] = (ok & self._inside(u, v, FRAGILE) & ~self._inside(u, v, -FRAGILE)).any(1)
        return count, fragile

    def surface(self, p, o, d):
        _, prim, _ = self._nearest(o, d)
        return self.normals[np.maximum(prim, 0)], \
            np.tile(np.asarray(self.material.color, float), (len(p), 1)), np.zeros(len(p), bool)


def from_model(model, width, height):
    """The scene of a parsed .RAY ``model`` (spheres, planes, triangles and meshes; ambient,
    point and directional lights; no textures) for a width x height image."""
    materials = [Material(m.color, m.ambient_mix, m.diffuse_mix, m.specular_mix, m.phong_coeff,
                          m.reflectivity, m.refractivity, m.ior) for m in model.materials]
    objects, triangles = [], {}
    for obj in model.objects:
        kind = obj.kind.value
        if obj.texture is not None or kind in ("cylinder", "cone"):
            what = "a textured " + kind if obj.texture is not None else "a " + kind
            raise NotImplementedError(f"line {obj.line}: {what}")
        m = np.asarray(obj.to_world, float)
        if kind == "sphere":
            objects.append(Ellipsoid(m, materials[obj.material]))
        elif kind == "plane":
            objects.append(AnyPlane(m, materials[obj.material], obj.checker))
        else:
            corners = np.c_[np.asarray(obj.vertices, float), np.ones(3)] @ m.T
            triangles.setdefault(obj.material, []).append(corners[:, :3])
    for mesh in model.meshes:
        vertices = np.asarray(mesh.vertices, float)
        triangles.setdefault(mesh.material, []).extend(vertices[np.asarray(mesh.faces)])
    objects += [Triangles(np.array(c), materials[k]) for k, c in triangles.items()]
    lights = []
    for light in model.lights:
        kind = light.kind.value
        if kind == "spotlight":
            raise NotImplementedError(f"line {light.line}: spotlight")
        vector = light.position if kind == "point" else light.direction
        lights.append(Light(kind, tuple(light.color), vector))
    cam = model.camera
    return Scene(tuple(cam.eye), tuple(cam.lookat), tuple(cam.up),
                 cam.vertical_fov(width, height), tuple(model.background), objects, lights)


def offset(p, normal, direction):
    """The origin of a ray leaving p (on a surface with this geometric normal) along direction."""
    mag = (1.0 + np.max(np.abs(p), axis=1)) * RAY_EPSILON
    side = np.where(np.sum(normal * direction, axis=1) >= 0, 1.0, -1.0)
    return p + (side * mag)[:, None] * normal


def _normalize(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def primary_rays(scene, width, height, bugs=()):
    """Pixel-centre rays, row 0 at the top, right = normalize(view x up), vertical fov."""
    forward = _normalize(np.subtract(scene.lookat, scene.eye).astype(float))
    right = _normalize(np.cross(forward, scene.up))
    top = np.cross(right, forward)
    tan_half = math.tan(math.radians(scene.fov) / 2.0)
    if "fov_horizontal" in bugs:
        tan_half *= height / width
    rows, cols = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    sx = (2.0 * (cols.ravel() + 0.5) / width - 1.0) * tan_half * width / height
    sy = (1.0 - 2.0 * (rows.ravel() + 0.5) / height) * tan_half
    d = _normalize(forward + sx[:, None] * right + sy[:, None] * top)
    o = np.tile(np.asarray(scene.eye, float), (len(d), 1))
    return o, d


def _sphere_roots(obj, o, d):
    """Both roots (t0 <= t1; nan when missed) and the ray's relative miss distance."""
    oc = o - np.asarray(obj.center, float)
    b = np.sum(oc * d, axis=1)
    c = np.sum(oc * oc, axis=1) - obj.radius ** 2
    disc = b * b - c
    root = np.sqrt(np.where(disc >= 0, disc, np.nan))
    # |distance of the line from the centre - radius| / radius: 0 on the silhouette
    closest = np.sqrt(np.maximum(c + obj.radius ** 2 - b * b, 0.0))
    graze = np.abs(closest - obj.radius) / obj.radius
    return -b - root, -b + root, graze


def _plane_t(obj, o, d):
    with np.errstate(divide="ignore", invalid="ignore"):
        return (obj.height - o[:, 1]) / d[:, 1]


def intersect(scene, o, d):
    """Nearest hit: (t, object index or -1, fragile)."""
    n = len(o)
    best_t = np.full(n, np.inf)
    best = np.full(n, -1)
    edges = []  # (distance along the ray of a near-discontinuity, its mask)
    for k, obj in enumerate(scene.objects):
        if hasattr(obj, "hit"):
            t, more = obj.hit(o, d)
            edges += more
        elif isinstance(obj, Sphere):
            t0, t1, graze = _sphere_roots(obj, o, d)
            t = np.where(t0 > T_MIN, t0, np.where(t1 > T_MIN, t1, np.inf))
            # a ray that grazes the sphere, hitting or just missing it
            tangent = -np.sum((o - np.asarray(obj.center, float)) * d, axis=1)
            edges.append((tangent - obj.radius, (graze < FRAGILE) & (tangent > T_MIN)))
        else:
            t = _plane_t(obj, o, d)
            t = np.where(t > T_MIN, t, np.inf)
            edges.append((t, np.isfinite(t) & (t > FAR)))
        closer = t < best_t
        best_t = np.where(closer, t, best_t)
        best = np.where(closer, k, best)
    fragile = np.zeros(n, bool)
    for where, mask in edges:
        fragile |= mask & (where <= best_t * (1 + FRAGILE) + FRAGILE)
    return best_t, best, fragile


def _transmittance(scene, p, wi, dist):
    """Product of kt of the surfaces crossed from p toward the light; fragile at shadow edges."""
    trans = np.ones(len(p))
    fragile = np.zeros(len(p), bool)
    for obj in scene.objects:
        kt = obj.material.kt
        if hasattr(obj, "crossings"):
            count, edge = obj.crossings(p, wi, dist)
            trans *= np.power(kt, count)
            fragile |= edge
        elif isinstance(obj, Sphere):
            t0, t1, graze = _sphere_roots(obj, p, wi)
            crossings = ((t0 > T_MIN) & (t0 < dist)).astype(int) + ((t1 > T_MIN) & (t1 < dist))
            trans *= np.where(crossings == 2, kt * kt, np.where(crossings == 1, kt, 1.0))
            fragile |= (graze < FRAGILE) & (t1 > T_MIN) & (t0 < dist)
        else:
            t = _plane_t(obj, p, wi)
            crossed = (t > T_MIN) & (t < dist)
            trans *= np.where(crossed, kt, 1.0)
            fragile |= crossed & (t > FAR)
    return trans, fragile


def _surface(scene, obj, p, o=None, d=None):
    """(outward/front unit normal, base color C) at points p of obj (hit by rays o + t d);
    fragile on checker edges."""
    if hasattr(obj, "surface"):
        return obj.surface(p, o, d)
    m = obj.material
    color = np.tile(np.asarray(m.color, float), (len(p), 1))
    fragile = np.zeros(len(p), bool)
    if isinstance(obj, Sphere):
        normal = (p - np.asarray(obj.center, float)) / obj.radius
        return normal, color, fragile
    normal = np.tile([0.0, 1.0, 0.0], (len(p), 1))
    if obj.checker is not None:
        s = obj.checker
        x, z = p[:, 0] - obj.offset[0], p[:, 2] - obj.offset[1]
        parity = (np.floor(x / s) + np.floor(z / s)) % 2
        color = color * (parity == 0)[:, None]
        edge = np.minimum(np.abs(x / s - np.round(x / s)), np.abs(z / s - np.round(z / s)))
        fragile |= edge * s < FRAGILE * (1.0 + np.linalg.norm(p, axis=1))
    return normal, color, fragile


def shade(scene, obj, p, normal, n, v, color, bugs=()):
    """The contract's L_local at points p (n facing v); fragile where a shadow edge is near."""
    m = obj.material
    ambient = sum((np.asarray(l.color, float) for l in scene.lights if l.kind == "ambient"),
                  np.zeros(3))
    out = ambient * m.ka * color
    fragile = np.zeros(len(p), bool)
    for light in scene.lights:
        if light.kind == "ambient":
            continue
        if light.kind == "directional":
            toward = -1.0 if "directional_reversed" not in bugs else 1.0
            wi = np.tile(toward * _normalize(np.asarray(light.vector, float)), (len(p), 1))
            dist = np.full(len(p), np.inf)
        else:
            to_light = np.asarray(light.vector, float) - p
            dist = np.linalg.norm(to_light, axis=1)
            wi = to_light / dist[:, None]
        n_dot_l = np.sum(n * wi, axis=1)
        r = 2.0 * n_dot_l[:, None] * n - wi
        r_dot_v = np.sum(r * v, axis=1)
        spec = np.where(r_dot_v > 0, np.power(np.maximum(r_dot_v, 0.0), m.n), 0.0)
        value = m.kd * color * n_dot_l[:, None] + m.ks * spec[:, None]
        origin = offset(p, normal, wi)
        trans, shadow_edge = _transmittance(scene, origin, wi, dist - np.linalg.norm(origin - p, axis=1))
        if "no_shadows" in bugs:
            trans, shadow_edge = np.ones(len(p)), np.zeros(len(p), bool)
        lit = n_dot_l > 0
        out = out + np.where(lit[:, None], np.asarray(light.color, float) * trans[:, None] * value, 0.0)
        fragile |= lit & shadow_edge
    return out, fragile


def render(scene, width, height, max_depth=5, bugs=()):
    """(image (H, W, 3) float64, fragile (H, W) bool); ``bugs``: see the module docstring."""
    o, d = primary_rays(scene, width, height, bugs)
    pixel = np.arange(width * height)
    weight = np.ones((len(o), 1))
    image = np.zeros((width * height, 3))
    fragile = np.zeros(width * height, bool)
    background = np.asarray(scene.background, float)
    for depth in range(max_depth + 1):
        if len(o) == 0:
            break
        t, hit, ray_fragile = intersect(scene, o, d)
        miss = hit < 0
        np.add.at(image, pixel[miss], weight[miss] * background)
        matters = weight[:, 0] > NEGLIGIBLE
        np.logical_or.at(fragile, pixel, ray_fragile & matters)
        children = ([], [], [], [])  # origins, directions, pixels, weights
        for k, obj in enumerate(scene.objects):
            sel = hit == k
            if not sel.any():
                continue
            m = obj.material
            oo, dd, px, w = o[sel], d[sel], pixel[sel], weight[sel]
            p = oo + t[sel][:, None] * dd
            normal, color, surface_fragile = _surface(scene, obj, p, oo, dd)
            v = -dd
            entering = np.sum(normal * dd, axis=1) < 0
            n = np.where(entering[:, None], normal, -normal)  # facing v
            local, shadow_fragile = shade(scene, obj, p, normal, n, v, color, bugs)
            np.add.at(image, px, w * local)
            np.logical_or.at(fragile, px, (surface_fragile | shadow_fragile) & (w[:, 0] > NEGLIGIBLE))
            if depth == max_depth or (m.kr == 0 and m.kt == 0):
                continue
            cos_i = np.sum(n * v, axis=1)
            ratio = np.where(entering, 1.0 / m.eta, m.eta)
            sin2_t = ratio ** 2 * (1.0 - cos_i ** 2)
            tir = sin2_t >= 1.0
            np.logical_or.at(fragile, px, (np.abs(sin2_t - 1.0) < FRAGILE) & (m.kt * w[:, 0] > NEGLIGIBLE))
            cos_t = np.sqrt(np.maximum(1.0 - sin2_t, 0.0))
            refracted = -ratio[:, None] * v + (ratio * cos_i - cos_t)[:, None] * n
            reflected = 2.0 * cos_i[:, None] * n - v
            weight_r = m.kr + np.where(tir, m.kt, 0.0)
            weight_t = np.where(tir, 0.0, m.kt)
            for direction, wk in ((reflected, weight_r), (refracted, weight_t)):
                keep = wk > 0
                if keep.any():
                    direction = _normalize(direction[keep])
                    children[0].append(offset(p[keep], normal[keep], direction))
                    children[1].append(direction)
                    children[2].append(px[keep])
                    children[3].append(w[keep] * wk[keep][:, None])
        if not children[0]:
            break
        o, d, pixel, weight = (np.concatenate(c) for c in children)
    return image.reshape(height, width, 3), fragile.reshape(height, width)
