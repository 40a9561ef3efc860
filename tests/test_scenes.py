"""The scene gallery (scenes/*.ray): every scene parses cleanly and renders.

* Parsing: no error and no warning (a gallery scene is an example to copy from).
* Rendering: a 24x24 render, 1 spp, is finite, has the expected shape and is not a
  constant image. Only that -- the numeric behaviour of the renderer is tested elsewhere;
  this file keeps the gallery from rotting, quickly, in one process.
"""

from __future__ import annotations

import glob
import os

import numpy as np
import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = sorted(glob.glob(os.path.join(ROOT, "scenes", "*.ray")))
IDS = [os.path.basename(p) for p in SCENES]

#: Scenes other files rely on by name (README, benchmarks/bench.py).
REQUIRED = ("whitted.ray", "benchmark_reflective.ray", "benchmark_glass.ray")


def test_gallery_is_complete():
    assert len(SCENES) >= 10
    for name in REQUIRED:
        assert name in IDS


@pytest.mark.parametrize("path", SCENES, ids=IDS)
def test_scene_parses_without_warnings(path):
    from raymitsuba.parser import parse_file

    scene = parse_file(path)  # raises RayError on any error
    assert scene.objects, "a gallery scene shows something"
    assert scene.lights, "a gallery scene is lit"
    assert [w.format() for w in scene.warnings] == []


@pytest.mark.parametrize("path", SCENES, ids=IDS)
def test_scene_renders(path):
    import raymitsuba

    loaded = raymitsuba.load(path, width=24, height=24, spp=1)
    image = np.array(raymitsuba.render(loaded))
    assert image.shape == (24, 24, 3)
    assert np.isfinite(image).all()
    assert float(image.max() - image.min()) > 1e-3, "a constant image"
