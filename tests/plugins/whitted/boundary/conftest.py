"""The boundary terms' tests (one module per module of plugins/whitted/boundary/): their
Mitsuba, a fixture; their scenes and helpers shared in tests/support_edges.py."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="module")
def mi():
    from raymitsuba.backend import mitsuba

    return mitsuba()
