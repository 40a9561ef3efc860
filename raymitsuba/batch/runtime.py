"""What every process that runs items shares, a Dask worker or this one, without Dask.

* :func:`versions` and :func:`check_versions`: the raymitsuba, mitsuba and drjit versions an
  image depends on; a worker whose versions are not the client's refuses work
  (:class:`VersionMismatch`): images must not depend on where they were rendered;
* :func:`set_threads`: Dr.Jit's thread count in this process;
* :data:`SCHEDULER_ENV`: where Dask's own tools read a scheduler's address from.

:mod:`raymitsuba.batch.core` (the items' loop) and :mod:`raymitsuba.batch.cluster` (the
Dask client and its workers' set-up) both read these; neither imports the other's
module for them, so the loop runs in process with Dask not imported.
"""

from __future__ import annotations

import functools
from typing import Optional

PACKAGES = ("raymitsuba", "mitsuba", "drjit")
#: the environment variable Dask's own tools read a scheduler's address from
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"


class VersionMismatch(RuntimeError):
    """A worker's raymitsuba, mitsuba or drjit differs from the client's."""


@functools.lru_cache(maxsize=None)
def _versions() -> tuple:
    from importlib.metadata import version

    return tuple((name, version(name)) for name in PACKAGES)


def versions() -> dict:
    """{package: version} of :data:`PACKAGES` in this process (read once)."""
    return dict(_versions())


def check_versions(expected: dict) -> None:
    """Raise :class:`VersionMismatch` unless this process has the ``expected`` versions."""
    here = versions()
    wrong = [f"{name} {here.get(name)} (the client has {want})"
             for name, want in expected.items() if here.get(name) != want]
    if wrong:
        raise VersionMismatch("this worker has " + ", ".join(wrong) +
                              ": images must not depend on where they were rendered")


def set_threads(threads: Optional[int]) -> None:
    """Dr.Jit's thread count in this process (None: Dr.Jit's default, every core)."""
    from raymitsuba.backend import mitsuba

    mitsuba(mitsuba_integrators=False)
    import drjit as dr

    if threads:
        dr.set_thread_count(int(threads))
