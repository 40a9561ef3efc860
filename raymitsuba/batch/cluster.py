"""The Dask client a batch runs on: an embedded local cluster, or a cluster's scheduler.

* :func:`connect` opens a ``distributed.Client``: to ``scheduler`` (an address such as
  ``tcp://10.0.0.1:8786``, or Dask's own ``DASK_SCHEDULER_ADDRESS``), else to a
  ``LocalCluster`` of ``jobs`` worker *processes* on loopback (127.0.0.1, no dashboard),
  one task at a time each. Dask's nanny starts them with multiprocessing's ``spawn``
  (set here, whatever the user's Dask configuration says): Dr.Jit's thread pool and LLVM
  do not survive a fork, and two renders in threads of one process crash.
* :class:`Setup`, a worker plugin registered before any work is sent: on every worker
  (and every worker that joins later, or is restarted by its nanny) it refuses a
  raymitsuba, mitsuba or drjit version other than the client's (images must not depend on
  where they were rendered) and a worker of several task threads (two renders in threads
  of one process crash: ``dask worker --nthreads 1``), sets Dr.Jit's thread count and renders a tiny scene once,
  so that the kernels a render needs are compiled (or read from the kernel cache) before
  the first item is timed.

Kernel caches: Dr.Jit keeps compiled kernels in ``DRJIT_CACHE_DIR`` (default
``~/.drjit``); where home is shared between machines, point it at local disk on each.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import os
from typing import Iterator, Optional

from distributed import WorkerPlugin

from raymitsuba.batch.runtime import SCHEDULER_ENV, check_versions, set_threads, versions

#: the scene the workers render once to warm their kernel caches (a sphere, a plane, a light)
WARM_SCENE = """
sphere
translate 0 -1 0
plane
light 1 1 1 point 0 4 4
"""
WARM_SIZE = 8  # pixels a side


class ThreadedWorker(RuntimeError):
    """A worker that would run several tasks at once, in threads of one process."""


def warm() -> None:
    """Render :data:`WARM_SCENE` once: the kernels every render needs, compiled or read from
    the kernel cache."""
    from raymitsuba import api

    loaded = api.load(WARM_SCENE, width=WARM_SIZE, height=WARM_SIZE)
    loaded.integrator.render_array(loaded.scene)


class Setup(WorkerPlugin):
    """On each worker: the versions checked against the client's ``expected``, Dr.Jit's
    ``threads`` set (None: Dr.Jit's default), the kernels warmed."""

    name = "raymitsuba-setup"

    def __init__(self, expected: dict, threads: Optional[int]):
        self.expected = expected  # the client's versions()
        self.threads = threads  # Dr.Jit threads per worker (None: Dr.Jit's default)

    def setup(self, worker):
        if worker.state.nthreads != 1:
            raise ThreadedWorker(
                f"this worker runs {worker.state.nthreads} tasks at a time; raymitsuba's "
                "need one each (dask worker --nthreads 1; Dr.Jit's threads: --threads): "
                "two renders in threads of one process crash")
        check_versions(self.expected)
        set_threads(self.threads)
        warm()

    def teardown(self, worker):
        # As the command line does on its way out (raymitsuba.cli.run): the objects still
        # alive out of the cyclic collector's sight, so that the worker's interpreter
        # does not trace them all again while it shuts down.
        gc.freeze()


def default_jobs() -> int:
    """Local workers by default: one per core."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def default_threads(jobs: int) -> int:
    """Dr.Jit threads per local worker by default: the cores shared out (at least one)."""
    return max(default_jobs() // max(jobs, 1), 1)


def _configure_dask() -> None:
    """Workers spawned, never forked, whatever the Dask configuration says."""
    import dask

    dask.config.set({"distributed.worker.multiprocessing-method": "spawn"})


@contextlib.contextmanager
def connect(jobs: Optional[int] = None, threads: Optional[int] = None,
            scheduler: Optional[str] = None) -> Iterator:
    """A ``distributed.Client`` ready for raymitsuba work (see the module docstring), closed
    (with its local cluster) when the block ends. ``jobs``: local workers (default: the
    cores); ``threads``: Dr.Jit threads per worker (default: the cores shared out locally,
    Dr.Jit's default on a cluster's workers); ``scheduler``: an address (default:
    ``DASK_SCHEDULER_ADDRESS``, else a local cluster)."""
    _configure_dask()
    from distributed import Client, LocalCluster

    scheduler = scheduler or os.environ.get(SCHEDULER_ENV) or None
    cluster = None
    try:
        if scheduler:
            client = Client(scheduler, timeout="30s")
        else:
            jobs = jobs or default_jobs()
            threads = threads or default_threads(jobs)
            cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None,
                                   # no dashboard; the scheduler's own HTTP routes (health)
                                   # on a free port of 127.0.0.1
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                                   silence_logs=logging.CRITICAL)
            client = Client(cluster)
        try:
            client.register_plugin(Setup(versions(), threads))
            yield client
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()
