"""What the tests of geometry and camera derivatives share: loading a scene with a key set,
and the derivative of its pixel-integrated image by finite differences.

**The reference.** The image of ``spp = 64^2`` samples per pixel (a lattice of spacing
1/64 pixel) stands for the pixel-integrated image; its central difference with a step
that moves the edges by about 0.1 pixel (6 lattice spacings each way) is the reference.
Each row of lattice samples an edge sweeps then switches 6 +- 1 samples, so a pixel's
difference is exact to a few percent and a weighted sum over the ~100 rows along an edge
to about 1-2 % (measured: the reference moves by 1-2 % between steps of 0.05 and 0.1
pixel and between 32^2 and 64^2 samples); smooth (interior) changes are exact to O(h^2).

Per pixel it is coarser: where an edge runs nearly along a pixel's border, the step's 0.1
pixel carries it across that border, and the difference shares between two pixels what
belongs to one (a sphere's flat-shaded silhouette: 8 % per-pixel relative L2 against the
fine reference below, whatever the lattice of the derivative it is compared with).
:func:`fine_difference` takes a step five times smaller on a 256 x 256 lattice (the image
rendered at 4 x 4 times the size with 64^2 samples per pixel, then averaged over 4 x 4
blocks): the same pixels within 0.5 % (measured: steps of 0.02 and 0.01 pixel), for
per-pixel comparisons (benchmarks/edges_bench.py).
"""

from __future__ import annotations

import math

import numpy as np

W, H = 16, 12
REFERENCE_SPP = 4096  # 64 x 64

# -- scenes of the boundary terms' kinds (tests/plugins/whitted/boundary/ and
# benchmarks/edges_bench.py) ----------------------------------------------------------------
# a shiny sphere lit from behind on the left: the terminator (N.L = 0) crosses the disk, and
# the specular term (ks (R.V)^n, n = 1) is cut off there
TERMINATOR = """\
eye 0 0 5
fov 40
background 0.2 0.3 0.4
light 1 1 1 point -5 0.3 -1
light 0.2 0.2 0.2 ambient
material 0.8 0.4 0.3 0.2 0.3 0.8 1 0 0 1
sphere
"""
# a sphere, its shadow on a checkered plane, a point light: every kind of edge seen directly
# (the benchmark's camera keys and its cost; tests/plugins/whitted/test_replay.py)
SPHERE_ON_CHECKER = """\
eye 0.4 4 5
lookat 0 0.2 0
fov 35
background 0.2 0.3 0.4
light 1 1 1 point 2 5 4
light 0.25 0.25 0.25 ambient
material 0.9 0.85 0.7 0.4 0.6 0 1 0 0 1
translate 0 -1 0
checkerboard 1.2
plane
reset
material 0.8 0.3 0.2 0.3 0.7 0.3 10 0 0 1
translate -0.9 0 0
sphere
"""
# a spotlight of coefficient 0 on a floor: it lights the half-space in front of it evenly,
# and its edge (cos a = 0) crosses the image
SPOT = """\
eye 0 2 5
lookat 0 -1 0
fov 50
background 0.2 0.3 0.4
light 1 0.9 0.7 spotlight -0.5 0.5 0  1 -0.2 0.3  0
light 0.2 0.2 0.2 ambient
material 0.8 0.8 0.7 0.3 0.7 0 1 0 0 1
translate 0 -1 0
plane
"""
# a mirror floor reflecting a wall on which a sphere casts its shadow: the shadow's edge is
# seen directly and in the mirror (the specular chain's first bounce)
MIRRORED_SHADOW = """\
eye 0 1 6
lookat 0 -0.5 0
fov 45
background 0.2 0.3 0.4
light 1 1 1 point 1.5 1 4
light 0.2 0.2 0.2 ambient
material 0.1 0.1 0.1 0.2 0.2 0 1 0.9 0 1
translate 0 -1 0
plane
reset
material 0.9 0.8 0.6 0.3 0.7 0 1 0 0 1
rotateX 90
translate 0 0 -2
plane
reset
material 0.8 0.4 0.3 0.3 0.7 0 1 0 0 1
translate 0 0.8 0
scale 0.6 0.6 0.6
sphere
"""
# Snell's window: looking up from under a glass surface (a plane; a ray from below leaves
# the glass), total internal reflection switches on at the critical angle; inside the window
# the sky, outside it the lit floor reflected
SNELL = """\
eye 0 -1 0
lookat 0 0 0
up 0 0 1
fov 120
background 0.1 0.2 0.6
light 1 0.9 0.8 point 0 -2 0
light 0.2 0.2 0.2 ambient
material 1 1 1 0 0 0 1 0 0.9 1.33
plane
material 0.9 0.6 0.3 0.3 0.7 0 1 0 0 1
translate 0 -3 0
plane
"""

