"""Running one function over many items on Dask workers: :func:`run_items`, the machinery
every batch command shares (rendering scenes, tiles, fits; any per-item function).

``fn(item)`` must be a pure function of its item, importable by the workers (a function
of a module, pickled by reference) and return what the client needs (image bytes, a
tile, a fitted scene's text): files are written by the client only. Each item ends as one
:class:`Result`, in the order of the items:

* ``done``: ``value`` is ``fn(item)``;
* ``error``: ``fn`` raised :class:`ItemError` -- the item itself is wrong (a scene no
  memory budget can hold); deterministic, so it is not retried;
* ``failed``: ``fn`` raised anything else, or the item killed every worker it ran on
  (Dask retries an item whose worker died, its nanny restarting the worker, until the
  scheduler's ``distributed.scheduler.allowed-failures``); ``error`` says why;
* ``cancelled``: not run, after a failure with ``fail_fast``.

``attempts`` counts the workers an item was started on (1 plus the workers that died
under it), ``worker`` the address of the one that finished it (``local`` in process).

In this process (``jobs=1``, no client or scheduler) Dask is not imported: ``-j 1``
costs no more than the loop it replaces.
"""

from __future__ import annotations

import os
import sys
import time
import uuid
from dataclasses import dataclass
from typing import Any, Callable, Iterable, List, Optional

from raymitsuba.batch.runtime import SCHEDULER_ENV, check_versions, set_threads, versions
from raymitsuba.util import error_message

LOCAL = "local"  # the worker name of an item run in this process


class ItemError(Exception):
    """Raised by an item's function: the item itself is wrong (reported, never retried)."""


@dataclass
class Result:
    """How one item ended (see the module docstring)."""

    item: Any  # the item, as given
    status: str = "done"  # done, error, failed or cancelled
    value: Any = None  # fn(item), when done
    error: Optional[str] = None  # one line, when not done
    attempts: int = 0  # workers the item was started on
    seconds: float = 0.0  # of the attempt that ended it, on its worker
    worker: Optional[str] = None  # the address of that worker (LOCAL: in this process)

    @property
    def ok(self) -> bool:
        return self.status == "done"


def attempt(fn: Callable, item, expected: Optional[dict] = None) -> tuple:
    """Run ``fn(item)`` on a worker: (its value, the worker's address, seconds). With the
    client's ``expected`` versions, a worker of others refuses the item first
    (``VersionMismatch``; a worker that joined after the batch began, whose setup refusal
    Dask only logs)."""
    if expected is not None:
        check_versions(expected)
    start = time.perf_counter()
    value = fn(item)
    where = LOCAL
    if "distributed" in sys.modules:  # a worker has it; in process it is not imported
        from distributed import get_worker

        try:
            where = get_worker().address
        except ValueError:  # not in a worker's task
            pass
    return value, where, time.perf_counter() - start


def run_items(fn: Callable, items: Iterable, client=None, jobs: Optional[int] = None,
              threads: Optional[int] = None, scheduler: Optional[str] = None,
              fail_fast: bool = False,
              on_result: Optional[Callable[[Result], None]] = None) -> List[Result]:
    """``fn`` over ``items``: one :class:`Result` per item, in their order.

    Where: ``client`` (any ``distributed.Client``), else ``scheduler`` (an address, or
    ``DASK_SCHEDULER_ADDRESS``), else ``jobs`` local workers (default: the cores; 1: in
    this process, no cluster); ``threads``: Dr.Jit threads per worker (see
    :func:`raymitsuba.batch.cluster.connect`). ``on_result(result)`` is called in this
    process as each item ends (in the order they end): where outputs are written.
    ``fail_fast``: after the first item not done, the rest are cancelled."""
    items = list(items)
    if client is None and jobs == 1 and not (scheduler or os.environ.get(SCHEDULER_ENV)):
        return _in_process(fn, items, threads, fail_fast, on_result)
    from raymitsuba.batch import cluster

    if client is not None:
        client.register_plugin(cluster.Setup(versions(), threads))
        return _on_client(client, fn, items, fail_fast, on_result)
    with cluster.connect(jobs, threads, scheduler) as client:
        return _on_client(client, fn, items, fail_fast, on_result)


