"""Tests of raymitsuba/batch/render.py (and tasks.py): render_many's outputs are the single
render's files, bit for bit; tiles (with and without --aa) are the untiled image; scene
errors, refused scenes, --skip-existing and an interrupted tiled render resumed."""

from __future__ import annotations

import hashlib
import json
import os
import signal

import pytest

import batch_helpers
from batch_support import SCENES, SIZE, single_render
from raymitsuba.batch import manifest, render_many
from raymitsuba.batch.tasks import textures_of, with_local_textures

pytestmark = pytest.mark.timeout(180)


def test_every_output_is_the_single_renders_file_bit_for_bit(client, tmp_path):
    # one format each: 8-bit PNG (sRGB), float EXR and NPY, JPEG
    outputs = [tmp_path / "batch" / f"{i}{ext}" for i, ext in
               enumerate((".png", ".exr", ".npy", ".jpg"))]
    os.makedirs(tmp_path / "batch")
    items = render_many(SCENES, outputs, client=client, srgb=True, **SIZE)
    assert [item.status for item in items] == ["done"] * 4
    for scene, output, item in zip(SCENES, outputs, items):
        want = single_render(scene, tmp_path / output.name, srgb=True, **SIZE)
        assert output.read_bytes() == want, scene
        assert item.sha256 == hashlib.sha256(want).hexdigest()
    lines = manifest.read(tmp_path / "batch" / manifest.NAME)
    assert sorted(line["output"] for line in lines) == sorted(map(str, outputs))
    assert all(line["status"] == "done" and line["attempts"] == 1 and
               line["worker"].startswith("tcp://127.0.0.1:") for line in lines)


def test_a_render_whose_worker_is_killed_is_retried_to_the_same_bytes(client, tmp_path):
    from raymitsuba.batch import run_items
    from raymitsuba.batch.tasks import RenderTask

    from raymitsuba.format import parser

    tasks = [RenderTask(parser.parse_file(s), dict(SIZE), textures_of(parser.parse_file(s)),
                        ext=".png") for s in SCENES]
    (tmp_path / "done").touch()
    items = [(str(tmp_path / ("first" if i == 1 else "done")), task)
             for i, task in enumerate(tasks)]
    results = run_items(batch_helpers.render_killing_the_first_time, items, client=client)
    assert [r.attempts for r in results] == [1, 2, 1, 1]  # scene 1's first worker died
    for scene, result in zip(SCENES, results):
        assert result.value == single_render(scene, tmp_path / "single.png", **SIZE), scene
    client.wait_for_workers(2, timeout=60)


def test_a_worker_killed_mid_batch_loses_nothing(client, tmp_path):
    # SIGKILL the first worker seen busy with a scene: its nanny restarts it, the scene is
    # retried; every output is written, each the single render's file, and the manifest
    # counts the attempts (exact counts: test_a_render_whose_worker_is_killed_...)
    scenes = SCENES * 3
    outputs = [tmp_path / f"{i}.png" for i in range(len(scenes))]
    killed = []

    def kill_a_busy_worker(done, total):
        busy = [address for address, keys in client.processing().items() if keys]
        if not killed and busy:
            killed.extend(client.run(os.getpid, workers=busy[:1]).values())
            os.kill(killed[0], signal.SIGKILL)

    items = render_many(scenes, outputs, client=client, progress=kill_a_busy_worker, **SIZE)
    assert len(killed) == 1
    assert [i.status for i in items] == ["done"] * len(scenes), [i.error for i in items]
    for scene, output in zip(scenes, outputs):
        assert output.read_bytes() == single_render(scene, tmp_path / "single.png", **SIZE)
    lines = manifest.read(tmp_path / manifest.NAME)
    assert sum(line["attempts"] for line in lines) == sum(i.attempts for i in items) >= \
        len(scenes)
    client.wait_for_workers(2, timeout=60)


def test_the_embedded_cluster_is_the_default(tmp_path):
    items = render_many(SCENES[:2], [tmp_path / "a.npy", tmp_path / "b.npy"], jobs=2, **SIZE)
    assert [i.status for i in items] == ["done", "done"]
    assert all(i.workers[0].startswith("tcp://127.0.0.1:") for i in items)
    assert (tmp_path / "a.npy").read_bytes() == single_render(SCENES[0], tmp_path / "w.npy",
                                                              **SIZE)