# the flat-shaded scenes of tests/plugins/whitted/boundary/: an ambient light, a red
# material, the view axis along -z at depth 5
FLAT = """\
eye 0 0 5
fov 40
background 0.2 0.3 0.4
light 1 1 1 ambient
material 0.8 0.4 0.3 1 0 0 10 0 0 1
translate 0.1 0.05 0
"""
SPHERE = FLAT + "sphere\n"
PIXELS_PER_UNIT = H / (2 * 5 * math.tan(math.radians(20)))  # at depth 5, fov 40
JUMP = 0.8 - 0.2  # red: the material's ambient color minus the background's
# a plane under a level camera, lit by ambient light only (the floor one flat colour): the
# horizon, 0.1 below the eye's level at the look-at point, crosses pixel row 5
HORIZON = """\
eye 0 1 5
lookat 0 0.9 0
fov 40
background 0.2 0.3 0.4
light 1 1 1 ambient
material 0.8 0.4 0.3 1 0 0 10 0 0 1
translate 0 -1 0
plane
"""
# d (red) / d (the look-at point's height) in each pixel of the horizon's row (row 5): the
# horizon moves down by H / (10 tan 20) rows per unit the look-at point rises (the eye
# rising moves it up as much), turning each pixel from the floor (0.8) to the background
HORIZON_RATE = -JUMP * H / (10 * math.tan(math.radians(20)))
# a sphere's shadow on a plane (the shadow edges' and the terms' tests)
SHADOW = """\
eye 0 3 6
lookat 0 0 0
fov 40
background 0.1 0.1 0.2
light 1 1 1 point 1.5 4 1
light 0.2 0.2 0.2 ambient
material 0.9 0.9 0.8 0.3 0.7 0 1 0 0 1
translate 0 -1 0
plane
reset
material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
translate 0.2 0 0
scale 0.8 0.8 0.8
sphere
"""

# a glass ball in front of a checkered wall: the checker seen through it moves with eta, and
# its rim compresses the checker (crossings that curve between two samples)
GLASS = """\
eye 0.05 0.03 4
fov 30
light 1 1 1 ambient
material 0.9 0.6 0.3 1 0 0 1 0 0 1
rotateX 90
translate 0 0 -3
checkerboard 0.5
plane
reset
material 1 1 1 0 0 0 1 0 0.9 1.5
sphere
"""


def loaded(mi, text, spp, key=None, value=None, **options):
    import raymitsuba

    scene = raymitsuba.load(text, width=options.pop("width", W), height=options.pop("height", H),
                            spp=spp, **options)
    if key is not None:
        scene.params[key] = typed(mi, scene.params[key], value)
        scene.params.update()
    return scene


def typed(mi, like, value):
    value = np.atleast_1d(np.asarray(value, np.float64))
    return type(like)(*map(float, value)) if len(value) > 1 else mi.Float(float(value[0]))


def value_of(scene, key):
    return np.array(scene.params[key].numpy(), np.float64).ravel()


def image(scene):
    import raymitsuba

    return raymitsuba.render(scene).numpy().astype(np.float64)


def finite_difference(mi, text, key, direction, h, spp=REFERENCE_SPP, **options):
    """d image / d (key along ``direction``) by central differences (H, W, 3)."""
    x0 = value_of(loaded(mi, text, 1, **dict(options)), key)
    u = np.asarray(direction, np.float64)
    plus = image(loaded(mi, text, spp, key, x0 + h * u, **dict(options)))
    minus = image(loaded(mi, text, spp, key, x0 - h * u, **dict(options)))
    return (plus - minus) / (2.0 * h)


