"""The geometry's and the camera's keys attached to rays and hits (plugins/whitted/geometry_ad.py):
here, the ``joint`` their derivatives pass through (the module docstring's "Cost"). What the
keys' derivatives are worth is pinned against finite differences elsewhere
(tests/plugins/whitted/boundary/, tests/test_parameters.py)."""

from __future__ import annotations

import pytest

LANES = 4096


def wide_kernels(run):
    """The operation counts of the kernels of ``LANES`` lanes that ``run()`` launched
    (Dr.Jit's kernel history)."""
    import drjit as dr

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # clears it
        run()
        return [k["operation_count"] for k in dr.kernel_history()
                if k.get("size") == LANES and "operation_count" in k]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


def rays_of(mitsuba, key, through_joint):
    """A 1-lane key spread over LANES lanes (as the eye over the camera rays), then through
    the joint or not."""
    import drjit as dr

    from raymitsuba.plugins.whitted.geometry_ad import joint

    lanes = dr.arange(mitsuba.Float, LANES) * (1.0 / LANES)
    spread = key + mitsuba.Vector3f(lanes, dr.square(lanes), 1.0)
    return joint(spread) if through_joint else spread


def image_of(mitsuba, rays):
    """Something costly of each lane, as an image is of its rays."""
    import drjit as dr

    value = mitsuba.Float(0.0)
    for i in range(8):
        value += dr.sin(rays.x * (i + 1)) * dr.cos(rays.y - i) + dr.exp(-dr.square(rays.z * i))
    return value


@pytest.mark.parametrize("through_joint", [False, True])
def test_the_joint_changes_neither_value_nor_derivative(mitsuba, through_joint):
    import drjit as dr
    import numpy as np

    key = mitsuba.Point3f(0.3, -0.2, 0.5)
    dr.enable_grad(key)
    value = image_of(mitsuba, rays_of(mitsuba, key, through_joint))
    dr.backward(dr.sum(value))
    reverse = np.array([dr.grad(key)[i][0] for i in range(3)])
    # the same without AD, and forward mode along x
    plain = image_of(mitsuba, rays_of(mitsuba, dr.detach(key), False))
    assert np.array_equal(value.numpy(), plain.numpy())  # bit for bit
    key2 = mitsuba.Point3f(0.3, -0.2, 0.5)
    dr.enable_grad(key2)
    dr.set_grad(key2, mitsuba.Point3f(1.0, 0.0, 0.0))
    tangent = dr.forward_to(image_of(mitsuba, rays_of(mitsuba, key2, through_joint)))
    # forward and reverse: the same sum, to float32 summation order
    assert dr.sum(tangent)[0] == pytest.approx(reverse[0], rel=1e-5)
    assert np.all(np.isfinite(reverse)) and np.all(reverse != 0)


def test_a_three_vector_key_evaluates_the_lanes_derivative_once(mitsuba):
    """Without the joint, the sums of the key's components are kernels that each compute
    the lanes' whole derivative (two of them here: Dr.Jit fuses two of the three sums);
    through it, one kernel computes it and the sums read it (measured: [618, 627] operations
    without, [762] through it)."""
    import drjit as dr

    def backward(through_joint):
        key = mitsuba.Point3f(0.3, -0.2, 0.5)
        dr.enable_grad(key)
        value = image_of(mitsuba, rays_of(mitsuba, key, through_joint))
        dr.eval(value)
        return wide_kernels(lambda: (dr.backward(dr.sum(value)), dr.eval(dr.grad(key))))

    without = backward(False)
    through = backward(True)
    assert len(without) >= 2  # (each computes the whole derivative again)
    assert sum(1 for ops in through if ops >= min(without)) == 1, (without, through)
