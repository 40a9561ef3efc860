"""Option values a user changes from run to run are data of the kernels, not constants
compiled into them: a new ``bailout``, or a new bound of the default one (tree.py,
bailout.py), or anti-aliasing threshold (antialias.py)
launches the very kernels of the render before (the same Dr.Jit kernels, by hash, all
from the cache), and a deeper ``max_depth`` runs more generations of kernels already
compiled (integrator.py).

A literal in a kernel changes its hash, which is what is compared; Dr.Jit's on-disk cache
could hide a recompilation from the cache-hit flag alone. The two values of each pair are
chosen to leave the same work (the same rays in each generation, the same pixels refined),
so that the kernels launched can only differ by what the values themselves put in them. The
scene is test_scale's row of analytic glass and mirror-ish spheres: no meshes, whose Mitsuba
kernels may come in a few variants depending on where a buffer lands in memory."""

import pytest

from support import kernels_launched
from test_scale import spheres

# kr 0.2, kt 0.5 everywhere: path weights are products of 0.2, 0.5 and 0.7 (kr + kt on
# total reflection); none lies between 0.0030 and 0.0035 (0.0028 and 0.00392 the nearest
# at these depths), so those two bailouts prune the same rays
SCENE = spheres(5)
SIZE = dict(width=12, height=9)


def render(scene=SCENE, **options):
    """(kernels launched, the integrator) of a render of ``scene`` with ``options``."""
    import raymitsuba

    loaded = raymitsuba.load(scene, **SIZE, **options)
    return kernels_launched(loaded), loaded.integrator


def hashes(kernels):
    return [k["hash"] for k in kernels]


def test_a_new_bailout_compiles_no_kernel(mitsuba):
    before, first = render(max_depth=4, bailout=0.0030)
    after, second = render(max_depth=4, bailout=0.0035)
    assert second.rays_per_generation == first.rays_per_generation  # the same tree
    assert hashes(after) == hashes(before)
    assert all(k["cache_hit"] for k in after)


def test_a_new_anti_aliasing_threshold_compiles_no_kernel(mitsuba):
    before, first = render(max_depth=2, aa=0.0200)
    after, second = render(max_depth=2, aa=0.0203)
    assert [len(level.pixels) for level in second.plan.levels] == \
        [len(level.pixels) for level in first.plan.levels]  # the same refinement
    assert hashes(after) == hashes(before)
    assert all(k["cache_hit"] for k in after)


@pytest.mark.parametrize("bailout", [0.0, 0.0030])
def test_a_deeper_tree_compiles_no_kernel(mitsuba, bailout):
    # depth 3, then 5: the two more generations run the kernels of the generations before
    before, _ = render(max_depth=3, bailout=bailout)
    after, _ = render(max_depth=5, bailout=bailout)
    assert set(hashes(after)) <= set(hashes(before))
    assert all(k["cache_hit"] for k in after)


def test_a_new_bound_of_the_bounded_bailout_compiles_no_kernel(mitsuba):
    # The default rule's limits follow the scene's lights (bailout.py): a brighter light, new
    # limits, the same kernels
    brighter = SCENE.replace("light 1 1 1 point", "light 1.25 1.25 1.25 point")
    assert brighter != SCENE
    before, first = render(max_depth=4)
    after, second = render(brighter, max_depth=4)
    assert second.rays_per_generation == first.rays_per_generation  # the same tree
    assert hashes(after) == hashes(before)
    assert all(k["cache_hit"] for k in after)
