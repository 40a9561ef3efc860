"""Tests of ``raymitsuba compare`` (raymitsuba/cli/compare.py): exit statuses, every input
format, --srgb, --json, --diff, and the batch with its CSV and HTML report, the latter
opened in a real browser (headless chromium)."""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from raymitsuba import images
from raymitsuba.cli import main
from raymitsuba.compare.picture import GAP
from support import open_in_browser

SCENE = """eye 0 1 5
lookat 0 0.3 0
background 0.2 0.3 0.5
light 0.2 0.2 0.2 ambient
light 0.8 0.8 0.8 point 3 4 5
material 0.9 0.4 0.2 1 0.8 0.3 20 0 0 1
sphere
material 0.8 0.8 0.8 1 1 0 1 0 0 1
translate 0 -1 0
plane
"""
W, H = 24, 18


def run(*args):
    return CliRunner().invoke(main, ["compare", *map(str, args)])


def gradient():
    y, x = np.mgrid[0:H, 0:W]
    # 8 x 8 blocks of one gray each: JPEG (8 x 8 blocks, no chroma to subsample) keeps
    # them within a level or two
    gray = 0.1 + 0.1 * (x // 8) + 0.2 * (y // 8)
    return np.repeat(gray[..., None], 3, -1).astype(np.float32)


@pytest.fixture
def scene(tmp_path):
    path = tmp_path / "ball.ray"
    path.write_text(SCENE)
    return path


@pytest.fixture
def rendered(tmp_path, scene):
    out = tmp_path / "ball.png"
    assert CliRunner().invoke(main, ["render", str(scene), "-o", str(out), "--width", str(W),
                                     "--height", str(H)]).exit_code == 0
    return out


def test_a_render_of_the_scene_passes_with_status_0(rendered, scene):
    result = run(rendered, scene)
    assert result.exit_code == 0, result.output
    assert "match: 100.000 %" in result.output and "PASS" in result.output
    assert re.search(r"left out \(reference not stable\): \d+ pixels", result.output)


def test_a_wrong_image_fails_with_status_1_and_says_where(tmp_path, rendered, scene):
    image = images.read(str(rendered))
    image[2:6, 3:9] = 1 - image[2:6, 3:9]  # 24 pixels in the tile x 3..5, y 2..4 and around
    wrong = tmp_path / "wrong.npy"
    images.write(str(wrong), image)
    result = run(wrong, scene, "--json")
    assert result.exit_code == 1
    figures = json.loads(result.output)
    assert figures["status"] == "fail" and figures["renders"] == 4
    # the 24 flipped pixels, less those left out (flipping may change a pixel by less than
    # the tolerance only where its value is near 0.5: none here)
    assert figures["failed"] + figures["left_out"] >= 24 >= figures["failed"] > 0
    assert figures["worst"][0] <= 3 and figures["worst"][1] <= 2
    assert run(wrong, scene, "--min-match", "80").exit_code == 0


@pytest.mark.parametrize("ext", [".exr", ".png", ".jpg", ".npy", ".ppm-p6", ".ppm-p3"])
def test_every_input_format_reads_as_the_image_it_holds(tmp_path, ext):
    want = gradient()
    reference = tmp_path / "want.npy"
    images.write(str(reference), want)
    path = tmp_path / ("image" + ext.split("-")[0])
    pixels = images.encode_8bit(want)
    if ext == ".ppm-p3":  # plain PPM, written by hand as a student tracer does
        values = " ".join(map(str, pixels.ravel()))
        path.write_text(f"P3\n# a student's tracer\n{W} {H}\n255\n{values}\n")
    elif ext == ".ppm-p6":
        path.write_bytes(f"P6\n{W} {H}\n255\n".encode() + pixels.tobytes())
    else:
        images.write(str(path), want)
    result = run(path, reference, "--json")
    assert result.exit_code == 0, result.output
    # 8-bit files round to within 0.5/255; JPEG's blocks of one color stay within 2/255
    assert json.loads(result.output)["match"] == 100


def test_srgb_decodes_8bit_images(tmp_path):
    want = gradient()
    reference, path = tmp_path / "want.exr", tmp_path / "srgb.png"
    images.write(str(reference), want)
    images.write(str(path), want, srgb=True)
    assert run(path, reference, "--srgb").exit_code == 0
    assert run(path, reference).exit_code == 1  # read as linear values: far too bright


def test_bad_inputs_exit_2_with_one_line(tmp_path, rendered, scene):
    junk = tmp_path / "junk.png"
    junk.write_text("not a picture")
    small = tmp_path / "small.npy"
    images.write(str(small), np.zeros((4, 4, 3)))
    bad = tmp_path / "bad.ray"
    bad.write_text("sphere\nfrob 1 2\n")
    cases = [((junk, scene), f"{junk}: cannot read image"),
             ((small, rendered), "sizes differ: image 4x4, reference 24x18"),
             ((tmp_path / "none.png", scene), "none.png: no such image"),
             ((rendered, bad), f"{bad}:2:1: error")]
    for args, message in cases:
        result = run(*args)
        assert result.exit_code == 2, result.output
        lines = result.output.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], result.output
    assert run(rendered, scene, "--diff", tmp_path / "d.txt").exit_code == 2
    for flag in ("--diff", "--report", "--csv"):  # (a folder that is not there: nothing done)
        out = tmp_path / "nowhere" / {"--diff": "d.png", "--report": "r.html", "--csv": "c.csv"}[flag]
        result = run(rendered, scene, flag, out)
        assert result.exit_code == 2 and "no folder" in result.output
    assert run(rendered, scene, scene).exit_code == 2  # two references, no {stem}


