"""The batch tests' shared cluster: two spawned workers on 127.0.0.1, one Dr.Jit thread
each, closed at the end of the session (raymitsuba.batch.cluster.connect). Dask's allowed
failures are 1 here (an item is given up after killing 2 workers) so that the fault tests
restart few workers; the rule tested is Dask's, whatever the count."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def client():
    import dask

    from raymitsuba.batch import cluster

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        with cluster.connect(jobs=2, threads=1) as c:
            c.wait_for_workers(2, timeout=60)
            yield c
