"""Tests of the ``raymitsuba`` command line (raymitsuba/cli/__init__.py): the group, the ``check``
command and ``python -m raymitsuba``. What the summary says is tested in test_summary.py."""

from __future__ import annotations

import subprocess
import sys

import pytest
from click.testing import CliRunner

from raymitsuba.cli import main

VALID = """\
# two spheres, a cone and a floor
eye 0 2 10
light 1 1 1 point 0 5 5
light 0.2 0.2 0.2 ambient
material 1 0 0 0.1 0.9 0 1 0 0 1
translate 2 0 0
scale 2 2 2
sphere
reset
sphere
rotateZ 90
cone
reset
plane
"""


def run(*args):
    return CliRunner().invoke(main, list(args))


@pytest.fixture
def valid(tmp_path):
    path = tmp_path / "valid.ray"
    path.write_text(VALID)
    return path


@pytest.fixture
def invalid(tmp_path):
    path = tmp_path / "invalid.ray"
    path.write_text("sphere 1\nrotatey2 3\nlight 1 1 1 ambient\n")
    return path


def test_every_command_has_help():
    result = run("--help")
    assert result.exit_code == 0
    assert [line.split()[0] for line in result.stdout.split("Commands:")[1].strip().splitlines()] \
        == ["check", "compare", "convert", "fit", "render"]
    for command in ("check", "compare", "convert", "fit", "render"):
        assert run(command, "--help").exit_code == 0
        # -h in a fresh process: click caches a command's help option, so a test that ran the
        # command on its own (without the group's -h) would change the answer here
        short = subprocess.run([sys.executable, "-m", "raymitsuba", command, "-h"],
                               capture_output=True, text=True, timeout=120)
        assert short.returncode == 0 and short.stdout.startswith("Usage: "), short.stderr


class TestCheck:
    def test_valid_scene_exits_0_with_a_summary(self, valid):
        result = run("check", str(valid))
        assert result.exit_code == 0, result.output
        assert result.stdout.splitlines() == [
            f"{valid}: ok",
            "  dialect    COMP 575",
            "  camera     eye (0, 2, 10)  lookat (0, 0, 0)  up (0, 1, 0)  fov 45",
            "  background (0, 0, 0)",
            "  objects    4 (2 sphere, 1 plane, 1 cone)",
            "  lights     2 (1 ambient, 1 point)",
            "  materials  1 declared (plus the default)",
            "  bounds     (-1, -2, -2) to (6, 2, 2)  (planes are infinite and left out)",
            "  warnings   0",
        ]
        assert result.stderr == ""

    def test_invalid_scene_exits_2_with_diagnostics_on_stderr(self, invalid):
        # forced: a `sphere` with operands would mark the file as MIT 6.837
        result = run("check", "--dialect", "comp575", str(invalid))
        assert result.exit_code == 2
        assert result.stdout == ""
        assert f"{invalid}:1:8: error: `sphere` takes no operands, found 1" in result.stderr
        assert (f"{invalid}:2:1: error: unknown command `rotatey2`; did you mean `rotateY`?"
                in result.stderr)
        assert result.stderr.rstrip().endswith(f"{invalid}: invalid, 2 errors")

    def test_any_invalid_scene_makes_the_status_2(self, valid, invalid):
        result = run("check", str(valid), str(invalid), str(valid))
        assert result.exit_code == 2
        assert result.stdout.count(": ok") == 2

    def test_warnings_go_to_stderr_and_are_counted(self, tmp_path):
        path = tmp_path / "w.ray"
        path.write_text("eye 0 0 4\neye 0 0 6\nsphere\n")
        result = run("check", str(path))
        assert result.exit_code == 0
        assert f"{path}:2:1: warning: `eye` given again" in result.stderr
        assert f"{path}:3:1: warning: the scene has objects but no light" in result.stderr
        assert "  warnings   2" in result.stdout

    @pytest.mark.parametrize("make", [
        lambda p: p / "missing.ray",
        lambda p: p,  # a directory
        lambda p: (p / "bad.ray").write_bytes(b"\xff\x00\xfe sphere\n") and p / "bad.ray",
        lambda p: (p / "nan.ray").write_text("translate nan 1e400 0\n") and p / "nan.ray",
    ])
    def test_bad_input_never_gives_a_traceback(self, tmp_path, make):
        result = run("check", str(make(tmp_path)))
        assert result.exit_code == 2
        assert result.exception is None or isinstance(result.exception, SystemExit)
        assert "Traceback" not in result.output and "error:" in result.stderr

    def test_an_empty_scene_is_valid_and_has_no_bounds(self, tmp_path):
        path = tmp_path / "empty.ray"
        path.write_text("")
        result = run("check", str(path))
        assert result.exit_code == 0
        assert "  objects    0" in result.stdout
        assert "  bounds     none (no finite objects)" in result.stdout

    def test_no_scene_is_a_usage_error(self):
        assert run("check").exit_code == 2  # click's usage error

    def test_help_describes_the_exit_status(self):
        result = run("check", "--help")
        assert result.exit_code == 0
        assert "Validate .RAY SCENES" in result.stdout and "Exit status 0" in result.stdout

    def test_loads_neither_mitsuba_nor_drjit(self, valid):
        code = ("import sys\n"
                "from raymitsuba.cli import main\n"
                "try:\n"
                "    main(['check', sys.argv[1]])\n"
                "except SystemExit as e:\n"
                "    assert e.code == 0, e.code\n"
                "print(sorted(m for m in sys.modules if m.split('.')[0] in ('mitsuba', 'drjit')))\n")
        result = subprocess.run([sys.executable, "-c", code, str(valid)], capture_output=True,
                                text=True, timeout=120)
        assert result.returncode == 0, result.stderr
        assert result.stdout.splitlines()[-1] == "[]"

    def test_python_dash_m_runs_it_with_the_same_statuses(self, valid, invalid):
        ok = subprocess.run([sys.executable, "-m", "raymitsuba", "check", str(valid)],
                            capture_output=True, text=True, timeout=120)
        assert ok.returncode == 0 and f"{valid}: ok" in ok.stdout
        bad = subprocess.run([sys.executable, "-m", "raymitsuba", "check", str(invalid),
                              str(invalid.parent / "\udcff.ray")],
                             capture_output=True, timeout=120)
        assert bad.returncode == 2 and b"Traceback" not in bad.stderr
        assert b"rotatey2" in bad.stderr


