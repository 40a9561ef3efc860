"""Which pixels an adjoint pass traces (plugins/whitted/support.py): where only shapes move,
the pixels with a sample on a moving shape, found from the primal render's recorded first
hits -- the same pixels Mitsuba's own intersection gives, and the same derivative, bit for
bit, as the pass over every pixel; elsewhere (the camera, a light or a material moving, a
mirror in the scene) every pixel, the keys recorded by the adjoint pass as before."""

from __future__ import annotations

import numpy as np
import pytest
from support_edges import SPHERE_ON_CHECKER as SCENE
from support_edges import tangent_derivative as derivative

WIDTH, HEIGHT, SPP = 24, 18, 16
MOVE = {"translate2.offset": (0.6, -0.8, 0.0)}  # the ball (its tangent, forward mode)


def load():
    import raymitsuba

    return raymitsuba.load(SCENE, width=WIDTH, height=HEIGHT, spp=SPP)


def pixels_seeing(mi, loaded, shape):
    """The pixels with a sample whose first hit is ``shape``, by Mitsuba's own intersection
    of the camera rays (their numbers, increasing)."""
    import drjit as dr

    from raymitsuba.plugins.whitted.camera import camera_rays

    scene = loaded.scene
    rays = camera_rays(scene.sensors()[0], WIDTH, HEIGHT, SPP)
    pi = scene.ray_intersect_preliminary(mi.Ray3f(rays), coherent=True)
    hit = (pi.is_valid() & (dr.reinterpret_array(mi.UInt32, pi.shape)
                            == dr.reinterpret_array(mi.UInt32, mi.ShapePtr(shape)))).numpy()
    return np.flatnonzero(hit.reshape(-1, SPP).any(axis=1))


def test_only_the_pixels_a_moving_shape_covers_are_traced_with_the_same_derivative(
        mitsuba, monkeypatch):
    from raymitsuba.plugins.whitted import support

    traced = []
    interior_pixels = support.interior_pixels

    def spied(*args):
        traced.append(interior_pixels(*args))
        return traced[-1]

    monkeypatch.setattr(support, "interior_pixels", spied)
    loaded = load()
    restricted = derivative(loaded, MOVE)
    ball, = (s for s in loaded.scene.shapes() if s.class_name() == "Sphere")
    expected = pixels_seeing(mitsuba, loaded, ball)
    assert len(traced) == 1 and np.array_equal(traced[0], expected)
    assert 0 < len(expected) < WIDTH * HEIGHT / 2

    def forget(loaded):  # (no keys from the primal: the pass records them, over every pixel)
        loaded.integrator.keys = None

    whole = derivative(load(), MOVE, forget)
    assert len(traced) == 1  # (not called: every pixel traced)
    assert np.array_equal(restricted, whole) and np.count_nonzero(whole) > 0


# a mirror floor under the ball: a sample on the floor sees the ball's reflection
MIRROR = SCENE.replace("0.4 0.6 0 1 0 0 1", "0.4 0.6 0 1 0.5 0 1")


@pytest.mark.parametrize("text,keys", [
    (SCENE, {**MOVE, "camera.eye": (0.0, 0.1, 0.0)}),
    (SCENE, {**MOVE, "light1.position": (0.0, 1.0, 0.0)}),
    (SCENE, {**MOVE, "mat2.color": (1.0, 0.0, 0.0)}),
    (MIRROR, MOVE),
])
def test_every_pixel_is_traced_where_more_than_the_shapes_move(mitsuba, text, keys):
    """The camera, a light or a material moving with the ball, or a mirror that shows the
    ball in other pixels: the primal render records no keys, the pass traces every pixel
    (and records them)."""
    import drjit as dr
    import raymitsuba

    from raymitsuba.plugins.whitted import support

    assert MIRROR != SCENE
    loaded = raymitsuba.load(text, width=WIDTH, height=HEIGHT, spp=SPP)
    params = loaded.params
    for key in keys:
        dr.enable_grad(params[key])
    params.update()
    raymitsuba.render(loaded)
    integrator = loaded.integrator
    assert integrator.keys is None and integrator.recording is not None
    assert not support.only_shapes_move(integrator.tracer, loaded.scene,
                                        integrator.tracer.surfaces)


def test_a_ball_alone_moving_is_only_shapes_moving(mitsuba):
    import drjit as dr
    import raymitsuba

    from raymitsuba.plugins.whitted import support

    loaded = load()
    dr.enable_grad(loaded.params["translate2.offset"])
    loaded.params.update()
    raymitsuba.render(loaded)
    integrator = loaded.integrator
    assert integrator.keys is not None
    assert support.only_shapes_move(integrator.tracer, loaded.scene, integrator.tracer.surfaces)
