"""Tests of raymitsuba/testing.py, the pytest plugin, run on student test files by pytester:
a passing and a failing file, the failure's figures and diff picture, the reference cache
on disk."""

from __future__ import annotations

import re
import subprocess
import sys

import numpy as np
import pytest

from raymitsuba import images

pytest_plugins = ["pytester"]

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

# A student's test file: "my tracer" here is a file the test is given (rendered by
# raymitsuba at 24 x 18, or a copy with a block of pixels wrong).
STUDENT = """
from raymitsuba.testing import assert_image_matches

def test_ball():
    assert_image_matches("{image}", "{scene}")

def test_cache(raymitsuba_references):
    assert_image_matches("{image}", "{scene}")
    print("CACHE", raymitsuba_references.renders, raymitsuba_references.hits)
"""


@pytest.fixture
def files(tmp_path):
    scene = tmp_path / "ball.ray"
    scene.write_text(SCENE)
    from raymitsuba import api

    loaded = api.load(str(scene), width=24, height=18)
    good = tmp_path / "good.png"
    images.write(str(good), loaded.integrator.render_array(loaded.scene))
    wrong = images.read(str(good))
    wrong[4:8, 10:16] = 1 - wrong[4:8, 10:16]
    bad = tmp_path / "bad.png"
    images.write(str(bad), wrong)
    return scene, good, bad


@pytest.fixture(scope="module", autouse=True)
def imported(tmp_path_factory):
    """Every module the plugin uses, imported before ``pytester`` notes the modules: it drops
    those first imported during its test, and Dr.Jit's cannot be imported twice."""
    from raymitsuba.compare import compare_scene

    scene = tmp_path_factory.mktemp("warm") / "warm.ray"
    scene.write_text(SCENE)
    compare_scene(np.zeros((3, 4, 3)), str(scene)).diff_picture()


def test_a_matching_image_passes_and_the_reference_is_rendered_once(pytester, files):
    scene, good, _ = files
    pytester.makepyfile(test_mine=STUDENT.format(image=good, scene=scene))
    result = pytester.runpytest("-s", "-p", "no:cacheprovider")
    result.assert_outcomes(passed=2)
    # one reference (4 renders) for the session, the second test served from memory
    assert "CACHE 4 1" in result.stdout.str()


def test_a_wrong_image_fails_with_the_figures_and_a_diff_picture(pytester, files):
    scene, _, bad = files
    pytester.makepyfile(test_mine=STUDENT.format(image=bad, scene=scene))
    result = pytester.runpytest("-p", "no:cacheprovider")
    result.assert_outcomes(failed=2)
    out = result.stdout.str()
    assert "does not match" in out and "within 2/255" in out and "worst region" in out
    assert "Traceback" not in out  # the figures, not the plugin's insides
    path = re.search(r"diff picture: (\S+\.png)", out).group(1)
    picture = images.read(path)
    assert picture.shape[0] == 18 and picture.shape[1] > 3 * 24


def test_references_are_cached_on_disk_across_sessions(pytester, files):
    scene, good, _ = files
    pytester.makepyfile(test_mine=STUDENT.format(image=good, scene=scene))
    pytester.runpytest("-s").assert_outcomes(passed=2)
    again = pytester.runpytest("-s")  # a new session: the reference comes from the disk
    again.assert_outcomes(passed=2)
    assert "CACHE 0 2" in again.stdout.str()
    assert len(list((pytester.path / ".pytest_cache" / "d" / "raymitsuba").glob("*.npz"))) == 1
    # another option is another reference
    scene.write_text(SCENE + "\n")  # (other bytes: the key changes)
    pytester.runpytest("-s").assert_outcomes(passed=2)
    assert len(list((pytester.path / ".pytest_cache" / "d" / "raymitsuba").glob("*.npz"))) == 2


def test_arrays_and_image_references_work_without_a_scene():
    from raymitsuba.testing import assert_image_matches

    image = np.full((4, 5, 3), 0.5, np.float32)
    assert assert_image_matches(image, image.copy()).score.match == 100
    with pytest.raises(pytest.fail.Exception, match="sizes differ"):
        assert_image_matches(image, image[:3])


def test_the_plugin_imports_no_mitsuba_nor_numpy_at_collection():
    """The plugin loads with every pytest run: it must cost nothing until used."""
    code = ("import sys, raymitsuba.testing; "
            "print(sorted(m for m in ('mitsuba', 'drjit', 'numpy') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60).stdout
    assert out.strip() == "[]"
