"""Per-item functions for the fault tests, run by the workers (imported by name: spawned
workers get the test process's import path). Each kills its own worker with SIGKILL, as
the kernel's OOM killer or a crash would."""

from __future__ import annotations

import os
import signal


def kill_the_first_time(item):
    """The item (marker path, value): the first worker to run it dies (the marker file
    says it did); the next returns value squared."""
    marker, value = item
    try:
        fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return value * value
    os.close(fd)
    os.kill(os.getpid(), signal.SIGKILL)


def kill_on(item):
    """The item (kill, value): with kill, every worker that runs it dies; else value squared."""
    kill, value = item
    if kill:
        os.kill(os.getpid(), signal.SIGKILL)
    return value * value


def fail_on(item):
    """Raises on a negative item, else returns its square."""
    if item < 0:
        raise ValueError(f"negative item {item}")
    return item * item


def render_killing_the_first_time(item):
    """The item (marker path, RenderTask): as :func:`kill_the_first_time`, then the task's
    render (raymitsuba.batch.tasks.render)."""
    from raymitsuba.batch.tasks import render

    marker, task = item
    kill_the_first_time((marker, 0))
    return render(task)
