"""Random scenes for the edges' randomized check (benchmarks/random_edges.py and
tests/plugins/whitted/boundary/test_random_scenes.py): a scene generated from a seed, with
one key of each kind that applies (:data:`KINDS`) along a random direction, and a case's
comparison of AD against the pixel-integrated finite difference (:func:`compare`).

:func:`generate`: both dialects (COMP 575 seeds even, MIT 6.837 seeds odd) -- spheres,
boxes and single triangles, MIT meshes, ellipsoids (quadrics), cones, cylinders, a floor
plane (checkered or a mirror), glass and mirror materials, point / directional / spot
lights, a random camera looking at the objects. Nobody tunes these scenes.

:func:`compare`: the reference is the central difference of the image on the k_FD x k_FD
lattice (spp = k_FD^2) with the step h / 2, h moving the nearest edges by about EDGE_PX
pixel (:func:`step`), validated against the same at h, and that against k_FD / 2 at h (the
FD's uncertainty: the larger difference; the same renders and checks as before, so the
same cases are flagged); AD is forward mode on the k x k lattice for each k asked for. The
errors are also given against the extrapolated reference, 2 FD(h / 2) - FD(h) (Richardson's,
from the same renders; relative to the same |Sum w FD| and Sum |w FD|): it differs from
the reference by FD(h / 2) - FD(h), which the validation bounds in every case it counts, so
it tells something only of the cases flagged for it.
(The reference was the step h until 2026-12-07: where an edge moves faster than the nearest
one, or runs by a pixel's border, a pixel's difference at h is off by up to
half of it, and the weighted sum by a point or more of Σ |w FD|: docs/gradients.md, "The
reference's own step, per pixel".)
"""

from __future__ import annotations

import math
import time

import numpy as np

EDGE_PX = 0.25  # how far (pixels) the FD's step moves the nearest edges
# an FD whose own uncertainty is above this, relative to |Sum w FD|, is not counted in the
# errors relative to |Sum w FD|; above FD_UNSTABLE_SIZE relative to Sum |w FD|, in none
FD_UNSTABLE, FD_UNSTABLE_SIZE = 0.01, 0.003
# ... and whose second difference (I(+h) - 2 I + I(-h)) / 2h, weighted, is above FD_KINK of it:
# the image has a kink at the key's value, where its one-sided derivatives differ (smooth
# shading's curvature: up to ~6 % measured; a horizon on the image's border: 60-90 %)
FD_KINK = 0.2
KINDS = ("camera.eye", "camera.lookat", "camera.fov", "translate.offset", "rotate.angle",
         "scale.factors", "triangle.v", "sphere.center", "sphere.radius", "v.position",
         "light.position", "light.direction", "mat.ior")


# -- scenes -----------------------------------------------------------------------------------
class Scene:
    """A generated scene: its text, dialect, and {kind: (key, direction, scale)} -- scale the
    world size of one unit of the key at the depth of what it moves (for the FD's step)."""

    def __init__(self, seed):
        self.seed = seed
        self.lines = []
        self.keys = {}
        self.counts = {}

    def add(self, line):
        self.lines.append(line)
        word = line.split()[0]
        self.counts[word] = self.counts.get(word, 0) + 1
        return self.counts[word]

    @property
    def text(self):
        return "\n".join(self.lines) + "\n"


def _f(*values):
    return " ".join(f"{v:.4g}" for v in values)


def _unit(rng, n=3):
    v = rng.normal(size=n)
    return v / np.linalg.norm(v)


