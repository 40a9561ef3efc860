"""Gradients through ``mi.render`` (reverse and forward mode) against finite differences.

For every material parameter (color, ambient_mix, diffuse_mix, specular_mix,
phong_coeff, reflectivity, refractivity, ior) and every light parameter (color;
position of point and spot lights; direction of directional and spot lights;
the spot's shape_coefficient), on a small scene that exercises it, the
derivative of a weighted image sum

    f(x) = sum_pixels,channels w * image(x)      (w: fixed random weights, seeded)

along a fixed random unit direction u in parameter space is computed three ways:

* reverse mode: ``dr.backward(f)`` then ``dr.grad(param) . u``;
* forward mode: ``dr.set_grad(param, u)``, ``dr.forward_to(image)``, then the
  weighted sum of the image's tangent (and once with ``dr.forward(param)``);
* central finite differences (f(x + h u) - f(x - h u)) / 2h.

and reverse must match the finite difference within 1 % and forward mode within
1e-5 (the two AD modes compute the same sums in a different order in float32).

**The step.** h = 1e-3 * max(|x|, 1). The image is float32 but f is summed in
float64 on the host, so the only noise is the images' own float32 error: about
1e-7 relative per pixel for local shading, ~1e-6 where a pixel's value depends on
a float32 intersection distance (refracted paths). Divided by 2h that is at most
~1e-3 relative per pixel, and it averages down over the ~1700 terms of f; the
truncation error of the central difference is O(h^2) relative to the scale on
which the image curves (scene units ~1), ~1e-6. Both are far below the 1 %
tolerance; the measured errors are ~1e-5 .. 5e-4.

**Edges.** These derivatives ignore discontinuities (the integrator does not
sample silhouettes or shadow edges), while finite differences see them. So no
scene here lets an edge *move* under its parameter: material and light
parameters do not move silhouettes; lights sit near the camera so the
terminator (N.L = 0) stays out of view where it would carry a jump in the
specular term; the glass sphere fills the frame (no silhouette in view, no total
internal reflection in a sphere) in front of a wall lit by a light between the
two (no shadow of the sphere to be seen through it); the spot scene has no
occluder; and the shadow scene varies only kt, which scales the shadow without
moving its edge. Checkerboard edges do not move with any of these parameters.

Also tested: that ``scene.ray_intersect`` carries derivatives from the ray to
``si.t``, ``si.p``, the shading normal and ``si.uv``, on Mitsuba's analytic
sphere and on our meshes (Mitsuba 3.9.1 re-intersects differentiably: the
sphere recomputes ``t`` in ``compute_surface_interaction``, meshes run a
differentiable Moeller-Trumbore when the ray carries gradients). That is what
makes ``ior`` differentiable through the next hit point and its shading.
"""

from __future__ import annotations

import zlib

import numpy as np
import pytest

# -- scenes -------------------------------------------------------------------------------------
SCENES = {
    # One Phong sphere; a point light near the camera keeps the terminator out of view.
    "phong": """\
eye 0.1 0.05 5
fov 35
background 0.05 0.1 0.15
light 0.9 0.85 0.8 point 1.5 1 6
light 0.25 0.2 0.2 ambient
material 0.8 0.45 0.3 0.4 0.7 0.5 12 0 0 1
sphere
""",
    # A Phong ellipsoid (a mesh) under a directional light from the camera's side.
    "directional": """\
eye 0.1 0.05 5
fov 40
light 0.9 0.9 0.8 directional -0.3 -0.2 -1
light 0.1 0.1 0.1 ambient
material 0.3 0.7 0.5 0.3 0.6 0.4 8 0 0 1
scale 1.3 1 1
sphere
""",
    # A checkered floor (a raytextured surface) under a spotlight; nothing casts a shadow.
    "spot": """\
eye 0.3 3 4
lookat 0 0 0
fov 50
light 1 0.95 0.9 spotlight 0.5 3 0.5 -0.1 -1 -0.2 6
light 0.1 0.1 0.1 ambient
material 0.9 0.8 0.6 0.5 0.8 0.3 10 0 0 1
checkerboard 0.7
plane
""",
    # A glass sphere filling the frame (no silhouette in view) in front of a diffuse wall
    # lit by a point light between the two (so the sphere casts no shadow on the wall).
    "glass": """\
eye 0.05 0.03 4
fov 14
light 1 1 1 point 0.4 0.6 -2.2
light 0.1 0.1 0.1 ambient
material 0.9 0.6 0.3 0.2 0.8 0 1 0 0 1
rotateX 90
translate 0 0 -3
plane
reset
material 1 1 1 0 0 0 1 0 0.9 1.5
sphere
""",
    # A mirror chain: two mirror spheres reflecting each other and a lit floor.
    "mirror": """\
eye 0 1.5 6
lookat 0 0.3 0
fov 40
background 0.2 0.25 0.3
light 1 1 1 point 2 5 4
light 0.15 0.15 0.15 ambient
material 0.7 0.8 0.6 0.3 0.7 0 1 0 0 1
translate 0 -1 0
plane
reset
material 0.9 0.9 1 0.1 0.2 0.4 30 0.7 0 1
translate -1.05 0 0
sphere
reset
material 1 0.8 0.8 0.1 0.2 0.4 30 0.6 0 1
translate 1.05 0 0
sphere
""",
    # A floor in the shadow of a transparent blocker that is out of view: the floor sees
    # the blocker's kt only through its shadow rays (kt^2: the ray enters and leaves).
    "shadow": """\
eye 0 4 3
lookat 0 0 0
fov 40
light 1 1 1 point 0 8 0
light 0.1 0.1 0.1 ambient
material 0.8 0.8 0.7 0.2 0.8 0 1 0 0 1
plane
material 1 1 1 0 0 0 1 0 0.6 1.3
translate 0 6 0
scale 0.8 0.8 0.8
sphere
""",
}
# The glass scene with an ellipsoid: the refracted rays hit a smooth-normal mesh.
SCENES["glass_mesh"] = SCENES["glass"].replace("\nsphere\n", "\nscale 1 1.1 1\nsphere\n")

