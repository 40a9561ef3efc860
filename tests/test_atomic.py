"""Tests of raymitsuba/atomic.py: a file appears complete, with the usual mode, or not at all."""

from __future__ import annotations

import os
import stat

import pytest

from raymitsuba.atomic import atomic_path


def test_the_file_appears_only_when_the_block_ends(tmp_path):
    target = tmp_path / "out.ray"
    with atomic_path(str(target), ".ray") as tmp:
        assert tmp.endswith(".ray") and os.path.dirname(tmp) == str(tmp_path)
        with open(tmp, "w") as f:
            f.write("sphere\n")
        assert not target.exists()
    assert target.read_text() == "sphere\n"
    assert os.listdir(tmp_path) == ["out.ray"]


def test_the_file_gets_the_usual_mode_not_mkstemps_0600(tmp_path):
    umask = os.umask(0o022)
    try:
        with atomic_path(str(tmp_path / "out.png")) as tmp:
            open(tmp, "wb").close()
    finally:
        os.umask(umask)
    assert stat.S_IMODE(os.stat(tmp_path / "out.png").st_mode) == 0o644


@pytest.mark.parametrize("failure", [ValueError, KeyboardInterrupt])
def test_a_failure_leaves_the_old_file_and_no_temporary(tmp_path, failure):
    target = tmp_path / "out.exr"
    target.write_bytes(b"the old image")
    with pytest.raises(failure):
        with atomic_path(str(target), ".exr") as tmp:
            with open(tmp, "wb") as f:
                f.write(b"half a new im")
            raise failure()
    assert target.read_bytes() == b"the old image"
    assert os.listdir(tmp_path) == ["out.exr"]


def test_a_writer_that_removed_its_file_is_no_problem(tmp_path):
    with pytest.raises(OSError):
        with atomic_path(str(tmp_path / "x.npy")) as tmp:
            os.unlink(tmp)
            raise OSError("disk full")
    assert os.listdir(tmp_path) == []
