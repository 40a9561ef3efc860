"""pytest configuration: the tests directory on the import path (``support``,
``reference_tracer``) and the shared fixtures. Helpers live in tests/support.py."""

from __future__ import annotations

import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))  # tests/support.py, tests/reference_tracer.py
# test_gradients.derivatives (the finite-difference check) is shared by other rooms' tests
sys.path.insert(1, os.path.join(os.path.dirname(__file__), "plugins", "whitted"))
# test_sphere_set's scenes (sphere_grid) are shared with the CLI's tests
sys.path.insert(2, os.path.join(os.path.dirname(__file__), "geometry"))


@pytest.fixture(scope="session")
def mitsuba():
    from raymitsuba.backend import mitsuba as get

    return get()
