"""The bailout: which rays of the tree are not traced, and the bound that makes that safe.

The render option ``bailout`` (``raymitsuba.options``) chooses one of three rules:

* 0: the exact tree: every child of weight > 0 is traced, down to ``max_depth``;
* a number p > 0: a child whose path weight (the product of the kr / kt weights from the
  camera ray down to it) is at most p is not traced;
* unset (the default): the **bounded** rule below, whose error is stated.

**The bound.** Write L for the largest value, in any channel, that the local term of one
hit can take anywhere in the scene, and B(d) for the largest value a subtree can return
when its ray may still bounce d times (d = 0: the local term or the background only)::

    L_local <= |A ka C| + sum_lights |I| (|kd C| + |ks| lobe) T_max      (format: integrator.py)

with A the summed ambient light, I a light's color (a point or directional light gives I,
a spotlight at most I), N.L <= 1, the highlight's lobe (R.V)^n <= 1 for n >= 0 (unbounded
for n < 0), and the shadow transmittance T, a product of at most ``max_shadow_crossings``
kt factors, <= T_max = max(1, kt_max)^max_shadow_crossings. C is the material's color times
its image textures (at most their largest texel; 8-bit ones at most 1) times its
checkerboard (0 or 1). So, over every surface and channel and the background b,

    L = max(max_surfaces L_local, max |b|)

A subtree's value is its local term plus its children's values weighted by kr and kt
(kr + kt to the reflected child on total internal reflection), so with
w = max over surfaces of max(kr, 0) + max(kt, 0) (negative weights are never traced):

    B(0) = L,   B(d) = L + w B(d - 1) = L (1 + w + ... + w^d)

which is L / (1 - w) at most when w < 1, and the depth-limited geometric sum otherwise
(w >= 1 makes no infinite bound; the depth limits it).

**The rule.** A child ray at generation g (the camera ray is 0) may bounce d = max_depth - g
more times, and its path weight P is the factor its subtree's value enters its pixel with.
It is not traced when P B(d) <= SUBTREE_ERROR = 1/1020, a quarter of a step of an 8-bit
display: then what its whole subtree would have added to its pixel is at most 1/1020
(linear value, in every channel). A pixel's error is at most the sum of that over the
subtrees not traced in it (an average of such sums with several samples). Half a step
(1/510) a subtree was tried first: on whitted.ray at depth 5 several subtrees of one pixel
add up, and a few pixels moved by just over one step; with a quarter, no image of the
tests or the gallery moves by more than half a step (docs/performance.md, "Deep trees").
The bound is computed anew at every render from the scene's current parameters (the limits
are data of the kernels, so a new bound compiles nothing); a scene whose bound is infinite
or not a number (n < 0, an infinite texel) is traced exactly.
"""

from __future__ import annotations

import math

import drjit as dr
import mitsuba as mi
import numpy as np

#: What a subtree left out may add to its pixel: a quarter of an 8-bit display's step.
SUBTREE_ERROR = 1.0 / 1020.0


def path_weight_limits(bailout, terms, max_depth, max_shadow_crossings):
    """The bailout's limit for each generation of children: a list whose entry g - 1 is the
    path weight at or below which a child of generation g (1 .. ``max_depth``) is not
    traced; None: the exact tree. ``bailout``: the option (None: the bounded rule; 0: exact;
    p > 0: p for every generation); ``terms``: the scene's SceneTerms."""
    if bailout is not None:
        return None if bailout == 0 else [float(bailout)] * max_depth
    local, weight = local_bound(terms, max_shadow_crossings), weight_bound(terms)
    limits = []
    for g in range(1, max_depth + 1):
        bound = subtree_bound(local, weight, max_depth - g)
        if not math.isfinite(bound):
            return None  # no finite bound: trace the exact tree
        limits.append(SUBTREE_ERROR / bound if bound > 0 else math.inf)
    return limits


def subtree_bound(local, weight, d):
    """B(d) = L (1 + w + ... + w^d): the most a subtree that may bounce ``d`` more times can
    return (``local``: L, ``weight``: w; see the module docstring)."""
    if weight == 1.0:
        return local * (d + 1)
    return local * (1.0 - weight ** (d + 1)) / (1.0 - weight)


def weight_bound(terms):
    """w: the largest sum of a hit's children's weights, max(kr, 0) + max(kt, 0), over the
    scene's surfaces."""
    host, count = terms.surfaces.host, terms.surfaces.layout.count
    if count == 0:
        return 0.0
    kr, kt = host["reflectivity"][:count], host["refractivity"][:count]
    return float(np.max(np.maximum(kr, 0.0) + np.maximum(kt, 0.0)))


def local_bound(terms, max_shadow_crossings):
    """L: the largest value, in any channel, of a hit's local term or of the background
    (see the module docstring)."""
    surfaces = terms.surfaces
    host, layout = surfaces.host, surfaces.layout
    background = float(np.max(np.abs(host_color(terms.background))))
    if layout.count == 0:
        return background
    rows = slice(0, layout.count)
    color = np.abs(host["color"][rows]) * texture_bounds(layout)[:, None]  # (slots, 3)
    ambient = np.abs(host_color(terms.ambient))  # (3,)
    lights = sum((np.abs(host_color(light.color)) for light in terms.direct), np.zeros(3))
    kt_max = float(np.max(host["refractivity"][rows]))
    transmittance = max(1.0, kt_max) ** max_shadow_crossings
    lobe = np.where(host["phong_coeff"][rows] >= 0, 1.0, math.inf)
    ka, kd, ks = (np.abs(host[name][rows])[:, None] for name in
                  ("ambient_mix", "diffuse_mix", "specular_mix"))
    with np.errstate(invalid="ignore"):  # (0 * inf: a surface with ks = 0 and n < 0)
        specular = np.where(ks > 0, ks * lobe[:, None], 0.0)
        local = ambient * ka * color + lights * (kd * color + specular) * transmittance
    return float(max(np.max(local), background))


def texture_bounds(layout):
    """By slot (float64, ``layout.count``): the largest factor the surface's image textures
    multiply its color by (the product of each one's largest texel; 1: none)."""
    factors = np.ones(layout.count)
    for texture_of_slot in layout.texture_of_slot:
        which = np.asarray(texture_of_slot.numpy())[:layout.count]
        largest = np.array([1.0] + [texel_bound(t) for t in layout.textures])
        factors *= largest[which]  # (index 0: no texture at this position, factor 1)
    return factors


def texel_bound(texture):
    """The largest value ``texture`` can return: 1 for 8-bit and 16-bit images (normalized,
    sRGB-decoded or not), the largest |texel| for float ones, infinite for a texture whose
    data cannot be read (then the exact tree)."""
    params = mi.traverse(texture)
    if "data" not in params:
        return math.inf
    data = params["data"]
    if not dr.is_float_v(data):
        return 1.0
    return float(dr.max(dr.abs(dr.ravel(dr.detach(data))))[0])


def host_color(color):
    """A Color3f of width 1 (a light's, the background's) as a numpy (3,) float64 array."""
    return np.asarray(dr.detach(color).numpy(), np.float64).reshape(3, -1)[:, 0]