def _in_process(fn, items, threads, fail_fast, on_result):
    set_threads(threads)
    results = []
    for item in items:
        if fail_fast and any(not r.ok for r in results):
            result = Result(item, "cancelled")
        else:
            start = time.perf_counter()
            try:
                value, where, seconds = attempt(fn, item)
                result = Result(item, "done", value, None, 1, seconds, where)
            except ItemError as e:
                result = Result(item, "error", None, str(e), 1,
                                time.perf_counter() - start, LOCAL)
            except Exception as e:
                result = Result(item, "failed", None, error_message(e), 1,
                                time.perf_counter() - start, LOCAL)
        results.append(result)
        if on_result is not None:
            on_result(result)
    return results


def _suspicious(dask_scheduler, key):
    """On the scheduler: how many workers died while running task ``key``."""
    ts = dask_scheduler.tasks.get(key)
    return 0 if ts is None else ts.suspicious


def _workers_died_under(client, key) -> int:
    try:
        return int(client.run_on_scheduler(_suspicious, key=key))
    except Exception:  # a scheduler that cannot say: no deaths counted
        return 0


def in_flight(client) -> int:
    """How many items the client keeps submitted: one per worker thread of the cluster now
    (at least one). The others wait here, not in a worker's queue, where Dask would count
    an item queued behind one that kills its worker as killed by it (and a few items are
    not held back at the scheduler, whatever its ``worker-saturation``)."""
    return max(sum(client.nthreads().values()), 1)


def _on_client(client, fn, items, fail_fast, on_result):
    from concurrent.futures import CancelledError

    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    batch = uuid.uuid4().hex[:12]
    expected = versions()
    waiting = iter(range(len(items)))  # items not submitted yet
    futures = {}  # submitted and not ended: future -> item index
    running = as_completed()

    def submit():
        """Submit items until each worker thread of the cluster has one (see in_flight)."""
        for i in waiting:
            future = client.submit(attempt, fn, items[i], expected,
                                   key=f"raymitsuba-{batch}-{i}", pure=False)
            futures[future] = i
            running.add(future)
            if len(futures) >= in_flight(client):
                return

    results: List[Optional[Result]] = [None] * len(items)
    try:
        submit()
        for future in running:
            i = futures.pop(future)
            if not fail_fast:  # the freed worker's next item first, then this one's result
                submit()
            try:  # (waits again if the worker holding the value died meanwhile)
                value, where, seconds = future.result()
            except CancelledError:
                result = Result(items[i], "cancelled")
            except KilledWorker:
                died = _workers_died_under(client, future.key)
                result = Result(items[i], "failed", None,
                                f"killed every worker it ran on ({died})", died)
            except ItemError as e:
                result = Result(items[i], "error", None, str(e),
                                _workers_died_under(client, future.key) + 1)
            except Exception as e:
                result = Result(items[i], "failed", None, error_message(e),
                                _workers_died_under(client, future.key) + 1)
            else:
                result = Result(items[i], "done", value, None,
                                _workers_died_under(client, future.key) + 1, seconds, where)
            future.release()
            results[i] = result
            if on_result is not None:
                on_result(result)
            if fail_fast:
                if not result.ok:
                    break
                submit()
        for future, i in list(futures.items()):  # after a failure with fail_fast
            future.cancel()
            del futures[future]
        for i in range(len(items)):
            if results[i] is None:
                results[i] = Result(items[i], "cancelled")
                if on_result is not None:
                    on_result(results[i])
    finally:
        if futures:  # interrupted: nothing left running for us
            client.cancel(list(futures))
    return results
