"""Tests of ``raymitsuba fit SCENE... --target TEMPLATE -o TEMPLATE`` (raymitsuba/cli/fit.py's
batch) as a process: one fit per scene, a scene error reported as today while the other
scene is fitted (exit 2), options only for one scene refused."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

pytestmark = pytest.mark.timeout(240)

SCENE = "eye 0 0 5\nlight 1 1 1 point 2 3 4\nmaterial {color} 0.1 0.8 0 1 0 0 1\nsphere\n"


def raymitsuba(*args):
    return subprocess.run([sys.executable, "-m", "raymitsuba", *map(str, args)],
                          capture_output=True, text=True, timeout=200)


def test_fits_in_batch_and_a_scene_error_among_them(tmp_path):
    (tmp_path / "targets").mkdir()
    (tmp_path / "good.ray").write_text(SCENE.format(color="0.8 0.2 0.2"))
    (tmp_path / "bad.ray").write_text(SCENE.format(color="0.8 0.2"))  # 2 operands short
    result = raymitsuba("render", tmp_path / "good.ray", "-o", tmp_path / "targets" / "good.npy",
                        "--width", 24, "--height", 16)
    assert result.returncode == 0, result.stderr
    result = raymitsuba("fit", tmp_path / "good.ray", tmp_path / "bad.ray", "--target",
                        tmp_path / "targets" / "{stem}.npy", "-o",
                        tmp_path / "fitted" / "{stem}.ray", "--iters", 3, "-j", 1)
    assert result.returncode == 2
    assert f"{tmp_path / 'bad.ray'}:3:" in result.stderr and "Traceback" not in result.stderr
    assert (tmp_path / "fitted" / "good.ray").exists()
    assert not (tmp_path / "fitted" / "bad.ray").exists()
    with open(tmp_path / "fitted" / "raymitsuba-manifest.jsonl") as f:
        status = {json.loads(line)["scene"].rsplit("/", 1)[1]: json.loads(line)["status"]
                  for line in f}
    assert status == {"good.ray": "done", "bad.ray": "error"}


def test_truth_and_plot_are_for_one_scene(tmp_path):
    result = raymitsuba("fit", "a.ray", "b.ray", "--target", "{stem}.png", "-o", "{stem}.out.ray",
                        "--plot", tmp_path / "p.png")
    assert result.returncode == 2 and "--truth and --plot are for one scene" in result.stderr
