"""Mitsuba and Dr.Jit, set up once: the variant, the LLVM library, our plugins.

The variant is ``llvm_ad_rgb`` (CPU, differentiable) unless the environment
variable ``RAYMITSUBA_VARIANT`` names another (``cuda_ad_rgb`` on a machine with
an NVIDIA GPU). Nothing below this choice is CPU-specific. For an LLVM variant,
:mod:`raymitsuba._llvm` picks the libLLVM before Dr.Jit is imported, so that a
missing or too old LLVM is a one-line :class:`LLVMError`, not an abort.
"""

from __future__ import annotations

import os

from raymitsuba._llvm import LLVMError, configure

DEFAULT_VARIANT = "llvm_ad_rgb"
VARIANT_ENV = "RAYMITSUBA_VARIANT"


def variant() -> str:
    return os.environ.get(VARIANT_ENV, DEFAULT_VARIANT)


def mitsuba():
    """The ``mitsuba`` module with our variant set and plugins registered."""
    name = variant()
    if name.startswith("llvm"):
        configure()
    import drjit as dr
    import mitsuba as mi

    if mi.variant() != name:
        if name not in mi.variants():
            raise LLVMError(f"Mitsuba variant {name!r} is not available; choose one of {mi.variants()}")
        mi.set_variant(name)
    backend = dr.JitBackend.LLVM if name.startswith("llvm") else dr.JitBackend.CUDA
    if not dr.has_backend(backend):
        raise LLVMError(f"Dr.Jit cannot start its {backend.name} backend for {name!r}")
    from raymitsuba.plugins import register

    register()
    return mi
