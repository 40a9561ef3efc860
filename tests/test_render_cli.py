"""Tests of ``raymitsuba render`` (raymitsuba/render_cli.py) as a process: the output matches
the API's render bit for bit, stderr stays clean, a bad LLVM is one line, the progress bar."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np

from raymitsuba import render_cli

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
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