CASES = [
    # materials
    ("phong", "mat1.color"),
    ("phong", "mat1.ambient_mix"),
    ("phong", "mat1.diffuse_mix"),
    ("phong", "mat1.specular_mix"),
    ("phong", "mat1.phong_coeff"),
    ("directional", "mat1.phong_coeff"),
    ("spot", "mat1.color"),  # through the checkerboard's raytextured surface
    ("mirror", "mat2.reflectivity"),
    ("mirror", "mat3.reflectivity"),
    ("mirror", "mat1.color"),  # the floor, seen in the mirrors (and in their mutual reflections)
    ("glass", "mat2.refractivity"),
    ("glass", "mat2.ior"),
    ("glass_mesh", "mat2.ior"),
    ("glass", "mat1.diffuse_mix"),  # the wall, seen through the glass
    ("shadow", "mat2.refractivity"),  # only through the shadow rays' kt attenuation
    # lights
    ("phong", "light1.color"),  # point
    ("phong", "light1.position"),
    ("phong", "light2.color"),  # ambient
    ("directional", "light1.color"),
    ("directional", "light1.direction"),
    ("spot", "light1.color"),
    ("spot", "light1.position"),
    ("spot", "light1.direction"),
    ("spot", "light1.shape_coefficient"),
    ("glass", "light1.position"),  # lights the wall seen through the glass
    # the background
    ("phong", "background.color"),
]

SIZE = 24
REL_FD = 1e-2  # reverse and forward mode vs. central finite differences
REL_AD = 1e-5  # reverse vs. forward mode


@pytest.fixture(scope="module")
def mi():
    from raymitsuba.backend import mitsuba

    return mitsuba()


def load(name, size=SIZE, spp=1):
    import raymitsuba

    return raymitsuba.load(SCENES[name], width=size, height=size, spp=spp)


def as_vector(value):
    """A parameter's value as a float64 numpy vector."""
    return np.array(value.numpy(), dtype=np.float64).ravel()


def typed(mi, value_type, x):
    """``x`` (a numpy vector) as a parameter value of ``value_type``."""
    if value_type is mi.Float:
        return mi.Float(float(x[0]))
    return value_type(*(float(c) for c in x))


def weighted_sum(loaded, weights):
    """f = sum(w * image), rendered without gradients, summed in float64 on the host."""
    return float(np.sum(weights * rendered(loaded)))


def rendered(loaded):
    """The image, rendered without gradients, as float64."""
    import drjit as dr
    import raymitsuba

    with dr.suspend_grad():
        return raymitsuba.render(loaded).numpy().astype(np.float64)


def refinement(loaded):
    """(H, W) int: the grid side each pixel's value came from in the last anti-aliased
    render (0: its first pass)."""
    height, width = loaded.options.height, loaded.options.width
    side = np.zeros(height * width, int)
    for level in loaded.integrator.plan.levels:
        side[level.pixels] = level.n
    return side.reshape(height, width)


