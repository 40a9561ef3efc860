"""The samples' keys (plugins/whitted/boundary/samples.py): recorded in the adjoint pass's
chunks, the specular chain's traced in blocks of lattice rows."""

from __future__ import annotations

import numpy as np

from support_edges import MIRRORED_SHADOW, H, W, reverse, weights


def test_keys_in_chunks_and_blocks_of_rows_give_the_derivative_of_one_block(mi):
    """A memory budget that just holds the lattice's keys: the adjoint pass runs in several
    chunks (each records its samples' first-hit keys at their lattice points) and the
    specular chain's keys are traced in blocks of rows (three here, a block's arrays within
    it): the chain's keys (the mirror floor, seen by the lower half only, so the first
    block reaches no bounce) are made with the second block, filled in for the first. The
    derivative is the one-block lattice's, to the float32 order of the adjoint pass's sums
    over its chunks."""
    from raymitsuba.options import RenderOptions
    from raymitsuba.plugins.whitted.boundary import chain_depth, samples

    # (one point light, the default depth, a mirror and no glass)
    per_sample = samples.bytes_per_sample(chain_depth(RenderOptions().max_depth), 1, False)
    budget = W * H * 16 * per_sample
    w = weights()
    one = reverse(mi, MIRRORED_SHADOW, "camera.eye", w, 16)
    blocks = reverse(mi, MIRRORED_SHADOW, "camera.eye", w, 16, memory_budget=budget)
    assert np.all(one != 0.0)
    np.testing.assert_allclose(blocks, one, rtol=1e-5)
