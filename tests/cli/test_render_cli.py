"""Tests of ``raymitsuba render`` (raymitsuba/cli/render.py) as a process: the output matches
the API's render bit for bit, stderr stays clean, a bad LLVM is one line, the progress bar."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from raymitsuba.cli import options as cli_options
from raymitsuba.cli import render as render_cli
from support import REPO

ROOT = REPO
SCENE = os.path.join(ROOT, "scenes", "whitted.ray")


def raymitsuba(*args, env=None):
    return subprocess.run([sys.executable, "-m", "raymitsuba", *map(str, args)],
                          capture_output=True, text=True, env=env, timeout=300)


def test_the_command_writes_what_the_api_renders(tmp_path):
    import raymitsuba as api

    out = tmp_path / "out.npy"
    result = raymitsuba("render", SCENE, "-o", out, "--width", 40, "--height", 30, "--spp", 4)
    assert result.returncode == 0, result.stderr
    assert result.stderr == ""  # nothing from Mitsuba, Dr.Jit or the interpreter's exit
    want = np.array(api.render(api.load(SCENE, width=40, height=30, spp=4)), dtype=np.float32)
    assert np.load(out).tobytes() == want.tobytes()


def test_an_unusable_llvm_is_one_line_and_no_output(tmp_path):
    out = tmp_path / "out.png"
    env = dict(os.environ, DRJIT_LIBLLVM_PATH=str(tmp_path / "libLLVM-99.so"))  # no such file
    result = raymitsuba("render", SCENE, "-o", out, "--width", 8, "--height", 8, env=env)
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert result.stderr.startswith("raymitsuba: error: DRJIT_LIBLLVM_PATH=")
    assert not out.exists()


class TestProgress:
    def test_off_the_terminal_it_never_loads_tqdm(self, monkeypatch):
        monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
        monkeypatch.setattr(render_cli.Progress, "DELAY", 0.0)
        monkeypatch.setitem(sys.modules, "tqdm", None)  # importing it would raise
        progress = render_cli.Progress(6)
        for done in range(1, 7):
            progress(done)
        progress.close()
        assert progress.bar is None

    def test_on_a_terminal_the_bar_appears_after_the_delay(self, monkeypatch):
        progress = render_cli.Progress(6)
        progress.enabled = True
        progress(1)  # within the delay: no bar yet
        assert progress.bar is None
        progress.start -= render_cli.Progress.DELAY
        progress(3)
        bar = progress.bar
        assert bar is not None and bar.n == 3 and bar.total == 6
        progress(6)
        assert bar.n == 6
        progress.close()
        assert progress.bar is None


def test_an_impossible_request_is_refused_up_front_in_one_line(tmp_path):
    out = tmp_path / "big.png"
    # 16384 x 16384 at 4096 spp: a trillion camera rays
    result = raymitsuba("render", SCENE, "-o", out, "--width", 16384, "--height", 16384,
                        "--spp", 4096)
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert "estimated" in result.stderr and "--time-limit" in result.stderr
    assert not out.exists()
    # the exact tree (--bailout 0) at depth 64 through glass: refused with the way out
    glass = os.path.join(ROOT, "scenes", "benchmark_glass.ray")
    result = raymitsuba("render", glass, "-o", out, "--width", 64, "--height", 48,
                        "--max-depth", 64, "--time-limit", 60, "--bailout", 0)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert "--bailout" in result.stderr and not out.exists()


def test_antialiasing_and_a_small_budget_from_the_command_line(tmp_path):
    import raymitsuba as api

    out = tmp_path / "out.npy"
    result = raymitsuba("render", SCENE, "-o", out, "--width", 40, "--height", 30, "--aa", 0.02,
                        "--memory-budget", "4M")
    assert result.returncode == 0, result.stderr
    loaded = api.load(SCENE, width=40, height=30, aa=0.02)
    assert np.load(out).tobytes() == np.array(api.render(loaded), dtype=np.float32).tobytes()
    # 8-bit output, encoded chunk by chunk, is the 8-bit encoding of the same image
    png = tmp_path / "out.png"
    assert raymitsuba("render", SCENE, "-o", png, "--width", 40, "--height", 30,
                      "--memory-budget", "2M").returncode == 0
    from raymitsuba import images

    plain = np.array(api.render(api.load(SCENE, width=40, height=30)))
    assert np.array_equal(images.read(str(png)), images.encode_8bit(plain) / np.float32(255.0))


def test_aa_alone_takes_the_records_threshold_wherever_it_stands():
    from raymitsuba import options

    alone = options.spec("aa").flag_value
    assert alone > 0 and options.RenderOptions(aa=True).aa == alone  # (True from Python)
    for args in ([SCENE, "--aa", "-o", "x.png"], ["--aa", SCENE, "-o", "x.png"],
                 [SCENE, "-o", "x.png", "--aa"]):
        params = render_cli.render.make_context("render", list(args)).params
        assert params["aa"] == alone and params["scenes"] == (SCENE,), args
    for args, value in ((["--aa", "0.05"], 0.05), (["--aa=0.1"], 0.1), ([], None)):
        params = render_cli.render.make_context("render", [SCENE, "-o", "x.png", *args]).params
        assert params["aa"] == value


def test_a_bad_memory_budget_is_a_usage_error(tmp_path):
    result = raymitsuba("render", SCENE, "-o", tmp_path / "x.png", "--memory-budget", "lots")
    assert result.returncode == 2 and "--memory-budget" not in result.stdout
    assert "expected a size" in result.stderr


def test_sizes():
    assert cli_options.parse_size("2G") == 2 << 30
    assert cli_options.parse_size("512M") == 512 << 20
    assert cli_options.parse_size("1.5GiB") == 3 << 29
    assert cli_options.parse_size("1000") == 1000


def test_the_bar_counts_pixels_and_chunks():
    progress = render_cli.Progress(100)
    progress.enabled = True
    progress.start -= render_cli.Progress.DELAY
    progress(40, 100, 2)
    assert progress.bar.n == 40 and "2 chunks" in str(progress.bar.postfix)
    progress(120, 160, 5)  # anti-aliasing added pixels to the total
    assert progress.bar.total == 160 and progress.bar.n == 120
    progress.close()