def test_diff_writes_image_reference_and_heat_map_side_by_side(tmp_path, rendered, scene):
    out = tmp_path / "diff.png"
    assert run(rendered, scene, "--diff", out).exit_code == 0
    picture = images.read(str(out))
    assert picture.shape == (H, 3 * W + 2 * GAP, 3)
    assert np.array_equal(picture[:, :W], picture[:, W + GAP:2 * W + GAP])  # image == reference


def test_batch_scores_every_scene_and_writes_a_report_that_a_browser_shows(tmp_path, scene,
                                                                             rendered):
    (tmp_path / "subs").mkdir()
    os.rename(rendered, tmp_path / "subs" / "ball.png")
    other = tmp_path / "other.ray"
    other.write_text(SCENE.replace("0.9 0.4 0.2", "0.2 0.4 0.9"))
    bad = tmp_path / "broken.ray"
    bad.write_text("sphere 1\n")
    (tmp_path / "subs" / "broken.png").write_bytes((tmp_path / "subs" / "ball.png").read_bytes())
    report, table = tmp_path / "report.html", tmp_path / "scores.csv"
    result = run(tmp_path / "subs" / "{stem}.png", scene, other, bad, "--report", report,
                 "--csv", table)
    # the bad scene is an input error (2), after the others were scored and reported
    assert result.exit_code == 2
    assert "ball: pass 100.000 %" in result.output and "other: missing" in result.output
    assert "broken.ray:1:" in result.output
    rows = list(csv.DictReader(table.open()))
    assert [(r["scene"], r["status"]) for r in rows] == [
        (str(scene), "pass"), (str(other), "missing"), (str(bad), "error")]
    assert rows[0]["match"] == "100.000" and rows[0]["psnr"] != ""

    dom, shot = open_in_browser(str(report), str(tmp_path))
    assert 'data-marked="3"' in dom  # the passing scene's three pictures ...
    assert dom.count(f'data-loaded="{W}x{H}"') == 3  # ... each loaded, at its size
    assert "<td>missing</td>" in dom and "<td>error</td>" in dom
    screenshot = images.read(shot)
    assert screenshot.shape[:2] == (1600, 1200)
    assert np.ptp(screenshot) > 0.5  # not a blank page


def test_one_comparison_and_a_batch_with_j1_do_not_import_dask(tmp_path, scene, rendered):
    # as raymitsuba render's single render: in this process, without Dask
    (tmp_path / "subs").mkdir()
    os.rename(rendered, tmp_path / "subs" / "ball.png")
    code = ("import sys; from raymitsuba.cli import main\n"
            "for args in (sys.argv[1:4], sys.argv[1:2] + sys.argv[4:]):\n"
            "    try:\n        main(args)\n    except SystemExit as e:\n"
            "        print('exit', e.code)\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in "
            "('dask', 'distributed')))")
    result = subprocess.run(
        [sys.executable, "-c", code, "compare", tmp_path / "subs" / "ball.png", scene,
         tmp_path / "subs" / "{stem}.png", scene, "-j", "1", "--csv", tmp_path / "s.csv"],
        capture_output=True, text=True, timeout=200)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines.count("exit 0") == 2 and lines[-1] == "[]", result.stdout
    rows = list(csv.DictReader((tmp_path / "s.csv").open()))
    assert [(r["status"], r["match"]) for r in rows] == [("pass", "100.000")]


def test_a_batchs_templates_are_refused_before_anything_runs(tmp_path, scene):
    other = tmp_path / "other.ray"
    other.write_text(SCENE)
    cases = [(("{student}.png", scene), "unknown placeholder {student}"),
             (("{stem}.png", scene, other, "--diff", tmp_path / "d.png"),
              "2 scenes need a template"),
             (("{stem}.png", scene, "--diff", tmp_path / "no" / "{stem}.png"), "no folder")]
    for args, message in cases:
        result = run(*args)
        assert result.exit_code == 2 and message in result.output, result.output
    assert sorted(os.listdir(tmp_path)) == ["ball.ray", "other.ray"]  # nothing written
