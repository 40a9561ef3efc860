"""Tests of raymitsuba/batch/cluster.py: the workers are spawned processes listening on
127.0.0.1 only, run the Dr.Jit threads asked for, refuse a client of other versions; a
cluster started with Dask's own commands renders what a single render does."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import psutil
import pytest

from batch_support import SCENES, SIZE, single_render
from raymitsuba.batch import cluster, render_many

pytestmark = pytest.mark.timeout(180)


def _cmdline():
    with open("/proc/self/cmdline") as f:
        return f.read().replace("\0", " ")


def _thread_count():
    import drjit as dr

    return dr.thread_count()


def test_workers_are_spawned_processes_listening_on_loopback_only(client):
    for line in client.run(_cmdline).values():
        # multiprocessing's spawn starts a new interpreter; a fork would keep our command
        assert "from multiprocessing.spawn import spawn_main" in line
    pids = [os.getpid(), *client.run(os.getpid).values()]
    listening = {c.laddr.ip for pid in pids for c in psutil.Process(pid).net_connections()
                 if c.status == psutil.CONN_LISTEN}
    assert listening == {"127.0.0.1"}


def test_workers_run_the_dr_jit_threads_asked_for(client):
    assert set(client.run(_thread_count).values()) == {1}  # connect(threads=1): conftest.py


def test_a_worker_of_other_versions_is_refused_before_any_work(client):
    from raymitsuba.batch.runtime import VersionMismatch, versions

    other = dict(versions(), mitsuba="3.0.0")
    with pytest.raises(VersionMismatch, match=r"mitsuba 3\.9\.1 \(the client has 3\.0\.0\)"):
        client.register_plugin(cluster.Setup(other, 1))
    client.register_plugin(cluster.Setup(versions(), 1))  # as it was


def test_a_worker_running_tasks_in_threads_is_refused(tmp_path):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True, host="127.0.0.1",
                      dashboard_address=None, scheduler_kwargs={"dashboard_address":
                                                                "127.0.0.1:0"}) as local, \
            Client(local) as client:
        with pytest.raises(cluster.ThreadedWorker, match="runs 2 tasks at a time"):
            render_many(SCENES[:1], [tmp_path / "a.png"], client=client, **SIZE)
    assert not (tmp_path / "a.png").exists()


def read_scheduler_file(file, timeout):
    """The address in a scheduler file, once the scheduler has written it whole (the file
    appears before its JSON is complete)."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return json.loads(file.read_text())["address"]
        except (OSError, ValueError, KeyError):
            if time.monotonic() > deadline:
                raise TimeoutError(f"no scheduler address in {file} after {timeout} s")
            time.sleep(0.1)


@pytest.fixture
def external_cluster(tmp_path):
    """``dask scheduler`` and ``dask worker`` (the venv's), on 127.0.0.1: the address."""
    dask = os.path.join(os.path.dirname(sys.executable), "dask")
    file = tmp_path / "scheduler.json"
    started = []
    try:
        started.append(subprocess.Popen(
            [dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
             "--scheduler-file", str(file)], start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        address = read_scheduler_file(file, timeout=60)
        # (the worker is started only once the file is whole: it reads it as soon as it exists)
        started.append(subprocess.Popen(
            [dask, "worker", "--scheduler-file", str(file), "--nworkers", "2", "--nthreads",
             "1", "--host", "127.0.0.1", "--no-dashboard"], start_new_session=True,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        assert address.startswith("tcp://127.0.0.1:")
        yield address
    finally:
        for process in reversed(started):
            os.killpg(process.pid, signal.SIGKILL)  # the worker's nanny and its workers too
            process.wait(timeout=30)


def test_a_cluster_started_with_dask_commands_renders_what_a_single_render_does(
        external_cluster, tmp_path):
    from distributed import Client

    with Client(external_cluster, timeout="30s") as client:
        client.wait_for_workers(2, timeout=60)
    outputs = [tmp_path / "a.png", tmp_path / "b.exr"]
    items = render_many(SCENES[:2], outputs, scheduler=external_cluster, **SIZE)
    assert [i.status for i in items] == ["done", "done"]
    for scene, output in zip(SCENES, outputs):
        assert output.read_bytes() == single_render(scene, tmp_path / ("w" + output.suffix),
                                                    **SIZE)
    # the command, told the address
    result = subprocess.run(
        [sys.executable, "-m", "raymitsuba", "render", *SCENES[2:], "-o",
         tmp_path / "cli" / "{stem}.png", "--width", "32", "--height", "24", "--scheduler",
         external_cluster], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    for scene in SCENES[2:]:
        name = os.path.splitext(os.path.basename(scene))[0] + ".png"
        assert (tmp_path / "cli" / name).read_bytes() == \
            single_render(scene, tmp_path / "w.png", **SIZE)
    records = [json.loads(line) for line in
               (tmp_path / "cli" / "raymitsuba-manifest.jsonl").read_text().splitlines()]
    with Client(external_cluster, timeout="30s") as client:
        workers = set(client.scheduler_info()["workers"])
    assert {r["worker"] for r in records} <= workers and len(workers) == 2
