"""Mitsuba and Dr.Jit, set up once: the variant, the LLVM library, our plugins.

The variant is ``llvm_ad_rgb`` (CPU, differentiable) unless the environment
variable ``RAYMITSUBA_VARIANT`` names another (``cuda_ad_rgb`` on a machine with
an NVIDIA GPU). Nothing below this choice is CPU-specific. For an LLVM variant,
:mod:`raymitsuba._llvm` picks the libLLVM before Dr.Jit is imported, so that a
missing or too old LLVM is a one-line :class:`LLVMError`, not an abort.

Mitsuba's own Python AD integrators (``prb``, ``prbvolpath``, ``direct_projective``,
...) are loaded by ``mi.set_variant`` for every JIT variant; their ``@dr.syntax``
transforms make that the slowest step of start-up. raymitsuba never
uses them (its integrator is ``raywhitted``), so the command line asks
:func:`mitsuba` to skip them (``mitsuba_integrators=False``); the library loads them
as Mitsuba does unless told otherwise, and :func:`load_mitsuba_integrators` loads
them later if they were skipped.

The C library's allocator is tuned once, with the variant (:func:`tune_allocator`): a
gradient step allocates and frees tens of megabytes of numpy arrays (the boundary terms'
lattice), and glibc's defaults hand them back to the system and fault them in anew, page by
page, at every step.
"""

from __future__ import annotations

import ctypes
import importlib
import importlib.abc
import importlib.machinery
import os
import sys

from raymitsuba._llvm import LLVMError, configure

DEFAULT_VARIANT = "llvm_ad_rgb"
VARIANT_ENV = "RAYMITSUBA_VARIANT"
AD_INTEGRATORS = "mitsuba.python.ad.integrators"  # the package mi.set_variant (re)loads
# glibc's mallopt parameters, and what tune_allocator sets them to: blocks up to 64 MiB come
# from the heap (not a mapping of their own, unmapped when freed), and up to 256 MiB freed at
# its top stay with the process for the next allocations
M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3
MMAP_THRESHOLD, TRIM_THRESHOLD = 64 << 20, 256 << 20


def variant() -> str:
    return os.environ.get(VARIANT_ENV, DEFAULT_VARIANT)


def mitsuba(mitsuba_integrators: bool | None = None):
    """The ``mitsuba`` module with our variant set and plugins registered.

    ``mitsuba_integrators``: whether Mitsuba's own Python AD integrators are loaded.
    None (default): as Mitsuba does when this call sets the variant, nothing otherwise;
    False: skip them if this call sets the variant; True: load them if they were skipped.
    """
    name = variant()
    if name.startswith("llvm"):
        configure()
    tune_allocator()
    import drjit as dr
    import mitsuba as mi

    if mi.variant() != name:
        if name not in mi.variants():
            raise LLVMError(f"Mitsuba variant {name!r} is not available; choose one of {mi.variants()}")
        if mitsuba_integrators is False:
            _set_variant_without_ad_integrators(mi, name)
        else:
            mi.set_variant(name)
    backend = dr.JitBackend.LLVM if name.startswith("llvm") else dr.JitBackend.CUDA
    if not dr.has_backend(backend):
        raise LLVMError(f"Dr.Jit cannot start its {backend.name} backend for {name!r}")
    if mitsuba_integrators:
        load_mitsuba_integrators()
    from raymitsuba.plugins import register

    register()
    return mi


def tune_allocator() -> bool:
    """Keep freed memory for reuse (MMAP_THRESHOLD, TRIM_THRESHOLD): with glibc's defaults a
    block over its (adaptive) threshold is a mapping of its own, and the heap's free top past
    twice that is handed back, so a gradient step's lattice arrays were faulted in afresh at
    every step (benchmarks/edges_bench.py's cost scene at 256 x 192: about 4 ms of a 76 ms
    step). Nothing is done where the process's environment sets a ``MALLOC_`` variable (its
    owner chose), or the C library has no ``mallopt`` (not glibc). Returns whether it was
    set. What a render frees is kept for the process's next allocations (up to
    TRIM_THRESHOLD of it at the heap's top) instead of going back to the system; the guards'
    budgets count what a render holds, which this does not change."""
    global _allocator_tuned
    if _allocator_tuned is None:
        _allocator_tuned = False
        if not any(name.startswith("MALLOC_") for name in os.environ):
            try:
                mallopt = getattr(ctypes.CDLL(None), "mallopt", None)
            except (OSError, TypeError):  # (no C library to open by the process's name)
                mallopt = None
            if mallopt is not None:
                _allocator_tuned = bool(mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and \
                    bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD))
    return _allocator_tuned


_allocator_tuned = None  # (tune_allocator's answer, once asked)


class _SkipSubmodules(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Import hook: every submodule of ``package`` imports as an empty module."""

    def __init__(self, package: str):
        self.prefix = package + "."
        self.skipped: set[str] = set()

    def find_spec(self, fullname, path=None, target=None):
        if not fullname.startswith(self.prefix):
            return None
        self.skipped.add(fullname)
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec):
        return None  # the default module object

    def exec_module(self, module):
        pass


def _loaded_ad_integrators() -> list[str]:
    return [key for key in sys.modules if key.startswith(AD_INTEGRATORS + ".")]


def _set_variant_without_ad_integrators(mi, name: str) -> None:
    """``mi.set_variant(name)``, but with Mitsuba's AD integrator modules left unloaded.

    mi.set_variant imports (and reloads) the package ``mitsuba.python.ad.integrators``,
    whose ``__init__`` imports each integrator module. Here those imports yield empty
    modules, which are then removed again: afterwards the package is as if it had
    never imported them, so a later variant change, or :func:`load_mitsuba_integrators`,
    imports the real ones. Only in the usual state (none of them loaded yet); with
    integrator modules already loaded (another variant was set), a plain set_variant.
    """
    if _loaded_ad_integrators():
        mi.set_variant(name)
        return
    hook = _SkipSubmodules(AD_INTEGRATORS)
    sys.meta_path.insert(0, hook)
    try:
        mi.set_variant(name)
    finally:
        sys.meta_path.remove(hook)
        package = sys.modules.get(AD_INTEGRATORS)
        for key in hook.skipped:
            module = sys.modules.pop(key, None)
            if package is not None and module is not None:
                short = key[len(hook.prefix):]
                if package.__dict__.get(short) is module:
                    del package.__dict__[short]


def load_mitsuba_integrators() -> None:
    """Load Mitsuba's Python AD integrators (``prb``, ...) for the current variant if
    they are not loaded (raymitsuba's command line skips them at start-up)."""
    import mitsuba as mi

    variant_name = mi.variant()
    if not variant_name or variant_name.startswith("scalar") or _loaded_ad_integrators():
        return
    importlib.reload(importlib.import_module(AD_INTEGRATORS))
