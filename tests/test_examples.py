"""The fitting examples in examples/ still run (briefly: few iterations, tiny images)."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@pytest.mark.parametrize("script,keys,extra", [
    ("fit_phong.py", ["mat2.color", "mat2.diffuse_mix", "mat2.specular_mix", "mat2.phong_coeff"],
     []),
    ("fit_glass.py", ["mat2.refractivity", "mat2.ior"], []),
    ("fit_shape.py", ["translate2.offset", "scale1.factors"], ["--spp", "4"]),
    ("fit_pose.py", ["camera.eye", "camera.lookat"], ["--spp", "4"]),
])
def test_example_runs(script, keys, extra):
    result = subprocess.run([sys.executable, os.path.join("examples", script), "--iters", "4",
                             "--size", "12"] + extra, cwd=ROOT, capture_output=True, text=True,
                            timeout=300)
    assert result.returncode == 0, result.stderr
    out = result.stdout
    assert "iter    1" in out  # progress
    for key in keys:  # the true / start / fitted table
        assert key in out
    assert "4 iterations" in out
    losses = out.rsplit("loss ", 1)[1].split()
    assert float(losses[2]) < float(losses[0])  # "loss A -> B": it went down
