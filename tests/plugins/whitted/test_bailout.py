"""The bailout (plugins/whitted/bailout.py): the bound of what a subtree can return, in closed
form from a scene's lights and materials; the bounded rule as the default, within one 8-bit
step of the exact tree on the gallery's deep scenes; the exact tree where no bound is finite."""

import math

import numpy as np
import pytest

from support import load_ray

# One material: color (1, 0.5, 0.25), ka 0.3, kd 0.6, ks 0.2, n 10, kr 0.3, kt 0.4.
SCENE = ("background 0.1 0.2 0.3\n"
         "light 0.2 0.2 0.2 ambient\n"
         "light 0.5 0.6 0.7 point 0 5 5\n"
         "light 0.4 0.4 0.4 directional 0 -1 -1\n"
         "material 1 0.5 0.25  0.3 0.6 0.2 10  0.3 0.4 1.5\n"
         "sphere\n")
# L: per channel A ka C + (I_point + I_dir) (kd C + ks), the largest being red:
# 0.2 * 0.3 * 1 + (0.5 + 0.4) * (0.6 * 1 + 0.2) = 0.78 (green 0.53, blue 0.4, background 0.3)
LOCAL = 0.78
WEIGHT = 0.3 + 0.4  # kr + kt


def terms_of(loaded):
    tracer = loaded.integrator.tracer
    return tracer, tracer.scene_terms(loaded.scene)


def test_the_bound_of_a_scene_from_its_lights_and_materials(mitsuba):
    from raymitsuba.plugins.whitted import bailout

    tracer, terms = terms_of(load_ray(SCENE, max_depth=3))
    # float32 parameters: a relative 1e-6
    assert bailout.local_bound(terms, tracer.max_shadow_crossings) == pytest.approx(LOCAL, rel=1e-6)
    assert bailout.weight_bound(terms) == pytest.approx(WEIGHT, rel=1e-6)
    # a child of generation g may bounce 3 - g more times: B(d) = L (1 + w + ... + w^d)
    limits = bailout.path_weight_limits(None, terms, 3, tracer.max_shadow_crossings)
    expected = [bailout.SUBTREE_ERROR / (LOCAL * sum(WEIGHT ** i for i in range(3 - g + 1)))
                for g in (1, 2, 3)]
    assert limits == pytest.approx(expected, rel=1e-6)


def test_the_option_chooses_the_rule(mitsuba):
    from raymitsuba.plugins.whitted import bailout

    tracer, terms = terms_of(load_ray(SCENE, max_depth=3))
    assert bailout.path_weight_limits(0.0, terms, 3, 16) is None  # exact
    assert bailout.path_weight_limits(1e-3, terms, 3, 16) == [1e-3] * 3  # a fixed path weight


def test_subtree_bound_is_the_geometric_sum_for_any_weight():
    from raymitsuba.plugins.whitted.bailout import subtree_bound

    for w in (0.0, 0.5, 1.0, 1.5):
        for d in (0, 1, 5):
            assert subtree_bound(2.0, w, d) == pytest.approx(2.0 * sum(w ** i for i in range(d + 1)))


@pytest.mark.parametrize("scene, depth", [("scenes/whitted.ray", 10),
                                          ("scenes/benchmark_glass.ray", 10)])
def test_the_bounded_default_is_within_an_8_bit_step_of_the_exact_tree(mitsuba, scene, depth):
    # Each subtree left out adds at most 1/1020 to its pixel; a pixel of these scenes loses
    # few, most far below their bound: no pixel moves by a whole 8-bit step (1/255).
    bounded = load_ray(open(scene).read(), 48, 36, max_depth=depth)
    exact = load_ray(open(scene).read(), 48, 36, max_depth=depth)
    exact.integrator.tracer.bailout = 0.0
    a = bounded.integrator.render_array(bounded.scene)
    b = exact.integrator.render_array(exact.scene)
    assert np.abs(a - b).max() <= 1 / 255
    assert bounded.integrator.rays_traced < 0.8 * exact.integrator.rays_traced


def test_no_finite_bound_means_the_exact_tree(mitsuba):
    # A negative Phong exponent (a fit may reach one): the highlight has no bound
    from raymitsuba.plugins.whitted import bailout

    loaded = load_ray(SCENE, max_depth=3)
    params = mitsuba.traverse(loaded.scene)
    params["mat1.phong_coeff"] = -1.0
    params.update()
    tracer, terms = terms_of(loaded)
    assert math.isinf(bailout.local_bound(terms, 16))
    assert bailout.path_weight_limits(None, terms, 3, 16) is None
