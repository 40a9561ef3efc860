"""The lattice (plugins/whitted/boundary/lattice.py): a camera ray's lattice point, the ring
of samples outside the image's border, and the square lattice (no anti-aliasing) the terms
need."""

from __future__ import annotations

import numpy as np
import pytest

from support_edges import FLAT, JUMP, PIXELS_PER_UNIT, SPHERE, H, W, forward, loaded


@pytest.mark.parametrize("offset, column", [(0.1, 0), (-0.1, None)])
def test_an_edge_at_the_images_border_moves_by_its_closed_form(mi, offset, column):
    """The rectangle's right edge ``offset`` pixels inside the image's left border: closer
    than the first samples (1/8 pixel at k = 4), so only a pair with the ring's sample
    outside the image straddles it. Inside, moving it right fills column 0 as the edge in
    the middle of the image fills its column; outside the border, it changes no pixel (the
    crossing is outside the image: its term goes nowhere)."""
    edge = -(W / 2 - offset) / PIXELS_PER_UNIT
    text = FLAT.replace("translate 0.1 0.05 0", f"translate {edge!r} 0.05 0") \
        + "triangle -3 -3 0  0 -3 0  0 3 0\ntriangle -3 -3 0  0 3 0  -3 3 0\n"
    grad = forward(mi, text, "translate1.offset", (1, 0, 0), 16)
    expected = np.zeros((H, W))
    if column is not None:
        expected[:, column] = JUMP * PIXELS_PER_UNIT
    np.testing.assert_allclose(grad[..., 0], expected, rtol=1e-3, atol=1e-4)


def test_geometry_derivatives_need_a_square_lattice_without_aa(mi):
    import drjit as dr
    import raymitsuba

    for options in (dict(aa=0.02), dict(spp=8)):
        scene = loaded(mi, SPHERE, options.pop("spp", 16), **options)
        dr.enable_grad(scene.params["translate1.offset"])
        scene.params.update()
        result = raymitsuba.render(scene)
        with pytest.raises(Exception, match="lattice"):
            dr.backward(dr.sum(result, axis=None))


def test_a_camera_rays_lattice_point_is_its_pixels_sample(mi):
    """lattice_index: sample s of pixel (px, py), the render's lane (py W + px) k^2
    + s, is lattice point (py k + s // k, px k + s % k), entry (Y + 1, X + 1) of the
    lattice's arrays (row-major, W k + 2 columns: the ring around), for a chunk starting at
    any pixel."""
    from raymitsuba.plugins.whitted.boundary import lattice

    width, k = 5, 3
    first, count = 4, 9  # pixels 4 .. 12: a chunk across rows
    lane = np.arange(count * k * k)
    pixel, sample = first + lane // (k * k), lane % (k * k)
    y = (pixel // width) * k + sample // k
    x = (pixel % width) * k + sample % k
    assert np.array_equal(lattice.lattice_index(width, k, first, count).numpy(),
                          (y + 1) * (width * k + 2) + x + 1)
