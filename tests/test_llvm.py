"""Tests of raymitsuba/_llvm.py: which libLLVM is chosen for Dr.Jit, and the one-line error."""

from __future__ import annotations

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
