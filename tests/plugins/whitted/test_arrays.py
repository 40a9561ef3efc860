"""Host arrays handed to Dr.Jit (plugins/whitted/arrays.py): a private, aligned copy, so
that the kernels reading them are the same kernels whatever numpy's allocator did, and a
fit's gradient steps compile their kernels once.

A literal or an alignment in a kernel changes its hash, which is what is compared (Dr.Jit's
on-disk cache could hide a recompilation from the cache-hit flag alone; see
test_option_kernels.py)."""

from __future__ import annotations

import numpy as np

from support import load_ray


def launched(run):
    """The hashes of the kernels that ``run()`` launched (Dr.Jit's kernel history)."""
    import drjit as dr

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        dr.kernel_history()  # clears it
        run()
        return [k["hash"] for k in dr.kernel_history() if "operation_count" in k]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)


def at_offset(values, offset):
    """A float32 copy of ``values`` at ``offset`` bytes past a 128-byte aligned address."""
    buffer = np.empty(len(values) * 4 + 256, np.uint8)
    start = -buffer.ctypes.data % 128 + offset
    out = buffer[start:start + len(values) * 4].view(np.float32)
    out[:] = values
    return out


def test_a_host_array_is_a_copy_read_by_the_same_kernel_whatever_its_alignment(mitsuba):
    import drjit as dr

    from raymitsuba.plugins.whitted.arrays import jit_array

    mi = mitsuba
    values = np.linspace(0.0, 1.0, 1000, dtype=np.float32)

    def hash_of(make, offset):
        # a fresh kernel's input (a different constant each time would change the hash too)
        x = make(at_offset(values, offset))
        return launched(lambda: dr.eval(dr.sqrt(x) * 3.0 + 1.0))

    # numpy memory mapped as it is: 64-byte and 16-byte aligned buffers, two kernels
    assert hash_of(mi.Float, 0) != hash_of(mi.Float, 16)
    assert hash_of(lambda a: jit_array(mi.Float, a), 0) == \
        hash_of(lambda a: jit_array(mi.Float, a), 16)
    source = at_offset(values, 16)
    copy = jit_array(mi.Float, source)
    source[:] = 7.0  # the Dr.Jit array does not follow its source
    assert np.array_equal(copy.numpy(), values)


SCENE = """\
eye 0 3 6
lookat 0 0 0
fov 40
background 0.1 0.1 0.2
light 1 1 1 point 1.5 4 1
light 0.2 0.2 0.2 ambient
material 0.9 0.9 0.8 0.3 0.7 0 1 0 0 1
translate 0 -1 0
checkerboard 0.7
plane
reset
material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
translate 0.2 0 0
scale 0.8 0.8 0.8
sphere
"""


def test_a_second_gradient_step_of_a_geometry_key_compiles_no_kernel(mitsuba):
    # A fit's steps: render and backward with respect to a transform and the eye (silhouettes,
    # the shadow's edge, checker lines: every kind of boundary pair), each after new values.
    # The first two steps compile what the fit needs (the first moves turn the values loaded
    # as constants into data, and the kernels of one lane that follow them: measured, the
    # second step compiles one such kernel, the third none); every later step runs the
    # kernels of the one before (their hashes), none compiled anew. The values move the
    # edges by a fraction of a sample, so that the same kinds of pairs are found.
    import drjit as dr
    import raymitsuba

    mi = mitsuba
    scene = load_ray(SCENE, width=24, height=18, spp=16)
    params = scene.params
    keys = ("translate2.offset", "camera.eye")

    def step():
        image = raymitsuba.render(scene)
        dr.backward(dr.mean(dr.square(image), axis=None))
        dr.eval(*(dr.grad(params[key]) for key in keys))

    def set_values(shift):
        for key in keys:
            v = params[key]
            params[key] = mi.Point3f(v.x + shift, v.y, v.z - shift)
            dr.enable_grad(params[key])
        params.update()

    for _ in range(2):
        set_values(2e-3)
        step()
    set_values(2e-3)
    first = launched(step)
    set_values(2e-3)
    second = launched(step)
    # Every later step runs the kernels of the one before (how many times each may differ:
    # the switch's bisection takes its steps in rounds sized by how many pairs it has,
    # Terms.switch). (Before arrays.py, 13-28 kernels
    # were compiled anew at every step; later, now and then two: the rendered image handed
    # to Mitsuba mapped from numpy, 64-byte aligned or not by chance, and the adjoint of a
    # gather from a stack of pairs' values, which the LLVM backend expanded per thread with
    # the stack's size a constant of the kernel.)
    assert set(second) == set(first)