def derivatives(mi, loaded, key, seed, use_forward=False, same_refinement=False):
    """(finite difference, reverse mode, forward mode) derivatives of the weighted image sum
    along a random unit direction in the parameter's space (along (1, ..., 1) with
    ``use_forward``: the tangent that ``dr.forward(param)`` seeds).

    ``same_refinement`` (anti-aliasing): only the pixels that the renders at x -+ h refine
    alike count (weight 0 on the others, for every derivative). Which pixels are refined
    is a detached decision, a step of the image where a pixel's contrast crosses the
    threshold between x - h and x + h: a finite difference across it is not a derivative."""
    import drjit as dr
    import raymitsuba

    params = loaded.params
    value_type = type(params[key])
    x0 = as_vector(params[key])
    rng = np.random.default_rng(seed)
    height, width = loaded.options.height, loaded.options.width
    weights = rng.uniform(0.5, 1.5, (height, width, 3))
    u = rng.normal(size=x0.shape)
    u /= np.linalg.norm(u)
    if use_forward:  # dr.forward(param) sets the tangent to 1 in every component
        u = np.ones_like(x0)

    def set_value(x):
        params[key] = typed(mi, value_type, x)
        params.update()

    h = 1e-3 * max(np.linalg.norm(x0), 1.0)
    set_value(x0 + h * u)
    image_plus = rendered(loaded)
    plan_plus = refinement(loaded) if same_refinement else None
    set_value(x0 - h * u)
    image_minus = rendered(loaded)
    if same_refinement:
        weights = weights * (refinement(loaded) == plan_plus)[..., None]
    finite = (np.sum(weights * image_plus) - np.sum(weights * image_minus)) / (2.0 * h)

    w = mi.TensorXf(weights.astype(np.float32))
    # Reverse mode.
    set_value(x0)
    dr.enable_grad(params[key])
    params.update()
    dr.backward(dr.sum(raymitsuba.render(loaded) * w))
    reverse = float(as_vector(dr.grad(params[key])) @ u)
    dr.disable_grad(params[key])

    # Forward mode.
    set_value(x0)
    dr.enable_grad(params[key])
    params.update()
    if use_forward:  # dr.forward(param): tangent 1, propagated to everything downstream
        image = raymitsuba.render(loaded)
        dr.forward(params[key])
    else:
        dr.set_grad(params[key], typed(mi, value_type, u))
        image = raymitsuba.render(loaded)
        dr.forward_to(image)
    forward = float(np.sum(weights * dr.grad(image).numpy().astype(np.float64)))
    dr.disable_grad(params[key])
    return finite, reverse, forward


def seed_of(*names):
    return zlib.crc32(":".join(names).encode())


@pytest.mark.parametrize("scene,key", CASES, ids=[f"{s}-{k}" for s, k in CASES])
def test_gradient_matches_finite_differences(mi, scene, key):
    loaded = load(scene)
    finite, reverse, forward = derivatives(mi, loaded, key, seed_of(scene, key))
    # The parameter must actually matter here (no vacuous pass).
    assert abs(finite) > 0.1, (scene, key, finite)
    assert abs(reverse - finite) <= REL_FD * abs(finite), (scene, key, finite, reverse)
    assert abs(forward - finite) <= REL_FD * abs(finite), (scene, key, finite, forward)
    assert abs(reverse - forward) <= REL_AD * abs(forward), (scene, key, reverse, forward)


@pytest.mark.parametrize("scene,key", [("glass", "mat2.ior"), ("spot", "light1.direction")])
def test_forward_with_dr_forward(mi, scene, key):
    """``dr.forward(param)`` (not only ``dr.forward_to``) reaches the image of mi.render."""
    finite, reverse, forward = derivatives(mi, load(scene), key, seed_of(scene, key, "f"),
                                           use_forward=True)
    assert abs(forward - finite) <= REL_FD * abs(finite)
    assert abs(reverse - forward) <= REL_AD * abs(forward)


def test_several_samples_per_pixel(mi):
    """The per-pixel average of several samples (spp = 4) is differentiated too."""
    finite, reverse, forward = derivatives(mi, load("glass", size=16, spp=4), "mat2.ior",
                                           seed_of("glass", "spp4"))
    assert abs(reverse - finite) <= REL_FD * abs(finite)
    assert abs(reverse - forward) <= REL_AD * abs(forward)