def _camera(rng, s, dialect, size):
    az, el = math.radians(rng.uniform(-60, 60)), math.radians(rng.uniform(8, 35))
    dist = rng.uniform(6.0, 8.0)
    lookat = rng.uniform(-0.3, 0.3, 3) + np.array([0.0, -0.2, 0.0])
    eye = lookat + dist * np.array([math.sin(az) * math.cos(el), math.sin(el),
                                    math.cos(az) * math.cos(el)])
    vfov = rng.uniform(35, 50)
    fov = vfov
    w, h = size
    if dialect == "mit":  # the horizontal angle
        fov = math.degrees(2 * math.atan(math.tan(math.radians(vfov) / 2) * w / h))
    s.eye, s.lookat, s.vfov, s.dist = eye, lookat, vfov, dist
    s.pixel = 2 * dist * math.tan(math.radians(vfov) / 2) / h  # world size of a pixel
    s.add(f"eye {_f(*eye)}")
    s.add(f"lookat {_f(*lookat)}")
    s.add(f"fov {fov:.4g}")
    s.keys["camera.eye"] = ("camera.eye", _unit(rng), s.pixel)
    s.keys["camera.lookat"] = ("camera.lookat", _unit(rng), s.pixel)
    # a fov step dv moves the image's edge by (h / 2) d tan(v/2) / tan(v/2) pixels
    t = math.tan(math.radians(vfov) / 2)
    per_degree = (h / 2) * (math.radians(1.0) / 2) * (1 + t * t) / t  # pixels per degree
    if dialect == "mit":  # degrees of the horizontal angle per degree of the vertical
        th = math.tan(math.radians(fov) / 2)
        per_degree *= (1 + t * t) * th / ((1 + th * th) * t)  # (approximately)
    s.keys["camera.fov"] = ("camera.fov", np.array([1.0]), 1.0 / per_degree * s.pixel)


def _lights(rng, s, dialect, objects):
    kinds = ["point", "directional"] + (["spotlight"] if dialect == "575" else [])
    n = rng.integers(1, 3)
    chosen = [kinds[i] for i in rng.choice(len(kinds), size=n, replace=False)]
    rng.shuffle(chosen)
    for kind in chosen:
        color = rng.uniform(0.5, 1.0, 3) / n
        if kind == "point":
            for _ in range(100):  # not inside (or too near) an object
                p = np.array([rng.uniform(-4, 4), rng.uniform(2.5, 6), rng.uniform(-4, 4)])
                if all(np.linalg.norm(p - c) > r + 0.5 for c, r in objects):
                    break
            j = s.add(f"light {_f(*color)} point {_f(*p)}")
            s.keys.setdefault("light.position", (f"light{j}.position", _unit(rng),
                                                 s.pixel * 2.0))
        elif kind == "directional":
            d = _unit(rng)
            d[1] = -abs(d[1]) - 0.5
            d /= np.linalg.norm(d)
            j = s.add(f"light {_f(*color)} directional {_f(*d)}")
            s.keys.setdefault("light.direction", (f"light{j}.direction", _unit(rng),
                                                  s.pixel / 2.0))
        else:
            p = np.array([rng.uniform(-3, 3), rng.uniform(3, 6), rng.uniform(-3, 3)])
            target = rng.uniform(-1, 1, 3) * np.array([1, 0, 1]) - np.array([0, 1, 0])
            axis = (target - p) / np.linalg.norm(target - p)
            shape = float(rng.choice([0.0, 1.0, 4.0]))
            j = s.add(f"light {_f(*color)} spotlight {_f(*p)} {_f(*axis)} {shape:g}")
            s.keys.setdefault("light.position", (f"light{j}.position", _unit(rng),
                                                 s.pixel * 2.0))
            s.keys.setdefault("light.direction", (f"light{j}.direction", _unit(rng),
                                                  s.pixel / 3.0))
    s.add(f"light {_f(*rng.uniform(0.1, 0.3, 3))} ambient")


def _material(rng, s, dialect, kind):
    word = "surface" if dialect == "mit" else "material"
    c = rng.uniform(0.3, 1.0, 3)
    if kind == "glass":
        eta = rng.uniform(1.3, 1.6)
        index = 1 / eta if dialect == "mit" else eta
        i = s.add(f"{word} {_f(*c)} 0.1 0.1 0.3 20 0.1 0.85 {index:.4g}")
        s.keys.setdefault("mat.ior", (f"mat{i}.ior", np.array([1.0]), None))
    elif kind == "mirror":
        s.add(f"{word} {_f(*c)} 0.2 0.3 0.3 20 0.7 0 1")
    else:
        s.add(f"{word} {_f(*c)} {rng.uniform(0.2, 0.4):.3g} {rng.uniform(0.5, 0.8):.3g} "
              f"{rng.uniform(0, 0.5):.3g} {rng.choice([1, 10, 30])} 0 0 1")