# ---- both dialects -------------------------------------------------------------------------------
MIT = """\
# MIT 6.837 / a sphere over a mesh
viewport 20 12
surface 1 0 0 0.2 0.8 0.2 10 0 0 1
sphere 0 0 0 1
triangles
v -2 -2 -1  v 2 -2 -1  v 0 2 -1
f 0 1 2
end
light 1 1 1 point 0 3 6
"""


@pytest.fixture
def mit(tmp_path):
    path = tmp_path / "mit.ray"
    path.write_text(MIT)
    return path


class TestDialects:
    def test_check_names_the_dialect(self, mit):
        result = run("check", str(mit))
        assert result.exit_code == 0, result.output
        lines = result.stdout.splitlines()
        assert lines[1] == "  dialect    MIT 6.837"
        assert "  image      20 x 12 (viewport)" in lines
        assert "  meshes     1 (1 triangles, 1 block)" in lines
        assert "fov 30 (horizontal)" in lines[2]

    def test_check_with_a_forced_dialect(self, mit, valid):
        assert run("check", "--dialect", "mit6837", str(mit)).exit_code == 0
        forced = run("check", "--dialect", "comp575", str(mit))
        assert forced.exit_code == 2 and "unknown command `surface`" in forced.stderr
        assert run("check", "--dialect", "mit6837", str(valid)).exit_code == 2
        assert run("check", "--dialect", "nope", str(valid)).exit_code == 2

    def test_a_mixed_file_is_one_error(self, tmp_path):
        path = tmp_path / "mixed.ray"
        path.write_text("material 1 1 1 1 1 0 1 0 0 1\nsphere 0 0 0 1\n")
        result = run("check", str(path))
        assert result.exit_code == 2
        assert (f"{path}:2:1: error: line 2 uses `sphere` (MIT 6.837) but line 1 uses "
                f"`material` (COMP 575)") in result.stderr

    def test_render_takes_the_viewport_size_unless_told(self, mit, tmp_path, mitsuba):
        import numpy as np

        out = tmp_path / "out.npy"
        result = run("render", str(mit), "-o", str(out))
        assert result.exit_code == 0, result.output
        assert np.load(out).shape == (12, 20, 3)
        assert run("render", str(mit), "-o", str(out), "--width", 8).exit_code == 0
        assert np.load(out).shape == (12, 8, 3)

    def test_render_a_bad_file_writes_nothing(self, tmp_path):
        path, out = tmp_path / "bad.ray", tmp_path / "out.png"
        path.write_text("triangles\nv 0 0 0\nf 0 1 2\n")
        result = run("render", str(path), "-o", str(out))
        assert result.exit_code == 2 and not out.exists()
        assert f"{path}:3:5: error: vertex index 1 is not defined" in result.stderr
        assert f"{path}:1:1: error: this `triangles` block is never closed" in result.stderr

    def test_fit_writes_the_index_back_as_a_ratio(self, tmp_path, mitsuba):
        from raymitsuba import images
        from support import render_ray

        glass = MIT.replace("0.2 10 0 0 1", "0.2 10 0 0.5 0.8")
        start, target, out = tmp_path / "s.ray", tmp_path / "t.exr", tmp_path / "o.ray"
        start.write_text(glass)
        images.write(str(target), render_ray(glass.replace("0.5 0.8", "0.5 0.7"), None, None))
        result = run("fit", str(start), "--target", str(target), "-o", str(out),
                     "--params", "mat1.ior", "--iters", 3, "-q")
        assert result.exit_code == 0, result.output
        fitted = out.read_text()
        assert fitted.splitlines()[0] == MIT.splitlines()[0]
        index = float(fitted.splitlines()[2].split()[-1])
        assert index != 0.8 and 0.5 < index < 1.2
        from raymitsuba.format.parser import parse_text

        ior = parse_text(fitted).materials[1].ior
        assert ior == pytest.approx(1 / index)
