"""Scenes of many objects (issue 7): kernels that do not depend on the scene's contents, and
exact gradients of one material among hundreds of objects.

The scenes come from :func:`grid_scene`: n objects on a grid, each with its own material,
one in five glass, one in seven a (non-uniformly) scaled sphere -- a smooth mesh --, over a
checkered floor, behind a big glass ball near the camera whose material is the one under
test. Rendered at a tiny size: the code paths, not the figures (those are in the report of
the scale benchmark).

Every material here differs from the others: ``mi.load_dict`` merges identical ones (its
``optimize``), and the later one's ``mat{i}`` keys would be missing."""

import math

import numpy as np
import pytest

from support import kernels_launched
from test_gradients import derivatives


def grid_scene(n, lights=1, shared=False):
    """.RAY text: the test ball (material 1), then n objects with materials 2 .. n + 1
    (``shared``: all n objects under material 2)."""
    side = max(1, math.ceil(math.sqrt(n)))
    lines = ["eye 0 0.5 %g" % (1.6 * side + 2), "lookat 0 0 0", "fov 45", "background 0.1 0.1 0.2",
             "light 0.2 0.2 0.2 ambient"]
    lines += ["light 0.7 0.7 0.6 point %g %g %g" % (2 * j - lights + 1, 2, 1.6 * side + 1)
              for j in range(lights)]
    # (a transform applies to what follows after the transforms written before it)
    lines += ["material 0.9 0.8 0.7 0.2 0.6 0.3 20 0.1 0.6 1.4",
              "scale %g %g %g" % ((0.25 * side,) * 3), "translate 0.4 0.2 %g" % (0.6 * side + 1),
              "sphere", "pop", "pop"]
    for i in range(n):
        r, c = divmod(i, side)
        kt = 0.7 if i % 5 == 0 else 0.0
        if not shared or i == 0:
            lines.append("material %g %g %g 0.2 0.7 0.3 20 0.1 %g 1.3" % (
                (i + 1) / (n + 1), (i * 61) % 100 / 100, (i * 17) % 100 / 100, kt))
        lines.append("scale 0.5 0.7 0.5" if i % 7 == 3 else "scale 0.6 0.6 0.6")
        lines.append("translate %g %g 0" % (1.6 * c - 0.8 * side, 1.6 * r - 0.8 * side))
        lines += ["sphere", "pop", "pop"]
    lines += ["material 0.9 0.9 0.9 0.3 0.7 0 1 0 0 1", "checkerboard 1",
              "translate 0 %g 0" % (-0.8 * side - 1), "plane", "pop", "checkerboard -1"]
    return "\n".join(lines) + "\n"


def kernels_of_a_render(text, size=(12, 9)):
    """(operation count, cache hit) of each kernel that rendering ``text`` launched
    (one bounce: max_depth 1)."""
    import raymitsuba

    loaded = raymitsuba.load(text, width=size[0], height=size[1], max_depth=1)
    return [(k["operation_count"], bool(k["cache_hit"])) for k in kernels_launched(loaded)]


def spheres(n, shared=False):
    """n alike analytic spheres in a row, glass and mirror-ish, each with its own material
    (``shared``: all under one). No meshes: Mitsuba's own mesh code may compile to one of
    a few variants depending on where a buffer lands in memory, which would blur what is
    tested here."""
    lines = ["eye 0 0 %g" % (n + 2), "fov 60", "light 0.2 0.2 0.2 ambient",
             "light 1 1 1 point 0 3 %g" % n]
    for i in range(n):
        if not shared or i == 0:
            lines.append("material %g 0.5 0.5 0.2 0.7 0.3 20 0.2 0.5 1.3" % ((i + 1) / n))
        lines += ["translate %g 0 0" % (2 * i - n + 1), "sphere", "pop"]
    return "\n".join(lines) + "\n"


def test_kernels_do_not_depend_on_the_number_of_materials(mitsuba):
    # 40 spheres under one material, then each under its own: the same kernels, and all
    # of the second render's come from the cache.
    few = kernels_of_a_render(spheres(40, shared=True))
    many = kernels_of_a_render(spheres(40))
    assert [ops for ops, _ in many] == [ops for ops, _ in few]
    assert all(hit for _, hit in many)


def test_kernels_do_not_depend_on_the_number_of_objects(mitsuba):
    # 2 spheres then 80, each with its own material: the same kernels, all from the cache.
    few = kernels_of_a_render(spheres(2))
    many = kernels_of_a_render(spheres(80))
    assert [ops for ops, _ in many] == [ops for ops, _ in few]
    assert all(hit for _, hit in many)


def test_kernels_do_not_change_for_one_material(mitsuba):
    # One surface only: the tables still have two rows, so the kernels are the same.
    one = kernels_of_a_render(spheres(2, shared=True))
    assert [ops for ops, _ in kernels_of_a_render(spheres(2))] == [ops for ops, _ in one]


@pytest.fixture(scope="module")
def crowd():
    import raymitsuba

    return raymitsuba.load(grid_scene(300), width=24, height=18)


@pytest.mark.parametrize("key", ["mat1.diffuse_mix", "mat1.refractivity"])
def test_gradient_of_one_material_among_hundreds(mitsuba, crowd, key):
    # The ball's kt also scales the shadows it casts on the crowd (the crossing record).
    finite, reverse, forward = derivatives(mitsuba, crowd, key, seed=7)
    assert abs(finite) > 1e-2
    assert reverse == pytest.approx(finite, rel=1e-2)
    assert forward == pytest.approx(reverse, rel=1e-5, abs=1e-6)


def test_gradient_of_a_material_in_the_crowd(mitsuba, crowd):
    # A glass sphere of the crowd, near its top (object 270: material 272).
    finite, reverse, forward = derivatives(mitsuba, crowd, "mat272.refractivity", seed=3)
    assert abs(finite) > 1e-3
    assert reverse == pytest.approx(finite, rel=1e-2)
    assert forward == pytest.approx(reverse, rel=1e-5, abs=1e-6)
