"""Camera rays (plugins/whitted/camera.py): the sample lattice's rays in its own order are the
render's rays, bit for bit (the boundary terms' keys, traced in lattice order, describe the
very samples whose colors the render averages)."""

from __future__ import annotations

import numpy as np
import pytest

from support import load_ray


@pytest.mark.parametrize("n", [1, 2, 4, 8])
def test_lattice_rays_are_the_renders_rays_bit_for_bit(mitsuba, n):
    from raymitsuba.plugins.whitted.camera import camera_rays, lattice_rays

    width, height = 13, 7
    scene = load_ray("eye 0.3 1 5\nlookat 0 0 0\nfov 37\nsphere\n", width=width, height=height)
    sensor = scene.scene.sensors()[0]
    render = camera_rays(sensor, width, height, n * n)  # pixel-major
    lattice = lattice_rays(sensor, width, height, n, 0, height * n)  # row-major lattice
    # lattice point (Y, X): sample (Y % n, X % n) of pixel (Y // n, X // n)
    y, x = np.divmod(np.arange(height * n * width * n), width * n)
    lane = ((y // n) * width + x // n) * n * n + (y % n) * n + x % n

    def host(vector):
        return np.stack([c.numpy() for c in vector], -1)

    assert np.array_equal(host(render.o)[lane], host(lattice.o))
    assert np.array_equal(host(render.d)[lane], host(lattice.d))
    # a block of rows is those rows of the whole
    rows = lattice_rays(sensor, width, height, n, 3, 2)
    assert np.array_equal(host(rows.d), host(lattice.d)[3 * width * n:5 * width * n])
