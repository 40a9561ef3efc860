"""The pairs (plugins/whitted/boundary/pairs.py): of the kinds of edges the keys move, only
of the edges they move, classified among the candidates as among every pair."""

from __future__ import annotations

import numpy as np
import pytest

from support_edges import loaded, pairs_of_a_step, weights


# a glass ball over a checkered floor, which a second (opaque) ball shadows: every kind of
# pair, at the first hit and through the glass
GLASS_OVER_CHECKER = """\
eye 0 2 5
lookat 0 0 0
fov 40
background 0.2 0.3 0.4
light 1 1 1 point 1 4 2
light 0.2 0.2 0.2 ambient
material 0.9 0.8 0.6 0.3 0.7 0 1 0 0 1
translate 0 -1 0
checkerboard 0.5
plane
reset
material 1 1 1 0 0 0 1 0.1 0.85 1.5
sphere
reset
material 0.8 0.4 0.3 0.3 0.7 0 1 0 0 1
translate 1.4 0 0.5
scale 0.4 0.4 0.4
sphere
"""


@pytest.mark.parametrize("keys, kinds", [
    (("mat2.ior",), "CHAIN_VISIBILITY CHAIN_CHECKER CHAIN_TIR CHAIN_SHADOW"),
    (("light1.position",), "SHADOW CHAIN_SHADOW"),
    (("mat2.ior", "light1.position"),
     "SHADOW CHAIN_VISIBILITY CHAIN_CHECKER CHAIN_TIR CHAIN_SHADOW"),
    (("camera.eye",), "VISIBILITY SHADOW CHECKER CHAIN_VISIBILITY CHAIN_CHECKER CHAIN_TIR "
                      "CHAIN_SHADOW"),
    (("mat1.diffuse_mix",), ""),
])
def test_pairs_are_formed_of_the_kinds_of_edges_the_keys_move(mi, keys, kinds):
    import drjit as dr
    import raymitsuba

    from raymitsuba.plugins.whitted import boundary

    scene = loaded(mi, GLASS_OVER_CHECKER, 16)
    for key in keys:
        dr.enable_grad(scene.params[key])
    scene.params.update()
    raymitsuba.render(scene)  # (the tracer's tables: the materials read)
    formed = boundary.moving_kinds(scene.integrator.tracer, scene.scene)
    assert formed == {getattr(boundary, name) for name in kinds.split()}


def test_the_pairs_are_those_of_every_pair_classified(mi, monkeypatch):
    """The pairs are classified among the candidates only (the pairs whose samples differ in
    some key): every pair of the lattice classified gives the same pairs, in the same order
    (glass over a checker: visibility, shadows, checker lines, the chain's kinds), a checker
    pair once per line between its samples."""
    import numpy as np

    from raymitsuba.plugins.whitted import boundary
    from raymitsuba.plugins.whitted.boundary import lattice

    _, edges, found = pairs_of_a_step(mi, monkeypatch, GLASS_OVER_CHECKER)
    rows, cols = edges.t.shape
    kinds = set()
    for axis in (1, 0):  # every pair of the axis but the ring's, row-major
        ly, lx = np.mgrid[1:rows - 1, 0:cols - 1] if axis == 1 else \
            np.mgrid[0:rows - 1, 1:cols - 1]
        ly, lx = ly.ravel(), lx.ravel()
        index, kind, light, depth = edges.classify(
            (ly, lx), (ly + (axis == 0), lx + (axis == 1)), edges.chain_bounces())
        if index is not None:  # (pairs across several edges: an entry each, appended)
            ly, lx = ly[index], lx[index]
        keep = edges.kept(kind)
        L = (ly[keep], lx[keep])
        every = edges.one_crossing_per_line(
            dict(kind=kind[keep], light=light[keep], depth=depth[keep],
                 **{name: L if name != "R" else (L[0] + (axis == 0), L[1] + (axis == 1))
                    for name in lattice.POINTS}))
        mine = found["axis"] == axis
        assert np.array_equal(found["L"][0][mine], every["L"][0])
        assert np.array_equal(found["L"][1][mine], every["L"][1])
        for name in ("kind", "light", "depth", "coord", "line"):
            assert np.array_equal(found[name][mine], every[name]), name
        kinds |= set(kind[keep].tolist())
    assert kinds == {boundary.VISIBILITY, boundary.SHADOW, boundary.CHECKER,
                     boundary.CHAIN_VISIBILITY, boundary.CHAIN_CHECKER, boundary.CHAIN_SHADOW}


