"""Tests of ``raymitsuba fit`` (raymitsuba/cli/fit.py): a fit from files that changes only the
fitted numbers, the default parameters, and bad input that exits 2 without a traceback."""

from __future__ import annotations

import os
import re

import numpy as np
import pytest
from click.testing import CliRunner

from raymitsuba.cli.fit import fit as fit_command
from raymitsuba.format.parser import parse_text
from test_fit import TRUE, render  # the fit tests' scene (diffuse mix 0.7) and renderer


def run(*args):
    return CliRunner().invoke(fit_command, [str(a) for a in args])


@pytest.fixture
def files(tmp_path, mitsuba):
    """start.ray (TRUE with kd perturbed, CRLF line ends, a tab, comments), true.ray,
    target.exr (TRUE rendered at 24x24)."""
    from raymitsuba import images

    true = tmp_path / "true.ray"
    true.write_text(TRUE)
    start = tmp_path / "start.ray"
    start.write_bytes(b"eye 0.1 0.05 5\r\n"
                      b"fov 35   # degrees\r\n"
                      b"light 0.9 0.85 0.8 point 1.5 1 6\r\n"
                      b"light 0.3 0.3 0.3 ambient\r\n"
                      b"material 0.8 0.45 0.3 0.4\t0.40 0.5 12 0 0 1 # kd is off\r\n"
                      b"sphere\r\n")
    target = tmp_path / "target.exr"
    images.write(str(target), render(TRUE))
    return tmp_path, start, true, target


class TestCommand:
    def test_fits_and_writes_only_the_fitted_number(self, files):
        tmp, start, true, target = files
        out, plot = tmp / "fitted.ray", tmp / "curve.png"
        result = run(start, "--target", target, "--params", "mat1.diffuse_mix", "--iters", 60,
                     "--lr", 0.05, "-o", out, "--truth", true, "--plot", plot)
        assert result.exit_code == 0, result.output + result.stderr
        assert "iter   60/60" in result.stdout and "|error| max" in result.stdout
        assert "mat1.diffuse_mix: 0.4 ->" in result.stdout
        before, after = start.read_bytes(), out.read_bytes()
        # Exactly one token differs: the diffuse mix `0.40` of the material line.
        prefix, suffix = before.split(b"\t0.40 ", 1)
        assert after.startswith(prefix + b"\t") and after.endswith(b" " + suffix)
        token = after[len(prefix) + 1:len(after) - len(suffix) - 1]
        assert re.fullmatch(rb"[0-9.]+", token)
        assert float(token) == pytest.approx(0.7, abs=5e-3)
        assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    def test_default_parameters_and_quiet(self, files):
        tmp, start, true, target = files
        out = tmp / "fitted.ray"
        result = run(start, "--target", target, "--iters", 2, "-o", out, "-q")
        assert result.exit_code == 0, result.output + result.stderr
        assert "iter " not in result.stdout
        assert "mat1.color" in result.stdout and "light2.color" in result.stdout
        assert parse_text(out.read_bytes()).objects  # a valid scene

    @pytest.mark.parametrize("problem", ["scene", "params", "mat0", "target", "no-target",
                                         "truth", "plot", "nan-target"])
    def test_bad_input_exits_2_without_traceback_or_output(self, files, problem):
        tmp, start, true, target = files
        out = tmp / "fitted.ray"
        args = [start, "--target", target, "-o", out, "--iters", 1]
        if problem == "scene":
            bad = tmp / "bad.ray"
            bad.write_text("eye 0 0 5\nmaterial 1 1 1\n")
            args[0] = bad
            expect = f"{bad}:2:"
        elif problem == "params":
            args += ["--params", "mat1.diffuse,light1.color"]
            expect = "unknown parameter `mat1.diffuse`; valid keys: mat1.color, mat1.ambient_mix"
        elif problem == "mat0":
            args += ["--params", "mat0.color"]
            expect = "default material"
        elif problem == "target":
            junk = tmp / "junk.png"
            junk.write_bytes(b"not an image")
            args[2] = junk
            expect = "cannot read image"
        elif problem == "no-target":
            args[2] = tmp / "missing.exr"
            expect = "cannot read image"
        elif problem == "truth":
            other = tmp / "other.ray"
            other.write_text("light 1 1 1 ambient\nsphere\n")  # no material 1
            args += ["--truth", other]
            expect = "no material 1"
        elif problem == "plot":
            args += ["--plot", tmp / "curve.txt"]
            expect = "--plot"
        else:
            bad = tmp / "nan.npy"
            image = np.zeros((4, 4, 3), np.float32)
            image[1, 1, 1] = np.nan
            np.save(bad, image)
            args[2] = bad
            expect = "non-finite"
        result = run(*args)
        assert result.exit_code == 2, (result.stdout, result.stderr)
        assert expect in result.stderr
        assert "Traceback" not in result.stdout + result.stderr
        assert not isinstance(result.exception, Exception) or isinstance(result.exception, SystemExit)
        assert not out.exists()
        assert not any(name.startswith(".raymitsuba-") for name in os.listdir(tmp))


