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

#: Scenes other files rely on by name (README, benchmarks/bench.py, docs/format.md).
REQUIRED = ("whitted.ray", "benchmark_reflective.ray", "benchmark_glass.ray",
            "mit6837_torus.ray")


def test_gallery_is_complete():
    assert len(SCENES) >= 10
    for name in REQUIRED:
        assert name in IDS


@pytest.mark.parametrize("path", SCENES, ids=IDS)
def test_scene_parses_without_warnings(path):
    from raymitsuba.format.parser import parse_file

    scene = parse_file(path)  # raises RayError on any error
    assert scene.objects or scene.meshes, "a gallery scene shows something"
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


def test_the_mit_6837_scenes_are_in_that_dialect_and_the_torus_is_large():
    from raymitsuba.format.parser import parse_file

    mit = [p for p in SCENES if os.path.basename(p).startswith("mit6837_")]
    assert len(mit) >= 3
    assert all(parse_file(p).dialect == "mit6837" for p in mit)
    torus = parse_file(os.path.join(ROOT, "scenes", "mit6837_torus.ray"))
    assert torus.triangle_count >= 4000


def test_the_generated_scenes_are_up_to_date(tmp_path, monkeypatch):
    import importlib.util

    spec = importlib.util.spec_from_file_location("make_6837", os.path.join(ROOT, "scenes",
                                                                          "make_6837.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with open(os.path.join(ROOT, "scenes", "mit6837_torus.ray"), encoding="utf-8") as f:
        assert f.read() == module.torus_scene()
    with open(os.path.join(ROOT, "scenes", "mit6837_terrain.ray"), encoding="utf-8") as f:
        assert f.read() == module.terrain_scene()
