"""The lattice and the constants its keys and pairs share (the package docstring: "The
lattice", "Pairs"): the keys' sentinels (NO_HIT, STOP) and the chain's keys past its end
(DEFAULT), the kinds of pairs and a pair's points, the angle of a crease; a lattice point's
flat position and the readers of the lattice's arrays at it; the lattice point of a camera
ray (:func:`lattice_index`) and the ring around the image (:func:`ring_points`); the host's
copies of the keys."""

import drjit as dr
import mitsuba as mi
import numpy as np

NO_HIT = 0xFFFFFFFF
STOP = 0xFFFFFFFE  # a chain that ended (a surface neither mirror nor glass)
LIT = 0xFFFFFFFD  # a shadow edge's key where its light lights the sample (shadow_key)
KINDS = 7  # kinds of pairs:
VISIBILITY, SHADOW, CHECKER, CHAIN_VISIBILITY, CHAIN_CHECKER, CHAIN_TIR, CHAIN_SHADOW = range(KINDS)
POINTS = ("L", "R")  # a pair's samples
# The chain's keys of a sample whose chain ended before a bounce (those of the first hit are
# set for every sample): what a bounce past a chain's end holds
DEFAULT = {"chain_shape": STOP, "chain_prim": 0, "chain_t": np.inf, "chain_normal": 0.0,
           "chain_cell": 0, "chain_tir": False, "chain_lit": False, "chain_occluder": NO_HIT,
           "chain_stopper": NO_HIT}
# Two faces of a mesh whose unit normals' dot product is below this (60 degrees apart) lie
# across a crease: more than the 45 degrees between neighbours of the coarsest tessellation
# (8 segments), less than a cap's 90 degrees to a cylinder's side
CREASE = 0.5


def shadow_key(lit, occluder, stopper):
    """The key that tells the sides of a shadow edge apart (numpy int64, per sample; ``lit``,
    ``occluder`` and ``stopper``: the light's keys there, numpy, see shadows.py): LIT where
    the light lights the sample, else the shapes that first block it and that stop it
    (NO_HIT: none; it faces away, lies outside a spot's cone, or the light gets through
    glass). A ray traced beside the crossing whose key is neither sample's lies past another
    edge (``terms.py``'s jump)."""
    both = (occluder[..., 0].astype(np.uint64) << np.uint64(32)) \
        | stopper[..., 0].astype(np.uint64)
    return np.where(lit, np.uint64(LIT), both).view(np.int64)


def across_crease(a, b):
    """Whether the unit normals ``a`` and ``b`` (numpy (n, 3)) lie across a crease (CREASE)."""
    return np.einsum("ij,ij->i", a, b) < CREASE


def flat(points, cols):
    """The flat positions (row-major) of the lattice points ``points`` = (y, x) (numpy) in
    arrays of ``cols`` columns: the lattice's arrays are read at these (:func:`at`)."""
    return points[0] * cols + points[1]


def at(plane, index):
    """The entries of ``plane`` (a contiguous lattice array, (rows, cols, ...)) at the flat
    positions ``index`` (numpy, see :func:`flat`), by ``np.take``: numpy's indexing by a
    pair of index arrays (y, x) is about four times slower, and of an array of vectors
    (an occluder's (shape, prim)) by an index array ten times."""
    return np.take(plane.reshape((-1,) + plane.shape[2:]), index, axis=0)


def nonzero(mask):
    """(y, x) of the True entries of a 2-D mask, row-major (np.nonzero's, faster: one pass
    for flat positions, then their rows and columns)."""
    return np.divmod(np.flatnonzero(mask), mask.shape[1])


def picked(arrays, index, positions):
    """The entry of arrays[index[i]] at positions[i] for each i (``arrays``: a list of
    lattice arrays, (H k, W k, ...); ``index``, ``positions``: numpy, per pair, the
    positions flat: see :func:`flat`)."""
    if len(arrays) == 1:
        return at(arrays[0], positions)
    out = np.empty((len(index),) + arrays[0].shape[2:], arrays[0].dtype)
    for j, array in enumerate(arrays):
        where = index == j
        if where.any():
            out[where] = at(array, positions[where])
    return out


def lattice_index(width, k, first_pixel, count):
    """The entry of the lattice's arrays (flat, row-major: W k + 2 columns, the ring
    included: see the package docstring) of each camera ray of the pixels first_pixel ..
    first_pixel + count - 1 of a ``width``-pixel-wide image on the k x k lattice (a lane
    per ray, pixel-major; sample s of a pixel at (s // k, s % k) within it): a UInt32."""
    lane = dr.arange(mi.UInt32, count * k * k)
    pixel = lane // (k * k)
    sample = lane - pixel * (k * k)
    pixel += dr.opaque(mi.UInt32, first_pixel)  # (data, not a constant of the kernel)
    py = pixel // width
    y, x = py * k + sample // k, (pixel - py * width) * k + sample % k
    return (y + 1) * (width * k + 2) + x + 1


def ring_points(width, height, k):
    """(Y, X) of the lattice's ring (numpy, entries of the lattice's arrays): the points
    half a lattice spacing outside the image, all round (the package docstring)."""
    rows, cols = height * k + 2, width * k + 2
    y = np.concatenate([np.zeros(cols, np.int64), np.full(cols, rows - 1),
                        np.arange(1, rows - 1), np.arange(1, rows - 1)])
    x = np.concatenate([np.arange(cols), np.arange(cols), np.zeros(rows - 2, np.int64),
                        np.full(rows - 2, cols - 1)])
    return y, x


def lattice_side(spp):
    """k for ``spp`` = k^2 samples per pixel (None: not a square lattice)."""
    k = int(round(spp ** 0.5))
    return k if k * k == spp else None


def _planes(vector):
    """A Dr.Jit vector of whole numbers as floats (evaluated) as numpy int32 (components,
    lanes): each component cast as it is copied in (a stack, then a cast, is four times
    slower: 2.1 against 0.5 ms for a 256 x 192 lattice at k = 4)."""
    out = np.empty((len(vector), dr.width(vector)), np.int32)
    for plane, component in zip(out, vector):
        plane[...] = component.numpy()
    return out


def _host_keys(keys):
    """The keys of :meth:`Boundary.hit_keys` (evaluated) as numpy arrays: shape, prim, t,
    cell (planes), and per light lit, occluder and stopper (lists)."""
    return {"shape": keys["shape"].numpy(), "prim": keys["prim"].numpy(),
            "t": keys["t"].numpy(), "cell": _planes(keys["cell"]),
            "lit": [v.numpy() for v in keys["lit"]],
            "occluder": [_host(v) for v in keys["occluder"]],
            "stopper": [_host(v) for v in keys.get("stopper", [])]}  # (none without glass)


def _host(vector):
    """A Dr.Jit vector (evaluated) as a numpy (lanes, components) array: interleaved on the
    device by one kernel (numpy's stack of the components' planes is 2.5 times slower: 0.75
    against 0.3 ms for a Vector2u of a 256 x 192 lattice at k = 4)."""
    return dr.ravel(dr.detach(vector)).numpy().reshape(-1, len(vector))
