"""Find a libLLVM that Dr.Jit's LLVM backend can use, before Dr.Jit is imported.

Dr.Jit 1.5 JIT-compiles its CPU kernels with the system's libLLVM, found through
the environment variable ``DRJIT_LIBLLVM_PATH`` or the loader's search path.
LLVM < 17 is not usable: LLVM 15 (Debian 12's default) aborts the whole
process on the first kernel (``Cannot select: f32 = fmaximum``) and LLVM 14 is
refused. So raymitsuba decides here, once and before any kernel runs, which
library Dr.Jit gets, and turns a missing or too old one into a one-line
:class:`LLVMError` that says what to install.

This module uses only the standard library: ``./dev`` runs it before the
virtual environment exists to decide whether ``libllvm19`` must be installed.
"""

from __future__ import annotations

import ctypes
import glob
import os
import re
import sys

MIN_VERSION = 17
ENV = "DRJIT_LIBLLVM_PATH"
INSTALL_HINT = ("install LLVM >= 17 (on Debian 12: `apt-get install libllvm19`, which ./dev "
                "does for you), or point DRJIT_LIBLLVM_PATH at its libLLVM.so")

_SEARCH_DIRS = ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64",
                "/usr/lib", "/usr/local/lib", "/opt/homebrew/opt/llvm/lib", "/usr/local/opt/llvm/lib")


class LLVMError(RuntimeError):
    """No usable libLLVM: the message is one line that says what to install."""


def library_version(path: str) -> tuple[int, int, int] | None:
    """The version a libLLVM reports through ``LLVMGetVersion`` (LLVM >= 16), else None."""
    try:
        lib = ctypes.CDLL(path)
        get_version = lib.LLVMGetVersion
    except (OSError, AttributeError):
        return None
    major, minor, patch = ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint()
    get_version(ctypes.byref(major), ctypes.byref(minor), ctypes.byref(patch))
    return major.value, minor.value, patch.value


def _version_from_name(path: str) -> int:
    """The major version in a library's file name (libLLVM-19.so, libLLVM.so.19.1), or 0."""
    name = os.path.basename(path)
    m = re.search(r"LLVM-(\d+)", name) or re.search(r"\.so\.(\d+)", name) \
        or re.search(r"llvm-(\d+)", path) or re.search(r"\.(\d+)\.dylib$", name)
    return int(m.group(1)) if m else 0


def candidates() -> list[str]:
    """libLLVM files on this machine, newest version first (by file name)."""
    found = set()
    for d in _SEARCH_DIRS:
        found.update(glob.glob(os.path.join(d, "libLLVM*.so*")))
        found.update(glob.glob(os.path.join(d, "libLLVM*.dylib")))
    found.update(glob.glob("/usr/lib/llvm-*/lib/libLLVM*.so*"))
    return sorted(found, key=lambda p: (_version_from_name(p), p), reverse=True)


def find() -> str:
    """Path of a libLLVM >= 17: ``$DRJIT_LIBLLVM_PATH`` if set, else the newest one found."""
    explicit = os.environ.get(ENV)
    if explicit:
        version = library_version(explicit)
        if version is None or version[0] < MIN_VERSION:
            known = version is not None or _version_from_name(explicit) > 0
            what = f"is older than LLVM {MIN_VERSION}" if known else "cannot be loaded"
            raise LLVMError(f"{ENV}={explicit} {what}; {INSTALL_HINT}")
        return explicit
    for path in candidates():
        if 0 < _version_from_name(path) < MIN_VERSION:
            continue  # too old by its name: not even loaded (names without a version come last)
        version = library_version(path)
        if version is not None and version[0] >= MIN_VERSION:
            return path
    raise LLVMError(f"no libLLVM >= {MIN_VERSION} found for Dr.Jit's LLVM backend; {INSTALL_HINT}")


def configure() -> str:
    """Point Dr.Jit at a usable libLLVM (sets ``DRJIT_LIBLLVM_PATH``); call before importing drjit."""
    path = find()
    os.environ[ENV] = path
    return path


if __name__ == "__main__":  # used by ./dev: exit 0 and print the path if a usable LLVM exists
    try:
        print(configure())
    except LLVMError as e:
        print(e, file=sys.stderr)
        sys.exit(1)
