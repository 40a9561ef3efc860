"""The sphere set: many analytic spheres and ellipsoids as one Mitsuba shape, and its data layout.

A scene with thousands of spheres would otherwise create a Mitsuba ``sphere`` per object
(about 40 microseconds of ``mi.load_dict`` each, and an Embree geometry each), and its
spheres under non-uniform scales would be tessellated (tens of triangles each, Embree's
BVH build being the largest cost per triangle). Mitsuba's ``ellipsoids`` shape holds any
number of ellipsoids in one object and one Embree geometry: with equal scales on the three
axes each is an exact sphere, with unequal ones an exact ellipsoid. The translator
(``translate.py``) packs them into it and the Whitted integrator's hit table
(``plugins/whitted/hits.py``) reads them back; this module is the layout both use.

The set's BSDF (``raysurfaceset``) holds a table of the materials only its members use, a
row each (``material_table``).

Which spheres: those whose material is opaque (kt = 0) and that do not contain the eye,
under a similarity transform without mirroring (drawn by Mitsuba's ``sphere`` otherwise)
or, if their surface is untextured, under any other invertible transform (tessellated
otherwise), when a scene has at least ``RenderOptions.sphere_set`` of them (default 256;
0: never). The restriction to opaque ones is Mitsuba's: ``ellipsoids`` culls the hits of
a ray that starts inside an ellipsoid (it is made for volumetric primitives), and only the
rays of glass (refraction, shadow rays through it) and a camera inside a sphere start
there. So a material that draws set spheres must stay opaque: the integrator refuses a
render where such a material has kt > 0 (a fit of kt from 0 on such a scene: load it with
``--sphere-set 0``, ``sphere_set=0``).

The data, per member, ten float32 (Mitsuba's order): the centre c (3), the scales (3), the
rotation as a unit quaternion (x, y, z, w), the member being ``T(c) R S(scales)`` applied
to the unit sphere. For a sphere (a to-world transform ``T(c) R S(r)``) the scales are the
radius r three times and R is the transform's rotation: it does not change the sphere,
only its texture coordinates (``uv`` from the object-space point, as for Mitsuba's own
sphere). For an ellipsoid (``T(c) A``, A any invertible matrix, A = U diag(s) V^T its
singular value decomposition) the scales are the singular values s and R = U (a column
negated if U mirrors): the same surface, since V^T maps the unit sphere onto itself, but
not the same object space -- so ellipsoids with a texture stay tessellated (their
``uv`` would turn with V). ``extent`` is 1 (Mitsuba's default, 3, is for Gaussian kernels).
"""

from __future__ import annotations

import operator
from itertools import chain

import numpy as np

from raymitsuba.model import Material

FLOATS = 10  # per sphere: centre (3), scale (3), quaternion (4)
EXTENT = 1.0  # the ellipsoids' ``extent``: the scale is the radius

# A row of the set's material table (``plugins/surfaceset.py``): the color r g b, then the
# other fields of ``Material.FIELDS`` in their order.
MATERIAL_COLUMNS = 3 + len(Material.FIELDS) - 1


def material_table(materials) -> np.ndarray:
    """The set's material table (n, MATERIAL_COLUMNS) float32 of ``materials``: a row each,
    the color r g b, then the other fields of ``Material.FIELDS`` in their order (read as
    two streams of floats: the colors, the rest)."""
    n = len(materials)
    table = np.empty((n, MATERIAL_COLUMNS), np.float64)
    colors = chain.from_iterable(map(operator.attrgetter("color"), materials))
    table[:, :3] = np.fromiter(colors, np.float64, 3 * n).reshape(n, 3)
    rest = chain.from_iterable(map(operator.attrgetter(*Material.FIELDS[1:]), materials))
    table[:, 3:] = np.fromiter(rest, np.float64, (MATERIAL_COLUMNS - 3) * n).reshape(n, -1)
    return table.astype(np.float32)


def material_column(field: str):
    """Where ``field`` is in a row of the material table: a slice (``color``) or an index."""
    return slice(0, 3) if field == "color" else 2 + Material.FIELDS.index(field)


