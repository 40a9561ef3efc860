"""The ``raybackground`` emitter (plugins/background.py): its one parameter, and that it is the
color of every ray that hits nothing."""

import numpy as np
import pytest

from support import render_ray


def test_color_defaults_to_black_and_is_a_differentiable_parameter(mitsuba):
    mi = mitsuba
    assert np.array(mi.load_dict({"type": "raybackground"}).color).ravel().tolist() == [0, 0, 0]
    background = mi.load_dict({"type": "raybackground", "color": mi.ScalarColor3f(0.2, 0.4, 0.6)})
    params = mi.traverse(background)
    assert list(params.keys()) == ["color"]
    assert np.array(params["color"]).ravel() == pytest.approx([0.2, 0.4, 0.6])
    assert not params.flags("color") & int(mi.ParamFlags.NonDifferentiable)


def test_every_pixel_of_an_empty_scene_is_the_background():
    image = render_ray("background 0.2 0.4 0.6\n", width=6, height=4)
    np.testing.assert_array_equal(image, np.broadcast_to(np.float32([0.2, 0.4, 0.6]), (4, 6, 3)))


def test_rays_that_miss_the_objects_see_the_background_unlit():
    # a lit sphere in the middle; the corners miss it: background there, whatever the lights
    image = render_ray("background 0.3 0.1 0.2\nlight 0.5 0.5 0.5 ambient\nsphere\n", width=8, height=8)
    for corner in (image[0, 0], image[0, -1], image[-1, 0], image[-1, -1]):
        np.testing.assert_array_equal(corner, np.float32([0.3, 0.1, 0.2]))
    assert image[4, 4].tolist() == [0.5, 0.5, 0.5]  # the sphere: ka 1 * C 1 * ambient 0.5
