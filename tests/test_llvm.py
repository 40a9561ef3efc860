"""Tests of raymitsuba/_llvm.py: which libLLVM is chosen for Dr.Jit, and the one-line error."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from raymitsuba import _llvm


def test_unversioned_libraries_are_tried_after_old_versioned_ones(monkeypatch):
    found = ["/lib/libLLVM-15.so.1", "/opt/llvm/lib/libLLVM.so"]  # newest first, by name
    monkeypatch.delenv(_llvm.ENV, raising=False)
    monkeypatch.setattr(_llvm, "candidates", lambda: found)
    loaded = []

    def version(path):
        loaded.append(path)
        return {"/opt/llvm/lib/libLLVM.so": (18, 1, 8)}.get(path)

    monkeypatch.setattr(_llvm, "library_version", version)
    assert _llvm.find() == "/opt/llvm/lib/libLLVM.so"
    assert loaded == ["/opt/llvm/lib/libLLVM.so"]  # the old one is not even loaded


def test_no_usable_library_is_an_llvm_error(monkeypatch):
    monkeypatch.delenv(_llvm.ENV, raising=False)
    monkeypatch.setattr(_llvm, "candidates", lambda: ["/lib/libLLVM-15.so.1", "/lib/libLLVM.so"])
    monkeypatch.setattr(_llvm, "library_version", lambda path: None)
    with pytest.raises(_llvm.LLVMError, match="no libLLVM >= 17 found") as error:
        _llvm.find()
    assert "\n" not in str(error.value)


def test_an_explicit_old_library_is_refused_in_one_line(monkeypatch):
    monkeypatch.setenv(_llvm.ENV, "/lib/libLLVM-15.so.1")
    monkeypatch.setattr(_llvm, "library_version", lambda path: None)  # < 16: no LLVMGetVersion
    with pytest.raises(_llvm.LLVMError, match="libLLVM-15.so.1 is older than LLVM 17") as error:
        _llvm.find()
    assert "\n" not in str(error.value)


# ---- on this machine's libraries (Debian 12 with libllvm19: see ./dev) ---------------------

SCRIPT = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                      "raymitsuba", "_llvm.py")
LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1"
LLVM15 = "/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1"
needs_llvm19 = pytest.mark.skipif(not os.path.exists(LLVM19), reason="needs Debian's libllvm19")
needs_llvm15 = pytest.mark.skipif(not os.path.exists(LLVM15), reason="needs Debian 12's libllvm15")


def run_script(**env):
    """``python raymitsuba/_llvm.py`` (what ./dev runs before the venv exists) with ``env``."""
    environment = {k: v for k, v in os.environ.items() if k != _llvm.ENV} | env
    return subprocess.run([sys.executable, SCRIPT], capture_output=True, text=True,
                          env=environment, timeout=120)


@pytest.mark.parametrize("path, major", [
    ("/usr/lib/x86_64-linux-gnu/libLLVM-19.so", 19),
    ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", 19),
    ("/usr/lib/x86_64-linux-gnu/libLLVM-15.so.1", 15),
    ("/usr/lib/llvm-14/lib/libLLVM.so", 14),
    ("/opt/homebrew/opt/llvm/lib/libLLVM.19.dylib", 19),
    ("/opt/llvm/lib/libLLVM.so", 0),
])
def test_the_version_in_a_file_name(path, major):
    assert _llvm._version_from_name(path) == major


@needs_llvm19
def test_llvm_get_version_reads_the_real_library():
    version = _llvm.library_version(LLVM19)
    assert version is not None and version[:2] == (19, 1)


def test_a_missing_library_has_no_version(tmp_path):
    assert _llvm.library_version(str(tmp_path / "libLLVM.so.99")) is None


@needs_llvm19
def test_the_script_prints_a_usable_library_and_exits_0():
    result = run_script()
    assert result.returncode == 0, result.stderr
    assert _llvm.library_version(result.stdout.strip())[0] >= _llvm.MIN_VERSION


@needs_llvm19
def test_drjit_libllvm_path_overrides_the_search(monkeypatch):
    link = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"  # not the one the search picks first
    monkeypatch.setenv(_llvm.ENV, link)
    assert _llvm.find() == link
    assert run_script(**{_llvm.ENV: link}).stdout.strip() == link
    monkeypatch.setenv(_llvm.ENV, "")
    assert _llvm.find() != ""  # empty: not set


@needs_llvm15
def test_llvm_15_is_refused_in_one_line_naming_the_package_to_install():
    # in a child process: LLVM 15 is loaded to ask for its version (it has no LLVMGetVersion)
    result = run_script(**{_llvm.ENV: LLVM15})
    assert result.returncode == 1 and result.stdout == ""
    message = result.stderr.strip()
    assert "\n" not in message
    assert message.startswith(f"{_llvm.ENV}={LLVM15} is older than LLVM 17")
    assert "apt-get install libllvm19" in message


def test_an_unloadable_explicit_path_is_refused(tmp_path):
    result = run_script(**{_llvm.ENV: str(tmp_path / "nothing.so")})
    assert result.returncode == 1
    assert "cannot be loaded" in result.stderr and "apt-get install libllvm19" in result.stderr
