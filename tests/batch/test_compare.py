"""Tests of raymitsuba/batch/compare.py (compare_many), through ``raymitsuba compare
TEMPLATE SCENE...``: a batch on the two workers of the embedded loopback cluster gives
the figures, the report, the CSV and the pictures of the same batch in this process
(``-j 1``), and each scene's figures are those of its single comparison; a scene error is
reported as FILE:LINE:COLUMN before any comparison and a missing image as missing, the
others scored."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest
from click.testing import CliRunner

from batch_support import SCENES, SIZE, single_render
from raymitsuba import images
from raymitsuba.cli import main

pytestmark = pytest.mark.timeout(180)


def stem(scene) -> str:
    return os.path.splitext(os.path.basename(scene))[0]


def compare(*args):
    return CliRunner().invoke(main, ["compare", *map(str, args)])


def test_a_batch_on_two_workers_gives_the_figures_and_report_of_j1(client, tmp_path):
    from distributed import get_task_stream

    scenes = SCENES[:3]  # whitted, textured_objects (a texture: sent as bytes), mit6837_balls
    subs = tmp_path / "subs"
    subs.mkdir()
    for scene in scenes:  # each scene's own render, as float32: identical to its reference
        single_render(scene, subs / f"{stem(scene)}.npy", **SIZE)
    wrong = images.read(str(subs / "whitted.npy"))
    wrong[4:10, 5:12] = 1 - wrong[4:10, 5:12]  # 42 pixels changed
    images.write(str(subs / "whitted.npy"), wrong)
    bad = tmp_path / "bad.ray"
    bad.write_text("sphere\nmaterial 1 1\n")
    missing = SCENES[3]  # primitives.ray: no image
    references = [*scenes, bad, missing]

    def batch(tag, *where):
        out = tmp_path / tag
        out.mkdir()
        result = compare(subs / "{stem}.npy", *references, "--json", "--report",
                         out / "report.html", "--csv", out / "scores.csv", "--diff",
                         out / "{stem}.png", *where)
        assert result.exit_code == 2, result.output  # the bad scene, after the others
        assert f"{bad}:2:" in result.stderr and "Traceback" not in result.output
        return json.loads(result.stdout), out

    with get_task_stream(client) as stream:
        on_cluster, a = batch("cluster", "--scheduler", client.scheduler.address)
    workers = {t["worker"] for t in stream.data if t["key"].startswith("raymitsuba-")}
    assert len([t for t in stream.data if t["key"].startswith("raymitsuba-")]) == 3
    assert workers <= set(client.scheduler_info()["workers"])  # the comparisons ran there
    serial, b = batch("serial", "-j", "1")

    assert on_cluster == serial  # every figure, exactly
    for name in ("report.html", "scores.csv", *(f"{stem(s)}.png" for s in scenes)):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert [r["status"] for r in serial] == ["fail", "pass", "pass", "error", "missing"]
    assert serial[3]["message"].startswith(f"{bad}:2:")
    # an image identical to the reference: every scored pixel within the tolerance, no
    # difference at all; the changed one fails in the changed pixels only (42 of them,
    # less those left out as unstable)
    assert all(r["match"] == 100 and r["mean_abs"] == 0 for r in serial[1:3])
    assert 0 < serial[0]["failed"] <= 42
    for scene, record in zip(scenes, serial):  # each, as its single comparison scores it
        single = compare(subs / f"{stem(scene)}.npy", scene, "--json")
        assert json.loads(single.stdout) == record, scene