def test_all_parameters_at_once(mi):
    """Reverse mode with several parameters enabled gives each the same gradient as a
    forward pass along that parameter alone."""
    import drjit as dr
    import raymitsuba

    keys = ["mat2.ior", "mat2.refractivity", "mat1.color", "light1.position", "light2.color"]
    loaded = load("glass", size=16)
    params = loaded.params
    weights = mi.TensorXf(np.random.default_rng(7).uniform(0.5, 1.5, (16, 16, 3)).astype(np.float32))
    for key in keys:
        dr.enable_grad(params[key])
    params.update()
    dr.backward(dr.sum(raymitsuba.render(loaded) * weights))
    grads = {key: as_vector(dr.grad(params[key])) for key in keys}
    for key in keys:
        dr.disable_grad(params[key])
    for key in keys:
        for component in range(len(grads[key])):
            tangent = np.zeros(len(grads[key]))
            tangent[component] = 1.0
            dr.enable_grad(params[key])
            params.update()
            dr.set_grad(params[key], typed(mi, type(params[key]), tangent))
            image = raymitsuba.render(loaded)
            dr.forward_to(image)
            forward = float(np.sum(weights.numpy() * dr.grad(image).numpy(), dtype=np.float64))
            dr.disable_grad(params[key])
            assert forward == pytest.approx(grads[key][component], rel=1e-5, abs=1e-6), (key, component)


# -- the intersection's derivatives -------------------------------------------------------------
@pytest.mark.parametrize("body", ["sphere", "scale 1 1.2 0.9\nsphere"], ids=["analytic", "mesh"])
def test_ray_intersect_carries_ray_derivatives(mi, body):
    """d(si.t, si.p, shading normal, si.uv)/d(ray direction) from Mitsuba's ray_intersect
    match finite differences, for the analytic sphere and for a mesh (the ellipsoid)."""
    import drjit as dr
    import raymitsuba

    loaded = raymitsuba.load(f"light 1 1 1 point 0 0 5\n{body}\n", width=8, height=8)
    scene = loaded.scene
    origin = mi.Point3f(0.0, 0.0, 5.0)
    base = np.array([[0.1, 0.12, -1.0], [-0.05, 0.15, -1.0], [0.13, -0.02, -1.0]])
    tangent = np.array([0.3, -0.7, 0.1])

    def hit(direction):
        ray = mi.Ray3f(origin, dr.normalize(direction))
        si = scene.ray_intersect(ray)
        return mi.Float(si.t), mi.Point3f(si.p), mi.Vector3f(si.sh_frame.n), mi.Point2f(si.uv)

    theta = mi.Float(0.0)
    dr.enable_grad(theta)
    d = mi.Vector3f(*(mi.Float(base[:, c]) + theta * tangent[c] for c in range(3)))
    outputs = hit(d)
    dr.set_grad(theta, 1.0)
    dr.forward_to(*outputs)
    ad = [np.array(dr.grad(o).numpy(), dtype=np.float64) for o in outputs]
    h = 1e-3
    with dr.suspend_grad():
        plus = hit(mi.Vector3f(*(mi.Float(base[:, c] + h * tangent[c]) for c in range(3))))
        minus = hit(mi.Vector3f(*(mi.Float(base[:, c] - h * tangent[c]) for c in range(3))))
    for name, a, p, m in zip(("t", "p", "n", "uv"), ad, plus, minus):
        fd = (np.array(p.numpy(), np.float64) - np.array(m.numpy(), np.float64)) / (2 * h)
        assert np.abs(fd).max() > 1e-2, name  # the quantity does move with the ray
        np.testing.assert_allclose(a, fd, rtol=2e-3, atol=2e-3 * np.abs(fd).max(), err_msg=name)


def test_a_key_the_image_does_not_depend_on_has_the_derivative_zero(mi):
    """A sphere turned about its centre changes no pixel: its angle's derivative is 0 in
    both modes (not Dr.Jit's error for a graph that does not reach the parameter)."""
    import drjit as dr
    import raymitsuba

    text = ("eye 0 0 5\nlight 1 1 1 point 2 3 1\n"
            "material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1\nrotateY 30\nsphere\n")
    loaded = raymitsuba.load(text, width=8, height=6, spp=4)
    params = loaded.params
    dr.enable_grad(params["rotateY1.angle"])
    params.update()
    dr.backward(dr.sum(raymitsuba.render(loaded), axis=None))
    assert dr.grad(params["rotateY1.angle"])[0] == 0.0
    dr.set_grad(params["rotateY1.angle"], 1.0)
    tangent = dr.forward_to(raymitsuba.render(loaded))
    assert np.all(tangent.numpy() == 0.0)
