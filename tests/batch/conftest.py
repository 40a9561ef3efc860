"""The batch tests' shared cluster: two spawned workers on 127.0.0.1, one Dr.Jit thread
each, closed at the end of the session (raymitsuba.batch.cluster.connect). Dask's allowed
failures are 1 here (an item is given up after killing 2 workers) so that the fault tests
restart few workers; the rule tested is Dask's, whatever the count."""

from __future__ import annotations

import os

import pytest

from support import REPO

#: tiny scenes of the gallery: both dialects, a texture, glass
SCENES = [os.path.join(REPO, "scenes", name) for name in
          ("whitted.ray", "textured_objects.ray", "mit6837_balls.ray", "primitives.ray")]
SIZE = dict(width=32, height=24)


@pytest.fixture(scope="session")
def client():
    import dask

    from raymitsuba.batch import cluster

    with dask.config.set({"distributed.scheduler.allowed-failures": 1}):
        with cluster.connect(jobs=2, threads=1) as c:
            c.wait_for_workers(2, timeout=60)
            yield c


def single_render(scene, output, **options):
    """``raymitsuba render SCENE -o OUTPUT`` (one scene: today's command), in this process."""
    from raymitsuba.cli import main

    args = ["render", str(scene), "-o", str(output)]
    for name, value in options.items():
        flag = "--" + name.replace("_", "-")
        args += [flag] if value is True else [flag, str(value)]
    try:
        main.main(args, standalone_mode=False)
    except SystemExit as e:
        assert e.code in (0, None), e
    with open(output, "rb") as f:
        return f.read()