def fine_difference(mi, text, key, direction, h, factor=4, **options):
    """:func:`finite_difference` with the step h / 5 on a (64 factor)^2 lattice: the image at
    ``factor`` times the width and height (64^2 samples per pixel), averaged over factor x
    factor blocks (see the module docstring)."""
    width, height = options.pop("width", W), options.pop("height", H)
    fine = finite_difference(mi, text, key, direction, h / 5.0, width=width * factor,
                             height=height * factor, **options)
    return fine.reshape(height, factor, width, factor, 3).mean(axis=(1, 3))


def forward(mi, text, key, direction, spp, **options):
    """d image / d (key along ``direction``) in forward mode (H, W, 3)."""
    import drjit as dr
    import raymitsuba

    scene = loaded(mi, text, spp, **options)
    params = scene.params
    dr.enable_grad(params[key])
    params.update()
    dr.set_grad(params[key], typed(mi, params[key], direction))
    result = raymitsuba.render(scene)
    dr.forward_to(result)
    return dr.grad(result).numpy().astype(np.float64)


def tangent_derivative(loaded, keys, before_pass=None):
    """The forward-mode derivative of ``loaded``'s image along ``keys``' tangents ({key:
    tangent}); ``before_pass(loaded)``: called between the render and the derivative pass."""
    import drjit as dr
    import raymitsuba

    params = loaded.params
    for key in keys:
        dr.enable_grad(params[key])
    params.update()
    for key, tangent in keys.items():
        dr.set_grad(params[key], type(params[key])(*tangent))
    image = raymitsuba.render(loaded)
    if before_pass is not None:
        before_pass(loaded)
    dr.forward_to(image)
    return dr.grad(image).numpy()


def reverse(mi, text, key, weights, spp, **options):
    """d sum(weights * image) / d key in reverse mode (the key's components)."""
    import drjit as dr
    import raymitsuba

    scene = loaded(mi, text, spp, **options)
    params = scene.params
    dr.enable_grad(params[key])
    params.update()
    result = raymitsuba.render(scene)
    dr.backward(dr.sum(result * mi.TensorXf(weights.astype(np.float32)), axis=None))
    return np.array(dr.grad(params[key]).numpy(), np.float64).ravel()


def assert_matches_finite_differences(mi, text, key, direction, h):
    """The forward-mode derivative of ``text``'s image along ``direction`` of ``key`` at k = 4
    against :func:`finite_difference` (step ``h``): the weighted sum's error (fixed random
    weights) within 5 % of the sum of the terms' sizes (measured 0.0-1.9 %), the per-pixel
    relative L2 within 15 % (measured per kind: each test module's docstring); and reverse
    mode's weighted sum the same."""
    import pytest

    reference = finite_difference(mi, text, key, direction, h)
    w = weights()
    grad = forward(mi, text, key, direction, 16)
    # the weighted sum's error, relative to the sum of the terms' sizes (a derivative of
    # both signs may nearly cancel in the sum itself)
    assert abs(np.sum(w * (grad - reference))) < 0.05 * np.sum(np.abs(w * reference))
    assert relative_l2(grad, reference) < 0.15
    # reverse mode gives the same weighted sum
    rev = reverse(mi, text, key, w, 16) @ np.asarray(direction)
    assert rev == pytest.approx(np.sum(w * grad), rel=1e-4)


def pairs_of_a_step(mi, monkeypatch, text):
    """A gradient step of ``text`` (spp 16) with respect to the eye: (the loaded scene, its
    boundary pass, the pairs that pass formed)."""
    import drjit as dr
    import raymitsuba

    from raymitsuba.plugins.whitted import boundary

    seen = []
    pairs = boundary.Boundary.pairs

    def kept(self):
        seen.append((self, pairs(self)))
        return seen[-1][1]

    monkeypatch.setattr(boundary.Boundary, "pairs", kept)
    scene = loaded(mi, text, 16)
    dr.enable_grad(scene.params["camera.eye"])
    scene.params.update()
    dr.backward(dr.sum(raymitsuba.render(scene), axis=None))
    return (scene, *seen[0])


def weights(height=H, width=W):
    return np.random.default_rng(13).random((height, width, 3))


def relative_l2(a, b):
    return float(np.linalg.norm(a - b) / np.linalg.norm(b))