def pack(to_world: np.ndarray, ellipsoid: np.ndarray = None) -> np.ndarray:
    """The set's data (n * FLOATS float32) of the members of to-world transforms
    ``to_world`` (n, 4, 4): an invertible linear part, then a translation. A linear part
    that is a rotation times a positive uniform scale gives a sphere (exactly: its radius
    three times, its rotation); any other, an ellipsoid (its singular values and rotation,
    see the module docstring). ``ellipsoid``: which are not similarities (n,) bool, where
    the caller knows (else :func:`is_similarity` finds them)."""
    m = np.asarray(to_world, np.float64).reshape(-1, 4, 4)
    linear = m[:, :3, :3]
    radius = np.linalg.norm(linear[:, :, 0], axis=1)
    scales = np.repeat(radius[:, None], 3, axis=1)
    rotation = linear / radius[:, None, None]
    if ellipsoid is None:
        ellipsoid = ~is_similarity(linear)
    if ellipsoid.any():
        u, s, _ = np.linalg.svd(linear[ellipsoid])
        u[np.linalg.det(u) < 0, :, 2] *= -1.0  # a proper rotation: the same surface
        scales[ellipsoid], rotation[ellipsoid] = s, u
    data = np.empty((len(m), FLOATS), np.float64)
    data[:, 0:3] = m[:, :3, 3]
    data[:, 3:6] = scales
    data[:, 6:10] = quaternion(rotation)
    return data.astype(np.float32).ravel()


def is_similarity(linear: np.ndarray) -> np.ndarray:
    """Which linear parts (n, 3, 3) are a rotation times a positive uniform scale (no
    mirroring, no shear): the transforms of spheres."""
    c0, c1, c2 = linear[:, :, 0], linear[:, :, 1], linear[:, :, 2]  # the columns
    dot = lambda a, b: (a * b).sum(axis=1)  # noqa: E731
    diagonal = np.stack([dot(c0, c0), dot(c1, c1), dot(c2, c2)])  # the Gram matrix's
    scale2 = diagonal.sum(axis=0) / 3.0
    off = np.abs(np.stack([dot(c0, c1), dot(c0, c2), dot(c1, c2)])).max(axis=0)
    off = np.maximum(off, np.abs(diagonal - scale2).max(axis=0))
    det = dot(c0, np.cross(c1, c2))
    return (det > 0) & (off <= 1e-9 * scale2)


def unpack(data: np.ndarray):
    """(centres (n, 3), radii (n,), world-to-object matrices (n, 3, 4), which members are
    ellipsoids (n,)) of the set's data, float64: the inverse of T(c) R S(scales) is
    S(1/scales) R^T T(-c). An ellipsoid's radius is its first scale; its object space is
    the set's (see the module docstring)."""
    d = np.asarray(data, np.float64).reshape(-1, FLOATS)
    center, scales = d[:, 0:3], d[:, 3:6]
    inverse_linear = np.transpose(rotation(d[:, 6:10]), (0, 2, 1)) / scales[:, :, None]
    to_object = np.concatenate(
        [inverse_linear, -np.einsum("nij,nj->ni", inverse_linear, center)[:, :, None]], axis=2)
    ellipsoid = (scales[:, 1] != scales[:, 0]) | (scales[:, 2] != scales[:, 0])
    return center, scales[:, 0], to_object, ellipsoid


def quaternion(r: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of rotation matrices r (n, 3, 3) (the largest of
    the four |components| first, for accuracy)."""
    q = np.empty((len(r), 4))
    trace = np.trace(r, axis1=1, axis2=2)
    # 4 q_k^2 for k = x, y, z, w, from the diagonal
    four_sq = np.stack([1 + 2 * r[:, 0, 0] - trace, 1 + 2 * r[:, 1, 1] - trace,
                        1 + 2 * r[:, 2, 2] - trace, 1 + trace], axis=1)
    k = np.argmax(four_sq, axis=1)
    s = 2.0 * np.sqrt(np.maximum(four_sq[np.arange(len(r)), k], 1e-300))  # 4 |q_k|
    zy, yz = r[:, 2, 1], r[:, 1, 2]
    xz, zx = r[:, 0, 2], r[:, 2, 0]
    yx, xy = r[:, 1, 0], r[:, 0, 1]
    by_largest = {  # (x, y, z, w) * s, for the largest component k
        0: (s * s / 4, xy + yx, xz + zx, zy - yz),
        1: (xy + yx, s * s / 4, yz + zy, xz - zx),
        2: (xz + zx, yz + zy, s * s / 4, yx - xy),
        3: (zy - yz, xz - zx, yx - xy, s * s / 4),
    }
    for which, parts in by_largest.items():
        rows = k == which
        q[rows] = np.stack(parts, axis=1)[rows] / s[rows, None]
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (n, 3, 3) of quaternions (x, y, z, w) (n, 4), normalized first."""
    q = np.asarray(q, np.float64)
    x, y, z, w = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], axis=1)
