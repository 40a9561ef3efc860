"""The primal render's first-generation answers, replayed by the adjoint pass after it
(plugins/whitted/replay.py): the derivative is the one the adjoint's own traversals give,
bit for bit, wherever it is replayed; a pass after the geometry, the camera or a light
moved does not replay; what a render records is bounded."""

from __future__ import annotations

import numpy as np
import pytest
from support_edges import SPHERE_ON_CHECKER as SCENE
from support_edges import tangent_derivative

WIDTH, HEIGHT = 24, 18
# the keys' tangents of the forward-mode derivative (forward mode: a pixel's derivative is
# its own sum, the same bits on every run; a reverse pass's key derivative is summed
# atomically, in the threads' order)
KEYS = {"translate2.offset": (0.6, -0.8, 0.0), "camera.eye": (0.6, 0.0, -0.8),
        "light1.position": (0.0, 1.0, 0.0)}


def derivative(mi, loaded, before_pass=None, adjoint_chunk=None, keys=KEYS):
    """The image's forward-mode derivative along KEYS' tangents, and the chunks of the
    derivative pass that replayed the recording. ``before_pass(loaded)``: called between the
    render and the derivative pass; ``adjoint_chunk``: the derivative pass's pixels a chunk
    (the render's as loaded); ``keys``: {key: tangent}."""
    def before(loaded):
        if before_pass is not None:
            before_pass(loaded)
        loaded.integrator.chunk_pixels = adjoint_chunk

    return tangent_derivative(loaded, keys, before), loaded.integrator.replayed


def load(primal_chunk=None, spp=16, **options):
    import raymitsuba

    loaded = raymitsuba.load(SCENE, width=WIDTH, height=HEIGHT, spp=spp, **options)
    loaded.integrator.chunk_pixels = primal_chunk
    return loaded


def forget(loaded):
    loaded.integrator.recording = None


@pytest.mark.parametrize("primal_chunk,adjoint_chunk", [(None, None), (50, 37)])
def test_the_adjoint_pass_replays_the_primal_renders_first_hits(mitsuba, primal_chunk,
                                                                 adjoint_chunk):
    """Replayed (in one chunk, or from a primal of several chunks into adjoint chunks that
    straddle them), the derivative is the one of the adjoint's own traversals, bit for bit."""
    replayed, chunks = derivative(mitsuba, load(primal_chunk), adjoint_chunk=adjoint_chunk)
    traced, none = derivative(mitsuba, load(primal_chunk), forget, adjoint_chunk)
    assert chunks >= (1 if adjoint_chunk is None else 2) and none == 0
    assert np.array_equal(replayed, traced) and np.count_nonzero(replayed) > replayed.size / 2


@pytest.mark.parametrize("key,shift", [("translate2.offset", (0.05, 0.0, 0.0)),
                                       ("camera.eye", (0.0, 0.05, 0.0)),
                                       ("light1.position", (0.0, 0.0, 0.3))])
def test_a_recording_is_not_replayed_once_what_it_answered_moved(mitsuba, key, shift):
    """The sphere, the eye or the light moved between the render and the backward pass:
    the derivative is the moved scene's (its own render's, which replays), not the
    recording's."""
    import drjit as dr

    def move(loaded):  # (the new value with its gradient and tangent, as derivative() sets them)
        params = loaded.params
        value = np.array(params[key].numpy()).ravel() + np.asarray(shift)
        params[key] = type(params[key])(*map(float, value))
        dr.enable_grad(params[key])
        params.update()
        dr.set_grad(params[key], type(params[key])(*KEYS[key]))

    moved, chunks = derivative(mitsuba, load(), move)
    fresh = load()
    move(fresh)
    expected, fresh_chunks = derivative(mitsuba, fresh)
    assert chunks == 0 and fresh_chunks >= 1
    assert np.array_equal(moved, expected)


def test_a_render_records_only_for_an_adjoint_pass_and_within_its_budget(mitsuba):
    """A render without a gradient enabled records nothing; nor does one whose recording
    would take more than a quarter of the memory budget (its derivative pass traces: the
    same derivative). (With the boundary terms, whose keys take more than a recording's
    4 times, a budget that holds them holds it: the light alone here, with 2 samples a
    pixel, has none.)"""
    import raymitsuba
    from raymitsuba.plugins.whitted import replay

    plain = load()
    raymitsuba.render(plain)
    assert plain.integrator.recording is None
    lanes = WIDTH * HEIGHT * 2
    needed = replay.recording_bytes(lanes, 1)  # 28 bytes a camera ray with one light
    assert needed == lanes * 28
    light = {"light1.position": KEYS["light1.position"]}
    tight = load(spp=2, memory_budget=4 * needed - 1024)
    traced, chunks = derivative(mitsuba, tight, keys=light)
    assert tight.integrator.recording is None and chunks == 0
    roomy = load(spp=2, memory_budget=4 * needed + 1024)
    replayed, chunks = derivative(mitsuba, roomy, keys=light)
    assert roomy.integrator.recording is not None and chunks >= 1
    assert np.array_equal(traced, replayed)
