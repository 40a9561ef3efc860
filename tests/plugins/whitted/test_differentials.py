"""Ray differentials through specular bounces (plugins/whitted/differentials.py): the children's
offset rays against the closed forms of a mirror and a lens to first order, and a checkerboard
seen in a mirror ball averaged over its footprint in an anti-aliased render."""

import numpy as np
import pytest

from support import render_ray

DELTA = 1e-3  # the offset rays' distance from the main ray: first order, within float32


@pytest.fixture(scope="module")
def unit_sphere(mitsuba):
    """(tracer, scene, its terms): a sphere of radius 1 at the origin (seen along -z)."""
    from support import load_ray

    loaded = load_ray("eye 0 0 10\nmaterial 1 1 1  0 1 0 1  1 0 1.5\nsphere\n", aa=0.02)
    tracer = loaded.integrator.tracer
    return tracer, loaded.scene, tracer.scene_terms(loaded.scene)


def _children(mi, tracer, scene, terms, ray, eta):
    """The reflected and refracted children (RayDifferential3f) of ``ray``'s hit, entering
    a medium of index ``eta``."""
    import drjit as dr

    from raymitsuba.plugins.whitted.differentials import offset_children
    from raymitsuba.plugins.whitted.tree import reflect, refract

    si = tracer.intersect(scene, terms.geometry, ray, coherent=False)
    hit = si.is_valid()
    assert hit.numpy().all()
    n, v = tracer.facing_normal(si, ray), -ray.d
    eta_ratio = mi.Float(1.0 / eta)
    d_t, _ = refract(v, n, eta_ratio)
    children = (tracer.spawn_ray(si, reflect(v, n)), tracer.spawn_ray(si, d_t))
    reflected, refracted = offset_children(ray, si, n, eta_ratio, children,
                                           terms.geometry.normal_at, hit, reflect, refract)
    dr.eval(reflected, refracted)
    return reflected, refracted


def _parallel_pair(mi, offset):
    """A ray down the -z axis from z = 10 and its offset ray ``offset`` away, parallel."""
    ray = mi.RayDifferential3f(mi.Ray3f(mi.Point3f(0, 0, 10), mi.Vector3f(0, 0, -1)))
    ray.o_x, ray.d_x = mi.Point3f(offset, 0, 10), mi.Vector3f(0, 0, -1)
    ray.o_y, ray.d_y = mi.Point3f(0, offset, 10), mi.Vector3f(0, 0, -1)
    ray.has_differentials = True
    return ray


def _unit(v):
    v = np.array(v, np.float64).ravel()
    return v / np.linalg.norm(v)


def test_a_mirror_ball_spreads_parallel_rays_by_twice_their_offset_over_its_radius(
        mitsuba, unit_sphere):
    """Parallel rays d apart at normal incidence on a mirror of radius r leave at an angle
    2 asin(d / r) (2 d / r to first order): here r = 1."""
    reflected, _ = _children(mitsuba, *unit_sphere, _parallel_pair(mitsuba, DELTA), 1.5)
    for axis, component in (("d_x", 0), ("d_y", 1)):
        spread = _unit(getattr(reflected, axis))[component]
        assert spread == pytest.approx(2 * DELTA, rel=1e-3)
    # the offset ray leaves where the offset ray met the tangent plane, lifted as the child is
    assert np.array(reflected.o_x).ravel()[:2] == pytest.approx([DELTA, 0], abs=1e-6)
    assert np.array(reflected.d).ravel() == pytest.approx([0, 0, 1], abs=1e-7)


def test_a_lens_surface_bends_parallel_rays_by_snells_law(mitsuba, unit_sphere):
    """Entering glass of index 1.5 at normal incidence on a sphere of radius 1, a parallel ray
    d off the axis meets a normal tilted by asin(d) and leaves at asin(d / 1.5) from it:
    towards the axis by asin(d) - asin(d / 1.5), d / 3 to first order."""
    _, refracted = _children(mitsuba, *unit_sphere, _parallel_pair(mitsuba, DELTA), 1.5)
    want = -np.sin(np.arcsin(DELTA) - np.arcsin(DELTA / 1.5))
    assert _unit(refracted.d_x)[0] == pytest.approx(want, rel=1e-3)
    assert _unit(refracted.d_y)[1] == pytest.approx(want, rel=1e-3)


def test_a_plane_mirror_keeps_the_footprints_spread(mitsuba):
    """A flat mirror has no curvature: the reflected offset ray is the mirror image of the
    offset ray, whatever its angle."""
    from support import load_ray

    loaded = load_ray("eye 0 3 5\nmaterial 1 1 1  0 1 0 1  1 0 1\nplane\n", aa=0.02)
    tracer = loaded.integrator.tracer
    terms = tracer.scene_terms(loaded.scene)
    ray = mitsuba.RayDifferential3f(mitsuba.Ray3f(mitsuba.Point3f(0, 3, 5),
                                                  mitsuba.Vector3f(*_unit([0, -3, -5]).tolist())))
    spread = _unit([0.01, -3, -5.02])
    ray.o_x, ray.d_x = mitsuba.Point3f(0, 3, 5), mitsuba.Vector3f(*spread.tolist())
    ray.o_y, ray.d_y = ray.o_x, ray.d_x
    ray.has_differentials = True
    reflected, _ = _children(mitsuba, tracer, loaded.scene, terms, ray, 1.0)
    assert _unit(reflected.d_x) == pytest.approx(spread * [1, -1, 1], abs=1e-6)


MIRROR_BALL = """\
eye 0 1.2 4
lookat 0 0.6 0
fov 30
background 0.5 0.6 0.8
light 0.3 0.3 0.3 ambient
light 0.8 0.8 0.8 directional -0.3 -1 -0.4
material 0.9 0.9 0.9  0.3 0.8 0 1  0 0 1
checkerboard 0.15
plane
checkerboard -1
material 0 0 0  0 0 0 1  1 0 1
translate 0 0.7 0
scale 0.7 0.7 0.7
sphere
"""


def test_a_board_seen_in_a_mirror_ball_is_averaged_over_the_reflected_footprint(mitsuba):
    """The mirror ball's pixels in the first pass of an anti-aliased render: each camera
    ray's footprint carried through the reflection averages the squares it sees there,
    which crowd towards the ball's rim. Measured over the ball's 357 pixels: mean error
    0.027 against a 1024-sample render, where the footprint left at the mirror (the
    reflected board point sampled, as before differentials.py) is off by 0.089, as the
    pixel centre's point sample is; away from the rim 0.0075 against 0.0146."""
    import raymitsuba

    width, height = 48, 36
    reference = render_ray(MIRROR_BALL, width, height, spp=1024)
    plain = render_ray(MIRROR_BALL, width, height)
    loaded = raymitsuba.load(MIRROR_BALL, width=width, height=height, aa=0.02)
    integrator = loaded.integrator
    integrator.aa = -1.0  # the first pass alone (its footprints), no refinement
    try:
        first = np.array(integrator.render_array(loaded.scene))
    finally:
        integrator.aa = 0.02
    # the ball's pixels: those whose centre sees the ball (black itself: only its reflection)
    plane_only = render_ray(MIRROR_BALL.split("material 0 0 0")[0], width, height)
    ball = np.abs(plain - plane_only).max(axis=-1) > 0
    assert ball.sum() > 100
    error = np.abs(first - reference).max(axis=-1)[ball].mean()
    point = np.abs(plain - reference).max(axis=-1)[ball].mean()
    assert error < 0.5 * point