def test_leaving_unmoved_kinds_out_leaves_the_derivative_as_it_was(mi):
    """eta's derivative alone (the chain's pairs) and with the camera's keys too (every
    pair formed, the others' surrogates flat in eta): the same, to the float32 order of the
    sums over chunks of pairs."""
    import drjit as dr
    import raymitsuba

    grads = []
    for keys in (("mat2.ior",), ("mat2.ior", "camera.eye")):
        scene = loaded(mi, GLASS_OVER_CHECKER, 16)
        for key in keys:
            dr.enable_grad(scene.params[key])
        scene.params.update()
        result = raymitsuba.render(scene)
        dr.backward(dr.sum(result * mi.TensorXf(weights().astype(np.float32)), axis=None))
        grads.append(float(dr.grad(scene.params["mat2.ior"])[0]))
    assert grads[0] != 0.0
    assert grads[0] == pytest.approx(grads[1], rel=1e-5)


def test_edges_that_no_key_moves_form_no_pairs_and_add_nothing(mi, monkeypatch):
    """The opaque ball moving, the camera still (glass over a checker): the pairs formed at
    the first hit are those of the ball's edges -- a sample sees it, or it blocks the light
    -- a fifth of those formed when every edge may move (the floor's checker lines and the
    glass ball's rim stay where they are); the chain's are all kept. Forming every pair
    anyway (their surrogates flat in the ball's key) gives the same derivative, to the
    float32 order of the sums over the pairs (reverse mode: their atomics)."""
    import drjit as dr
    import raymitsuba

    from raymitsuba.plugins.whitted import boundary
    from raymitsuba.plugins.whitted.boundary import lattice

    formed = {}
    pairs, moving_edges = boundary.Boundary.pairs, boundary.Boundary.moving_edges

    def kept(self):
        formed[self] = pairs(self)
        return formed[self]

    def every_edge(self, kind, *args):
        return np.ones(len(kind), bool)

    monkeypatch.setattr(boundary.Boundary, "pairs", kept)
    grads, counts = [], []
    for control in (False, True):
        monkeypatch.setattr(boundary.Boundary, "moving_edges",
                            every_edge if control else moving_edges)
        formed.clear()
        scene = loaded(mi, GLASS_OVER_CHECKER, 16)
        dr.enable_grad(scene.params["translate2.offset"])
        scene.params.update()
        result = raymitsuba.render(scene)
        dr.backward(dr.sum(result * mi.TensorXf(weights().astype(np.float32)), axis=None))
        grads.append(dr.grad(scene.params["translate2.offset"]).numpy().ravel())
        (edges, found), = formed.items()
        counts.append(len(found["kind"]))
        if not control:
            name, = scene.integrator.tracer.geometry_ad.moving_shapes()
            ball = edges.terms.geometry.id_by_name[name]
            first = found["kind"] < boundary.CHAIN_VISIBILITY
            l, r = (lattice.flat(found[side], edges.cols)[first] for side in ("L", "R"))
            sees = (lattice.at(edges.shape, l) == ball) | (lattice.at(edges.shape, r) == ball)
            blocks = np.any([b[:, 0] == ball for b in edges.blockers(
                edges.occluder, edges.stopper, found["light"][first], l, r)], axis=0)
            assert np.all(sees | ((found["kind"][first] == boundary.SHADOW) & blocks))
            assert np.any(~first)  # (the chain's: kept)
    assert counts[0] < counts[1] / 4
    assert np.all(grads[0] != 0.0)
    # (to float32's order of the largest component: the sums' rounding is that of the terms
    # they add, not of a component that nearly cancels, -0.0024 against 1.04)
    np.testing.assert_allclose(grads[0], grads[1], rtol=1e-5,
                               atol=1e-5 * np.abs(grads[1]).max())
