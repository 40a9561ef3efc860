"""Tests of raymitsuba/batch/core.py: run_items over real Dask workers (the session's
two-worker cluster, conftest.py) and in this process; real SIGKILLs of real workers."""

from __future__ import annotations

import pytest

import batch_helpers
from raymitsuba.batch import run_items

pytestmark = pytest.mark.timeout(180)


def test_every_item_ends_as_one_result_in_the_items_order(client):
    results = run_items(batch_helpers.fail_on, [3, 1, 4, 1, 5], client=client)
    assert [r.value for r in results] == [9, 1, 16, 1, 25]
    assert all(r.ok and r.attempts == 1 for r in results)
    assert {r.worker for r in results} <= set(client.scheduler_info()["workers"])


def test_one_job_runs_in_this_process_without_a_cluster():
    results = run_items(batch_helpers.fail_on, [2, -1, 3], jobs=1)
    assert [(r.status, r.value, r.worker) for r in results] == [
        ("done", 4, "local"), ("failed", None, "local"), ("done", 9, "local")]
    assert results[1].error == "negative item -1"


def test_fail_fast_cancels_what_is_left_after_a_failure():
    results = run_items(batch_helpers.fail_on, [2, -1, 3], jobs=1, fail_fast=True)
    assert [r.status for r in results] == ["done", "failed", "cancelled"]


def test_a_worker_killed_under_an_item_is_replaced_and_the_item_retried(client, tmp_path):
    # item 2's first worker dies (SIGKILL); Dask's nanny restarts it, the scheduler runs
    # the item again: every result arrives, item 2 after 2 attempts, the others after 1
    items = [(str(tmp_path / f"marker-{i}"), i) if i == 2 else (str(tmp_path / "never"), i)
             for i in range(5)]
    (tmp_path / "never").touch()  # the other items find their marker: they never die
    results = run_items(batch_helpers.kill_the_first_time, items, client=client)
    assert [r.value for r in results] == [0, 1, 4, 9, 16]
    assert [r.attempts for r in results] == [1, 1, 2, 1, 1]
    client.wait_for_workers(2, timeout=60)


def test_an_item_that_kills_every_worker_fails_alone_with_its_reason(client):
    items = [(i == 1, i) for i in range(4)]
    results = run_items(batch_helpers.kill_on, items, client=client)
    assert [r.status for r in results] == ["done", "failed", "done", "done"]
    assert [r.value for r in results if r.ok] == [0, 4, 9]
    # allowed-failures 1 (conftest.py): given up when a second worker died under it
    assert results[1].attempts == 2
    assert results[1].error == "killed every worker it ran on (2)"
    client.wait_for_workers(2, timeout=60)


def test_a_worker_of_other_versions_refuses_each_item():
    # what a worker that joins after the batch began does (its setup's refusal is only
    # logged by Dask): the item is refused before it runs
    from raymitsuba.batch.runtime import VersionMismatch, versions
    from raymitsuba.batch.core import attempt

    assert attempt(batch_helpers.fail_on, 3, versions())[0] == 9
    with pytest.raises(VersionMismatch, match=r"drjit 1\.5\.0 \(the client has 0\.0\.1\)"):
        attempt(batch_helpers.fail_on, 3, dict(versions(), drjit="0.0.1"))