@pytest.mark.parametrize("aa", [None, 0.02])
def test_tiles_are_the_untiled_image_bit_for_bit(client, tmp_path, aa):
    # 5 bands of a 24-row image: edges inside the spheres' silhouettes, whose neighbours'
    # contrast decides --aa's refinement at the bands' edge rows
    options = dict(SIZE, **({"aa": aa} if aa else {}))
    items = render_many([SCENES[0]], [tmp_path / "tiled.npy"], client=client, tiles=5,
                        **options)
    assert items[0].status == "done" and items[0].attempts == 5
    want = single_render(SCENES[0], tmp_path / "whole.npy", **options)
    assert (tmp_path / "tiled.npy").read_bytes() == want
    assert not [p for p in os.listdir(tmp_path) if ".tiles-" in p]  # the bands removed


def test_an_interrupted_tiled_render_resumes_from_its_kept_bands(tmp_path):
    out = tmp_path / "poster.npy"

    def interrupt(done, total):
        if done >= 2 * SIZE["width"] * 6:  # after two of four bands of 6 rows
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        render_many([SCENES[1]], [out], jobs=1, tiles=4, progress=interrupt, **SIZE)
    assert not out.exists()
    [folder] = [p for p in os.listdir(tmp_path) if ".tiles-" in p]
    assert sorted(os.listdir(tmp_path / folder)) == ["tile-0000.npy", "tile-0001.npy"]
    items = render_many([SCENES[1]], [out], jobs=1, tiles=4, **SIZE)
    assert items[0].status == "done" and items[0].attempts == 2  # only the missing bands
    assert out.read_bytes() == single_render(SCENES[1], tmp_path / "whole.npy", **SIZE)


def test_a_scene_error_is_reported_and_the_other_scenes_rendered(client, tmp_path):
    bad = tmp_path / "bad.ray"
    bad.write_text("sphere\nlight 1 1 1 point 0 0 5\nspher 1\n")
    reported = []
    items = render_many([SCENES[0], bad, SCENES[2]],
                        [tmp_path / "a.png", tmp_path / "bad.png", tmp_path / "c.png"],
                        client=client, report=reported.extend, **SIZE)
    assert [i.status for i in items] == ["done", "error", "done"]
    assert items[1].error.startswith(f"{bad}:3:1: error: unknown command `spher`")
    assert items[1].attempts == 0  # never sent to a worker
    assert any(d.format().startswith(f"{bad}:3:1:") for d in reported)
    assert not (tmp_path / "bad.png").exists()
    assert (tmp_path / "c.png").read_bytes() == single_render(SCENES[2], tmp_path / "w.png",
                                                              **SIZE)


def test_a_render_the_guards_refuse_is_an_error_tried_once(client, tmp_path):
    # any render takes longer than a nanosecond: refused by the time guard on the worker
    items = render_many([SCENES[0]], [tmp_path / "a.png"], client=client, time_limit=1e-9,
                        **SIZE)
    assert items[0].status == "error" and items[0].attempts == 1
    assert "over the" in items[0].error and "limit" in items[0].error
    assert not (tmp_path / "a.png").exists()


def test_skip_existing_keeps_the_outputs_there_and_renders_the_missing(tmp_path):
    outputs = [tmp_path / "a.png", tmp_path / "b.png"]
    outputs[0].write_bytes(b"kept")  # complete, as every output written is
    items = render_many(SCENES[:2], outputs, jobs=1, skip_existing=True, **SIZE)
    assert [i.status for i in items] == ["skipped", "done"]
    assert outputs[0].read_bytes() == b"kept"
    assert items[0].sha256 == hashlib.sha256(b"kept").hexdigest()
    lines = {line["scene"]: line for line in manifest.read(tmp_path / manifest.NAME)}
    assert lines[SCENES[0]]["status"] == "skipped" and lines[SCENES[1]]["status"] == "done"
    assert json.dumps(lines[SCENES[0]])  # one JSON object per line


def test_textures_travel_as_bytes_to_files_of_the_worker():
    from raymitsuba.format import parser

    model = parser.parse_file(SCENES[1])
    textures = textures_of(model)
    assert textures  # the textured scene has some
    local = with_local_textures(model, textures)
    for before, after in zip(model.objects, local.objects):
        if before.texture is not None:
            assert after.texture.path != before.texture.path
            with open(after.texture.path, "rb") as f:
                assert f.read() == textures[before.texture.path]
