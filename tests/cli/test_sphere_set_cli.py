"""``--sphere-set N`` on the command line (raymitsuba/cli/render.py, fit.py): the sphere set
(raymitsuba/geometry/sphere_set.py) draws what single spheres draw, and a fit it cannot do stops with
a one-line error that says how to load the scene instead."""

from __future__ import annotations

import numpy as np
from click.testing import CliRunner

from raymitsuba.cli.fit import fit as fit_command
from raymitsuba.cli.render import render as render_command
from test_sphere_set import SET_MIN, sphere_grid


def test_render_draws_the_same_image_with_and_without_the_set(tmp_path, mitsuba):
    scene = tmp_path / "grid.ray"
    scene.write_text(sphere_grid(SET_MIN + 4, glass_every=9, mirror_every=4))
    images = []
    for extra in ([], ["--sphere-set", "0"]):
        out = tmp_path / f"grid{len(images)}.npy"
        result = CliRunner().invoke(render_command, [str(scene), "-o", str(out), "--width", "64",
                                                     "--height", "48", *extra])
        assert result.exit_code == 0, result.output
        images.append(np.load(out))
    # float rounding only, but for a ray that grazes a sphere (tests/geometry/test_sphere_set.py)
    assert (np.abs(images[0] - images[1]).max(axis=-1) > 1e-5).mean() < 0.01


def test_a_fit_that_makes_a_set_material_transparent_says_how_to_load_the_scene(tmp_path,
                                                                                 mitsuba):
    from raymitsuba import images

    scene = tmp_path / "grid.ray"
    scene.write_text(sphere_grid(SET_MIN))
    target = tmp_path / "target.exr"
    images.write(str(target), np.zeros((24, 32, 3), np.float32))
    out = tmp_path / "fitted.ray"
    result = CliRunner().invoke(fit_command, [str(scene), "--target", str(target), "-o", str(out),
                                              "--params", "mat3.refractivity", "--iters", "2"])
    assert result.exit_code == 1 and not out.exists()
    assert "Traceback" not in result.output and "--sphere-set 0" in result.output
    result = CliRunner().invoke(fit_command, [str(scene), "--target", str(target), "-o", str(out),
                                              "--params", "mat3.refractivity", "--iters", "2",
                                              "--sphere-set", "0"])
    assert result.exit_code == 0, result.output