def test_a_scan_runs_first_and_a_bad_one_exits_2(files):
    tmp, start, true, target = files
    out = tmp / "fitted.ray"
    result = run(start, "--target", target, "--params", "mat1.diffuse_mix", "--iters", 5,
                 "--scan", "mat1.diffuse_mix=0:1:5", "-o", out, "-q")
    assert result.exit_code == 0, result.output + result.stderr
    assert "scanned 5 combination(s): best mat1.diffuse_mix=0.75" in result.stdout
    assert "mat1.diffuse_mix: 0.75 ->" in result.stdout
    out.unlink()
    for scan, expect in (("mat1.diffuse_mix=1:0:5", "LOW < HIGH"),
                         ("mat1.diffuse_mix", "KEY=LOW:HIGH:COUNT"),
                         ("mat1.phong_coeff=1:30:4", "not among the fitted parameters")):
        result = run(start, "--target", target, "--params", "mat1.diffuse_mix", "--iters", 1,
                     "--scan", scan, "-o", out)
        assert result.exit_code == 2, (scan, result.output)
        assert expect in result.output + result.stderr
        assert "Traceback" not in result.output + result.stderr
        assert not out.exists()


def test_the_automatic_scan_is_the_default_and_none_turns_it_off(tmp_path, mitsuba):
    """A fitted ior is scanned by default (its start and 32 values, the cost printed);
    ``--scan none`` fits without; 'auto' mixed with a grid exits 2."""
    from raymitsuba import images
    from test_fit import GLASS_OVER_CHECKER

    import raymitsuba

    scene = tmp_path / "glass.ray"
    scene.write_text(GLASS_OVER_CHECKER.replace("0 0.85 1.5\n", "0 0.85 1.15\n"))
    target = tmp_path / "target.exr"
    images.write(str(target), raymitsuba.render(raymitsuba.load(
        GLASS_OVER_CHECKER, width=12, height=12, spp=4)).numpy())
    out = tmp_path / "fitted.ray"
    result = run(scene, "--target", target, "--params", "mat2.ior", "--iters", 1, "--spp", 4,
                 "-o", out, "-q")
    assert result.exit_code == 0, result.output + result.stderr
    assert "scanned mat2.ior (auto; --scan none to skip): its start and 32 values in " \
           "[0.7667, 1.725]: best " in result.stdout
    assert "the automatic scan: 33 renders" in result.stdout
    result = run(scene, "--target", target, "--params", "mat2.ior", "--iters", 1, "--spp", 4,
                 "--scan", "none", "-o", out, "-q")
    assert result.exit_code == 0, result.output + result.stderr
    assert "scanned" not in result.stdout and "mat2.ior: 1.15 ->" in result.stdout
    result = run(scene, "--target", target, "--scan", "auto", "--scan", "mat2.ior=1:2:3",
                 "-o", out)
    assert result.exit_code == 2 and "not a mix" in result.output + result.stderr


def test_antialiasing_and_a_memory_budget_pass_through(files, monkeypatch):
    from raymitsuba import api

    seen = {}
    load = api.load

    def spy(*args, **kwargs):
        seen.update(kwargs)
        return load(*args, **kwargs)

    monkeypatch.setattr(api, "load", spy)
    tmp, start, _, target = files
    result = run(start, "--target", target, "--params", "mat1.diffuse_mix", "--iters", 3,
                 "--aa", 0.05, "--memory-budget", "64M", "-o", tmp / "fitted.ray", "-q")
    assert result.exit_code == 0, result.output + result.stderr
    assert seen["aa"] == 0.05 and seen["memory_budget"] == 64 << 20


def test_geometry_and_camera_keys_are_fitted_and_written_back(tmp_path, mitsuba):
    # A sphere moved 0.15 to the right of its place in the target (and the eye line
    # written with a tab) comes back toward it in a few steps on the 2 x 2 lattice; the
    # fitted file differs from the start only in the translate's numbers.
    import raymitsuba
    from raymitsuba import images

    true = "eye 0 0 5\nfov 40\nbackground 0.2 0.3 0.4\nlight 1 1 1 ambient\n" \
           "material 0.8 0.4 0.3 1 0 0 1 0 0 1\ntranslate 0.1 0 0\nsphere\n"
    start = tmp_path / "start.ray"
    start.write_bytes(true.replace("translate 0.1 0 0", "translate 0.25 0 0").encode())
    target = tmp_path / "target.exr"
    images.write(str(target), raymitsuba.render(raymitsuba.load(true, width=16, height=12,
                                                                 spp=4)).numpy())
    out = tmp_path / "fitted.ray"
    result = run(start, "--target", target, "--params", "translate1.offset", "--spp", 4,
                 "--iters", 12, "--lr", 0.05, "-o", out, "-q")
    assert result.exit_code == 0, result.output
    fitted = out.read_bytes()
    lines = fitted.split(b"\n")
    assert lines[:5] + lines[6:] == start.read_bytes().split(b"\n")[:5] + \
        start.read_bytes().split(b"\n")[6:]
    offset = [float(v) for v in lines[5].split()[1:]]
    assert abs(offset[0] - 0.1) < 0.05  # from 0.15 off


def test_a_key_that_cannot_move_is_refused(tmp_path, mitsuba):
    """Bad input: status 2, the key's line and column, the object it would move (by its
    line) and why, nothing written."""
    scene = tmp_path / "plane.ray"
    scene.write_text("light 1 1 1 ambient\ntranslate 0 -1 0\nplane\n")
    from raymitsuba import images

    target = tmp_path / "target.exr"
    images.write(str(target), np.zeros((8, 8, 3), np.float32))
    result = run(scene, "--target", target, "--params", "translate1.offset", "-o",
                 tmp_path / "out.ray")
    assert result.exit_code == 2
    assert re.search(r"plane\.ray:2:1: `translate1\.offset` cannot be a parameter: it moves "
                     r"the plane of line 3, and a plane cannot move", result.output), \
        result.output
    assert "Traceback" not in result.output and not (tmp_path / "out.ray").exists()