def _placed(rng, objects, radius, y=None):
    for _ in range(200):
        c = np.array([rng.uniform(-1.8, 1.8), 0.0, rng.uniform(-1.8, 1.8)])
        c[1] = -1 + radius + (rng.uniform(0, 0.6) if y is None else y)
        if all(np.linalg.norm(c - o) > radius + r + 0.1 for o, r in objects):
            objects.append((c, radius))
            return c
    return None


def _matkind(rng):
    return str(rng.choice(["diffuse", "diffuse", "mirror", "glass"]))


def _box_triangles(half):
    """The 12 triangles of a box of half-sizes ``half`` centred at the origin."""
    hx, hy, hz = half
    v = [np.array([sx * hx, sy * hy, sz * hz]) for sx in (-1, 1) for sy in (-1, 1)
         for sz in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return v, faces


def generate(seed, size=(32, 24)):
    """The scene of ``seed`` (even: COMP 575, odd: MIT 6.837)."""
    rng = np.random.default_rng(1000 + seed)
    dialect = "575" if seed % 2 == 0 else "mit"
    s = Scene(seed)
    s.dialect = dialect
    _camera(rng, s, dialect, size)
    s.add(f"background {_f(*rng.uniform(0, 0.4, 3))}")
    objects = []
    # the objects are placed first (the lights avoid them), written after the lights
    n = int(rng.integers(2, 5))
    if dialect == "575":
        body = []
        floor = rng.choice(["checker", "plain", "mirror"])
        kinds = ["sphere", "box", "triangle", "ellipsoid", "cylinder", "cone"]
        picks = [kinds[i] for i in rng.choice(len(kinds), size=n, replace=False)]
        if not {"sphere", "box", "triangle"} & set(picks):  # something that moves
            picks[0] = str(rng.choice(["sphere", "box", "triangle"]))
        for kind in picks:
            r = rng.uniform(0.4, 0.9)
            c = _placed(rng, objects, r)
            if c is not None:
                body.append((kind, c, r, _matkind(rng)))
        _lights(rng, s, dialect, objects)
        _material(rng, s, dialect, "mirror" if floor == "mirror" else "diffuse")
        s.add("translate 0 -1 0")
        if floor == "checker":
            s.add(f"checkerboard {rng.uniform(0.4, 1.2):.3g}")
        s.add("plane")
        if floor == "checker":
            s.add("checkerboard -1")
        s.add("reset")
        for kind, c, r, mat in body:
            _material(rng, s, dialect, mat)
            t = s.add(f"translate {_f(*c)}")
            scale = s.pixel * np.linalg.norm(s.eye - c) / s.dist
            if kind in ("sphere", "box", "triangle"):
                s.keys.setdefault("translate.offset", (f"translate{t}.offset", _unit(rng),
                                                       scale))
            if kind == "sphere":
                k = s.add(f"scale {_f(r, r, r)}")
                s.keys.setdefault("scale.factors", (f"scale{k}.factors",
                                                    np.ones(3) / math.sqrt(3), scale / r))
                s.add("sphere")
            elif kind == "box":
                k = s.add(f"rotateY {rng.uniform(0, 90):.4g}")
                s.keys.setdefault("rotate.angle", (f"rotateY{k}.angle", np.array([1.0]),
                                                   math.degrees(scale / r)))
                half = rng.uniform(0.5, 1.0, 3) * r / math.sqrt(2)
                v, faces = _box_triangles(half)
                for f in faces:
                    for tri in ((f[0], f[1], f[2]), (f[0], f[2], f[3])):
                        s.add("triangle " + "  ".join(_f(*v[i]) for i in tri))
            elif kind == "triangle":
                k = s.add(f"rotateZ {rng.uniform(-30, 30):.4g}")
                s.keys.setdefault("rotate.angle", (f"rotateZ{k}.angle", np.array([1.0]),
                                                   math.degrees(scale / r)))
                corners = [r * np.array([math.cos(a), math.sin(a), 0.0])
                           for a in rng.uniform(0, 2 * math.pi) + np.array([0, 2.1, 4.2])]
                j = s.add("triangle " + "  ".join(_f(*p) for p in corners))
                s.keys.setdefault("triangle.v", (f"triangle{j}.v{rng.integers(0, 3)}",
                                                 _unit(rng), scale))
            elif kind == "ellipsoid":
                s.add(f"scale {_f(r, r * rng.uniform(0.5, 0.9), r * rng.uniform(0.6, 1.0))}")
                s.add("sphere")
            elif kind in ("cylinder", "cone"):
                s.add(f"scale {_f(r, 2 * r, r)}")
                s.add(kind)
            s.add("reset")
    else:
        body = []
        kinds = ["sphere", "sphere", "mesh", "sphere"]
        for kind in kinds[:n]:
            r = rng.uniform(0.4, 0.9)
            c = _placed(rng, objects, r)
            if c is not None:
                body.append((kind, c, r, _matkind(rng)))
        _lights(rng, s, dialect, objects)
        _material(rng, s, dialect, "diffuse")
        vcount = 0
        s.add("triangles")  # the floor
        for x, z in ((-6, -6), (6, -6), (6, 6), (-6, 6)):
            s.add(f"v {x} -1 {z}")
            vcount += 1
        s.add("f 0 1 2")
        s.add("f 0 2 3")
        s.add("end")
        for kind, c, r, mat in body:
            _material(rng, s, dialect, mat)
            scale = s.pixel * np.linalg.norm(s.eye - c) / s.dist
            if kind == "sphere":
                j = s.add(f"sphere {_f(*c, r)}")
                s.keys.setdefault("sphere.center", (f"sphere{j}.center", _unit(rng), scale))
                s.keys.setdefault("sphere.radius", (f"sphere{j}.radius", np.array([1.0]),
                                                    scale))
            else:
                s.add("triangles")
                first = vcount
                # a tetrahedron of random corners around c
                for a in range(4):
                    p = c + r * _unit(rng)
                    s.add(f"v {_f(*p)}")
                    vcount += 1
                for f in ((0, 1, 2), (0, 3, 1), (1, 3, 2), (0, 2, 3)):
                    s.add("f " + " ".join(str(i) for i in f))
                s.add("end")
                s.keys.setdefault("v.position", (f"v{first + int(rng.integers(0, 4)) + 1}"
                                                 ".position", _unit(rng), scale))
    # the mat key's unit step
    if "mat.ior" in s.keys:
        key, d, _ = s.keys["mat.ior"]
        s.keys["mat.ior"] = (key, d, 0.004)
    return s


# -- the comparison ------------------------------------------------------------------------
def step(scale):
    return EDGE_PX * scale


def lattice_image(mi, text, key, value, k, size):
    """The image (H, W, 3) on the k x k lattice per pixel with ``key`` set to ``value`` (None:
    as loaded): where k > 64 (spp is at most 4096), the image at f times the size with
    (k / f)^2 samples per pixel (the same lattice), averaged over f x f blocks."""
    from support_edges import image, loaded

    f = -(-k // 64)
    while k % f:
        f += 1
    w, h_ = size
    fine = image(loaded(mi, text, (k // f) ** 2, key if value is not None else None, value,
                        width=w * f, height=h_ * f))
    return fine.reshape(h_, f, w, f, 3).mean(axis=(1, 3))


def lattice_difference(mi, text, key, direction, h, k, size, base=None):
    """The central difference (H, W, 3) of the image on the k x k lattice per pixel
    (:func:`lattice_image`); with ``base`` (a list), the image at the key's value itself
    (one render more) is appended to it."""
    from support_edges import loaded, value_of

    x0 = value_of(loaded(mi, text, 1, width=size[0], height=size[1]), key)
    u = np.asarray(direction, np.float64)
    plus, minus = (lattice_image(mi, text, key, x0 + s * h * u, k, size) for s in (1, -1))
    if base is not None:
        base.append(lattice_image(mi, text, key, None, k, size))
        base.append((plus + minus - 2.0 * base[0]) / (2.0 * h))
    return (plus - minus) / (2.0 * h)


def weights_for(size):
    w, h = size
    return np.random.default_rng(13).random((h, w, 3))


def compare(mi, s, kind, size, fd_k, ks, reverse_check=False):
    """{the case's figures} for ``kind`` of scene ``s``."""
    from support_edges import finite_difference, forward, relative_l2, reverse

    key, direction, scale = s.keys[kind]
    w, h = size
    options = dict(width=w, height=h)
    wts = weights_for(size)
    hh = step(scale)
    started = time.perf_counter()
    base = []  # (the image at the key's value, and the second difference / 2h)
    whole = lattice_difference(mi, s.text, key, direction, hh, fd_k, size, base)  # (step h)
    fd = lattice_difference(mi, s.text, key, direction, hh / 2, fd_k, size)  # the reference
    # (the lattice checked at the step h, against the k_FD lattice's: at h / 2 a lattice of
    # k_FD / 2 moves the nearest edges across some 6 of its points, whose count is noise)
    coarse = lattice_difference(mi, s.text, key, direction, hh, fd_k // 2, size)
    fd_sum = float(np.sum(wts * fd))
    size_sum = float(np.sum(np.abs(wts * fd)))
    out = dict(seed=s.seed, kind=kind, key=key, h=hh, fd_sum=fd_sum, fd_size=size_sum)
    if size_sum == 0.0 or fd_sum == 0.0:
        out.update(flag="FD zero: nothing visible moves")
        return out
    unc = max(abs(float(np.sum(wts * coarse)) - float(np.sum(wts * whole))),
              abs(float(np.sum(wts * whole)) - fd_sum))
    out["fd_uncertainty"] = unc / abs(fd_sum)
    out["fd_uncertainty_size"] = unc / size_sum
    out["fd_pixel_uncertainty"] = max(relative_l2(coarse, whole), relative_l2(whole, fd))
    # a kink: the one-sided differences (I(+h) - I) / h and (I - I(-h)) / h differ by twice
    # this (an edge that lies on the image's border, or moves into it one way only); the
    # central difference is then their mean, which no derivative is
    out["fd_kink"] = abs(float(np.sum(wts * base[1]))) / size_sum
    out["fd_seconds"] = time.perf_counter() - started
    if unc / size_sum > FD_UNSTABLE_SIZE:
        out["flag"] = f"FD unstable ({unc / size_sum:.2%} of sum abs(w FD))"
    elif out["fd_kink"] > FD_KINK:
        out["flag"] = f"FD one-sided (a kink: {out['fd_kink']:.2%} of sum abs(w FD))"
    out["rel_counted"] = unc / abs(fd_sum) <= FD_UNSTABLE
    # the extrapolated reference, Richardson's from the same two steps (where the image is not
    # smooth in the key, a shaded sphere's rim, the central difference's error is
    # proportional to its step: docs/gradients.md, "The reference's step, in the sums")
    extrapolated = 2.0 * fd - whole
    x_sum = float(np.sum(wts * extrapolated))
    out["fd_extrapolated_sum"] = x_sum
    errors, errors_x = {}, {}
    for k in ks:
        ad = forward(mi, s.text, key, direction, k * k, **options)
        ad_sum = float(np.sum(wts * ad))
        e = abs(ad_sum - fd_sum)
        errors[k] = dict(rel=e / abs(fd_sum), rel_size=e / size_sum, l2=relative_l2(ad, fd))
        e = abs(ad_sum - x_sum)
        errors_x[k] = dict(rel=e / abs(x_sum) if x_sum else math.inf, rel_size=e / size_sum,
                           l2=relative_l2(ad, extrapolated))
        if reverse_check and k == ks[0]:
            g = reverse(mi, s.text, key, wts, k * k, **options)
            rev = float(np.dot(g, direction))
            out["reverse_vs_forward"] = abs(rev - ad_sum) / size_sum
    out["errors"], out["errors_extrapolated"] = errors, errors_x
    return out
