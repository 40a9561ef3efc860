"""Tests of raymitsuba/batch/fit.py: a batch of fits writes, for each scene, the fitted
scene that ``raymitsuba fit`` of that scene alone writes, byte for byte (the fit is
deterministic); a target that cannot be read is that scene's error, the others fitted."""

from __future__ import annotations

import pytest

from batch_support import SIZE
from raymitsuba.batch import manifest
from raymitsuba.batch.fit import fit_many

pytestmark = pytest.mark.timeout(180)

SCENE = """eye 0 0 5
light 1 1 1 point 2 3 4
material {color} 0.1 0.8 0 1 0 0 1
sphere
"""


def single_fit(scene, target, output, *args):
    from raymitsuba.cli import main

    try:
        main.main(["fit", str(scene), "--target", str(target), "-o", str(output), "-q", *args],
                  standalone_mode=False)
    except SystemExit as e:
        assert e.code in (0, None), e
    return output.read_bytes()


def test_each_fitted_scene_is_the_single_fits_and_a_bad_target_fails_alone(client, tmp_path):
    from raymitsuba import api, images

    truth = api.load(SCENE.format(color="0.5 0.5 0.5"), **SIZE)
    images.write(str(tmp_path / "target.npy"), truth.integrator.render_array(truth.scene))
    scenes = []
    for name, color in (("a", "0.8 0.2 0.2"), ("b", "0.3 0.6 0.2"), ("c", "0.1 0.1 0.9")):
        scenes.append(tmp_path / f"{name}.ray")
        scenes[-1].write_text(SCENE.format(color=color))
    (tmp_path / "broken.npy").write_bytes(b"not an image")
    targets = [tmp_path / "target.npy", tmp_path / "target.npy", tmp_path / "broken.npy"]
    outputs = [tmp_path / "fitted" / f"{s.stem}.ray" for s in scenes]
    items = fit_many(scenes, targets, outputs, keys=["mat1.color"], iters=10, client=client)
    assert [i.status for i in items] == ["done", "done", "error"]
    assert "cannot read image" in items[2].error and not outputs[2].exists()
    for scene, output in zip(scenes[:2], outputs):
        want = single_fit(scene, tmp_path / "target.npy", tmp_path / f"single-{scene.name}",
                          "--params", "mat1.color", "--iters", "10")
        assert output.read_bytes() == want
    lines = manifest.read(tmp_path / "fitted" / manifest.NAME)
    assert sorted(line["status"] for line in lines) == ["done", "done", "error"]
