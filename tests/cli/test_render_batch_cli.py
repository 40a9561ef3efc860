"""Tests of ``raymitsuba render SCENE... -o TEMPLATE`` (raymitsuba/cli/render.py's batch) as
a process: outputs bit for bit those of one-scene commands, the manifest, exit statuses
0/1/2, --skip-existing, --tiles; a single render never imports Dask."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from support import REPO

pytestmark = pytest.mark.timeout(240)

SCENES = [os.path.join(REPO, "scenes", name) for name in
          ("whitted.ray", "textured_objects.ray", "mit6837_balls.ray")]
SIZE = ("--width", "32", "--height", "24")


def raymitsuba(*args):
    return subprocess.run([sys.executable, "-m", "raymitsuba", *map(str, args)],
                          capture_output=True, text=True, timeout=200)


def single(scene, output, *options):
    result = raymitsuba("render", scene, "-o", output, *SIZE, *options)
    assert result.returncode == 0, result.stderr
    return output.read_bytes()


def manifest(folder):
    with open(folder / "raymitsuba-manifest.jsonl") as f:
        return {os.path.basename(r["scene"]): r for r in map(json.loads, f)}


def test_a_batch_writes_each_scenes_image_and_a_manifest(tmp_path):
    result = raymitsuba("render", *SCENES, "-o", tmp_path / "out" / "{index:02d}-{stem}.png",
                        *SIZE, "-j", "2")
    assert result.returncode == 0, result.stderr
    assert result.stderr.splitlines()[-1].startswith("raymitsuba: 3 scenes: 3 done")
    for i, scene in enumerate(SCENES):
        out = tmp_path / "out" / f"{i:02d}-{os.path.splitext(os.path.basename(scene))[0]}.png"
        assert out.read_bytes() == single(scene, tmp_path / f"single{i}.png"), scene
    records = manifest(tmp_path / "out")
    assert set(records) == {os.path.basename(s) for s in SCENES}
    assert all(set(r) == {"scene", "output", "status", "error", "attempts", "seconds",
                          "worker", "sha256"} for r in records.values())
    assert all(r["status"] == "done" and r["attempts"] == 1 for r in records.values())


def test_a_scene_error_is_reported_as_today_and_the_others_still_render(tmp_path):
    bad = tmp_path / "bad.ray"
    bad.write_text("sphere\nlight 1 1 1 ambient\nmaterial 1 1\n")
    result = raymitsuba("render", SCENES[0], bad, "-o", tmp_path / "{stem}.png", *SIZE,
                        "-j", "1")
    assert result.returncode == 2
    assert f"{bad}:3:" in result.stderr and "Traceback" not in result.stderr
    assert (tmp_path / "whitted.png").exists() and not (tmp_path / "bad.png").exists()
    assert manifest(tmp_path)["bad.ray"]["status"] == "error"


def test_an_item_that_fails_exits_1_and_the_others_are_written(tmp_path):
    os.makedirs(tmp_path / "whitted.png")  # a folder where the output goes: cannot be written
    result = raymitsuba("render", SCENES[0], SCENES[2], "-o", tmp_path / "{stem}.png",
                        *SIZE, "-j", "1")
    assert result.returncode == 1
    assert f"raymitsuba: error: {SCENES[0]}: {tmp_path / 'whitted.png'}: cannot write" \
        in result.stderr and "Traceback" not in result.stderr
    assert (tmp_path / "mit6837_balls.png").read_bytes() == \
        single(SCENES[2], tmp_path / "single.png")
    assert manifest(tmp_path)["whitted.ray"]["status"] == "failed"


def test_skip_existing_renders_only_the_outputs_missing(tmp_path):
    template = tmp_path / "{stem}.npy"
    assert raymitsuba("render", *SCENES[:2], "-o", template, *SIZE, "-j", "1").returncode == 0
    kept = (tmp_path / "whitted.npy").stat().st_mtime_ns
    os.remove(tmp_path / "textured_objects.npy")  # as if the batch had been interrupted
    result = raymitsuba("render", *SCENES[:2], "-o", template, *SIZE, "-j", "1",
                        "--skip-existing")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "whitted.npy").stat().st_mtime_ns == kept
    records = manifest(tmp_path)
    assert records["whitted.ray"]["status"] == "skipped"
    assert records["textured_objects.ray"]["status"] == "done"
    assert (tmp_path / "textured_objects.npy").read_bytes() == \
        single(SCENES[1], tmp_path / "single.npy")


@pytest.mark.parametrize("aa", [(), ("--aa", "0.02")])
def test_tiles_over_workers_give_the_single_renders_file(tmp_path, aa):
    result = raymitsuba("render", SCENES[0], "-o", tmp_path / "poster.png", *SIZE, *aa,
                        "--tiles", "4", "-j", "2")
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "poster.png").read_bytes() == single(SCENES[0], tmp_path / "one.png",
                                                            *aa)


def test_outputs_that_cannot_be_told_apart_are_refused_before_anything_runs(tmp_path):
    result = raymitsuba("render", *SCENES[:2], "-o", tmp_path / "out.png")
    assert result.returncode == 2 and "need a template" in result.stderr
    assert os.listdir(tmp_path) == []


def test_a_single_render_does_not_import_dask(tmp_path):
    code = ("import sys; from raymitsuba.cli import main\n"
            "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed', 'raymitsuba.batch')))")
    result = subprocess.run([sys.executable, "-c", code, "render", SCENES[0], "-o",
                             tmp_path / "a.png", *SIZE], capture_output=True, text=True,
                            timeout=200)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "a.png").exists()
    assert result.stdout.strip() == "[]"
