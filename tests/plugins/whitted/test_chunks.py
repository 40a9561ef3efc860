"""Rendering in chunks (plugins/whitted/chunks.py, driven by plugins/whitted/integrator.py): the image does not
depend on how the camera rays are split, bit for bit; the tree's size is bounded (a chunk
too large is traced again in halves); gradients under chunking match finite differences."""

from __future__ import annotations

import numpy as np
import pytest

import test_gradients as tg
from support import load_ray

GLASS = "scenes/benchmark_glass.ray"
WHITTED = "scenes/whitted.ray"


@pytest.fixture(scope="module")
def mi():
    from raymitsuba.backend import mitsuba

    return mitsuba()


def unchunked(loaded):
    """Today's render: the whole image as one wavefront."""
    import drjit as dr

    with dr.suspend_grad():
        return loaded.integrator.render_image(loaded.scene).numpy()


def chunked(loaded, pixels=None, budget=None):
    integrator = loaded.integrator
    integrator.chunk_pixels = pixels
    if budget is not None:
        integrator.memory_budget = budget
    return integrator.render_array(loaded.scene)


@pytest.mark.parametrize("scene,spp", [(WHITTED, 1), (GLASS, 4), (GLASS, 3)])
def test_chunked_and_unchunked_renders_are_bit_identical(mi, scene, spp):
    import raymitsuba

    # 29 x 17: chunks of 1, 7, 29 (a row), 40 (across rows) and 100 pixels, and by budget
    loaded = raymitsuba.load(scene, width=29, height=17, spp=spp)
    want = unchunked(loaded)
    for pixels in (1, 7, 29, 40, 100, None):
        image = chunked(loaded, pixels)
        assert np.array_equal(image, want), pixels
        assert loaded.integrator.chunks == (-(-29 * 17 // pixels) if pixels else 1)
    # what mi.render (the API) returns is the same image
    assert np.array_equal(np.array(raymitsuba.render(loaded)), want)


def test_a_ranges_chunks_are_traced_in_whole_packets_of_the_images_lanes(mi):
    """A ray that ties between two surfaces may resolve by its packet mates (Embree's
    coherent packets, chunks.PACKET lanes): a range's chunk is cut, or traced with the rays
    around it, so that its packets are those of the image's own lane numbering."""
    from raymitsuba.plugins.whitted.chunks import PACKET, Job

    assert PACKET == 16
    band = Job(37, 5, 1, first=40, count=100)  # pixels 40 .. 139 of 185
    assert band.packet_margins(0, 10) == (40 % 16, 14)  # 32 .. 63: 8 before, 14 after
    assert band.packet_margins(0, 100) == (8, 4)  # .. 143
    assert Job(37, 5, 1, first=180).packet_margins(0, 5) == (4, 0)  # the image ends at 185
    assert Job(37, 5, 4, first=41).packet_margins(0, 3) == (1, 0)  # 4 pixels a packet
    assert Job(37, 5, 16, first=41).packet_margins(0, 3) == (0, 0)  # one pixel a packet
    assert Job(37, 5, 1, pixels=[3, 9]).packet_margins(0, 2) == (0, 0)  # a list: rays alone
    assert not Job(37, 5, 9, pixels=[3, 9]).coherent and band.coherent
    assert Job(37, 5, 144, pixels=[3, 9]).coherent  # each pixel 9 whole packets


def test_anti_aliasing_does_not_depend_on_the_memory_budget_where_rays_tie(mi):
    """scenes/mirror_hall.ray has coincident faces: at 512 x 384 with --aa, the chunks a
    200 MB budget cuts (none of them a whole number of packets) changed a pixel by 0.017
    while a ray's packet mates decided which face it hit (and a refined pixel's, the
    other pixels refined with it). Now a range is traced in whole packets and a list's
    rays alone: the same image at any budget."""
    import raymitsuba

    loaded = raymitsuba.load("scenes/mirror_hall.ray", aa=0.02)
    whole = loaded.integrator.render_array(loaded.scene)
    loaded.integrator.memory_budget = 200 << 20
    assert np.array_equal(loaded.integrator.render_array(loaded.scene), whole)
    assert loaded.integrator.chunks > 1  # (cut: not vacuous)


def test_a_tree_larger_than_the_budget_is_traced_again_in_halves(mi, monkeypatch):
    import raymitsuba
    from raymitsuba.plugins.whitted import chunks, guards
    from raymitsuba.plugins.whitted.camera import pixel_means

    monkeypatch.setattr(chunks, "MIN_CHUNK_RAYS", 1)
    loaded = raymitsuba.load(GLASS, width=32, height=24, spp=1, max_depth=8)
    want = unchunked(loaded)
    integrator = loaded.integrator
    sensor = loaded.scene.sensors()[0]
    # 600 rays at most: the first chunk, sized for 1 ray per camera ray, is too large
    chunker = chunks.Chunker(integrator.tracer, loaded.scene, sensor, 600 * guards.BYTES_PER_RAY,
                              rays_per_camera_ray=1.0)
    image = np.empty((32 * 24, 3), np.float32)
    largest = []

    def visit(start, count, color):
        import drjit as dr

        largest.append(sum(chunker.rays_per_generation))  # this chunk's tree
        image[start:start + count] = dr.ravel(pixel_means(color, count, 1)).numpy().reshape(-1, 3)

    chunker.run(chunks.Job(32, 24, 1), visit)
    assert max(largest) <= 600 and chunker.chunks_done > 32 * 24 * 2 / 600
    assert np.array_equal(image.reshape(24, 32, 3), want)


def test_a_pixel_whose_tree_exceeds_the_budget_is_refused(mi, monkeypatch):
    import raymitsuba
    from raymitsuba.plugins.whitted import chunks, guards

    monkeypatch.setattr(chunks, "MIN_CHUNK_RAYS", 1)
    loaded = raymitsuba.load(GLASS, width=16, height=12, max_depth=30, time_limit=0,
                             memory_budget=20 * guards.BYTES_PER_RAY)
    with pytest.raises(guards.BudgetError, match="ray tree of (one|a) pixel.*--bailout"):
        loaded.integrator.render_array(loaded.scene)


def test_renders_are_deterministic(mi):
    import raymitsuba

    loaded = raymitsuba.load(GLASS, width=24, height=16, spp=4)
    first = chunked(loaded, 9)
    assert np.array_equal(chunked(loaded, 9), first)
    assert np.array_equal(chunked(loaded, 50), first)


def test_a_chunk_holds_at_most_the_camera_rays_asked_for(mi):
    import raymitsuba
    from raymitsuba.plugins.whitted.chunks import Chunker, Job

    loaded = raymitsuba.load(GLASS, width=24, height=16)
    integrator, scene = loaded.integrator, loaded.scene
    chunker = Chunker(integrator.tracer, scene, scene.sensors()[0], integrator.memory_budget)
    sizes = []
    chunker.run(Job(24, 16, 16, pixels=np.arange(50, 70, dtype=np.uint32)),
                lambda start, count, color: sizes.append(count), lanes=100)
    assert sizes == [6, 6, 6, 2]  # 16 lanes a pixel: 6 fit in 100


def test_the_probe_estimates_the_rays_per_camera_ray(mi):
    import raymitsuba

    loaded = raymitsuba.load(GLASS, width=64, height=48)
    integrator = loaded.integrator
    integrator.render_image(loaded.scene)
    actual = sum(integrator.rays_per_generation) / (64 * 48)
    integrator.render_array(loaded.scene)
    estimate = integrator.estimated_rays / (64 * 48)
    assert 0.7 * actual < estimate < 1.3 * actual


def test_the_probe_extrapolates_a_tree_too_large_to_trace(mi, monkeypatch):
    from raymitsuba.plugins.whitted import chunks, guards
    import raymitsuba

    # 1.2x more rays per generation: about 6e5 rays per pixel, 2e9 for the image
    monkeypatch.setattr(chunks, "PROBE_RAYS", 20000)
    # (the exact tree: --bailout 0)
    loaded = raymitsuba.load(GLASS, width=64, height=48, max_depth=64, time_limit=60, bailout=0)
    # (the probe's tree is too large to trace: nothing measured, the nominal rate)
    with pytest.raises(guards.BudgetError,
                       match="about .* rays, an estimated .* min at 4 M rays/s .*--bailout"):
        loaded.integrator.render_array(loaded.scene)
    assert 3e8 < loaded.integrator.estimated_rays < 3e10
    loaded = raymitsuba.load(GLASS, width=64, height=48, max_depth=64, time_limit=0,
                             memory_budget=1 << 24, bailout=0)
    with pytest.raises(guards.BudgetError, match="the ray tree of a pixel needs"):
        loaded.integrator.render_array(loaded.scene)


def test_a_bailout_prunes_light_paths_and_leaves_heavy_ones(mi):
    # kr 0.1 kt 0.85 glass: a bailout of 0.05 drops every reflection's subtree beyond the
    # first bounce... and changes the image only by what those paths carried
    import raymitsuba

    exact = raymitsuba.load(GLASS, width=32, height=24, max_depth=6, bailout=0)
    pruned = raymitsuba.load(GLASS, width=32, height=24, max_depth=6, bailout=0.05)
    a, b = chunked(exact), chunked(pruned)
    assert pruned.integrator.estimated_rays < 0.8 * exact.integrator.estimated_rays
    assert np.abs(a - b).max() < 0.1 and not np.array_equal(a, b)
    # a zero bailout is the exact tree: every ray of weight > 0 traced, unchunked too
    assert np.array_equal(unchunked(exact), a)


@pytest.mark.parametrize("scene,key", [("glass", "mat2.ior"), ("phong", "mat1.color"),
                                       ("shadow", "mat2.refractivity"),
                                       ("spot", "light1.direction")])
def test_gradients_under_chunking_match_finite_differences(mi, scene, key):
    loaded = tg.load(scene)
    loaded.integrator.chunk_pixels = 7  # 7 pixels a chunk: rows split, many chunks
    finite, reverse, forward = tg.derivatives(mi, loaded, key, tg.seed_of(scene, key, "chunks"))
    assert abs(finite) > 0.1
    assert abs(reverse - finite) <= tg.REL_FD * abs(finite), (finite, reverse)
    assert abs(forward - finite) <= tg.REL_FD * abs(finite), (finite, forward)
    assert abs(reverse - forward) <= tg.REL_AD * abs(forward), (reverse, forward)


def test_gradients_do_not_depend_on_the_chunks(mi):
    import drjit as dr
    import raymitsuba

    grads = []
    for pixels in (None, 5, 33):
        loaded = tg.load("glass", size=12, spp=4)
        loaded.integrator.chunk_pixels = pixels
        params = loaded.params
        dr.enable_grad(params["mat2.ior"])
        params.update()
        dr.backward(dr.sum(raymitsuba.render(loaded), axis=None))
        grads.append(float(dr.grad(params["mat2.ior"])[0]))
    assert grads[1] == pytest.approx(grads[0], rel=1e-5)
    assert grads[2] == pytest.approx(grads[0], rel=1e-5)


def test_the_output_buffer_guard(mi, monkeypatch):
    import raymitsuba
    from raymitsuba.plugins.whitted import guards

    loaded = load_ray("sphere\n", 64, 64)
    monkeypatch.setattr(guards, "available_memory", lambda: 40_000)
    with pytest.raises(guards.BudgetError, match="64 x 64 float image needs"):
        loaded.integrator.render_array(loaded.scene)
    with pytest.raises(guards.BudgetError, match="64 x 64 float image needs"):
        loaded.integrator.render(loaded.scene)  # (assembled on the device: refused alike)
    # chunk by chunk into the caller's buffer: nothing to assemble, nothing refused
    stored = []
    assert loaded.integrator.render_array(loaded.scene,
                                          store=lambda first, v: stored.append(len(v))) is None
    assert sum(stored) == 64 * 64
    with pytest.raises(guards.BudgetError, match="2\\^32"):
        guards.check_image(65536, 32768, loaded.integrator.memory_budget)
    del raymitsuba


@pytest.mark.parametrize("pixels", [None, 7])
def test_the_image_kept_on_the_device_is_the_one_assembled_on_the_host(mi, pixels):
    """``render`` (mi.render's) keeps the chunks' pixels on the device, joined there when
    there are several; ``render_array`` assembles them on the host: the same bits."""
    import raymitsuba

    loaded = tg.load("glass", size=12, spp=4)
    loaded.integrator.chunk_pixels = pixels
    on_device = raymitsuba.render(loaded)
    chunks = loaded.integrator.chunks
    assert chunks == (1 if pixels is None else 21)  # 144 pixels, 7 a chunk
    assert np.array_equal(on_device.numpy(), loaded.integrator.render_array(loaded.scene))


@pytest.mark.parametrize("aa", [None, 0.02])
def test_a_band_of_rows_is_those_rows_of_the_whole_image(mi, aa):
    # bands of 1, 29, 17 and 1 rows (and small chunks inside them): the rows of the whole
    # render, bit for bit; with --aa each band's edge rows are refined as in the whole image
    import raymitsuba

    loaded = raymitsuba.load(WHITTED, width=64, height=48, aa=aa)
    whole = loaded.integrator.render_array(loaded.scene)
    loaded.integrator.chunk_pixels = 100
    bands = [loaded.integrator.render_array(loaded.scene, rows=rows)
             for rows in ((0, 1), (1, 30), (30, 47), (47, 48))]
    assert np.concatenate(bands).tobytes() == whole.tobytes()
    if aa:  # the test means something: refinement reaches rows at the bands' edges
        # (a pixel's decision: its own centre and corners; a band traces its corner rows)
        plain = raymitsuba.load(WHITTED, width=64, height=48)
        differs = (plain.integrator.render_array(plain.scene) != whole).any(axis=(1, 2))
        assert differs[[29, 30, 46]].any()


def test_rows_outside_the_image_are_refused(mi):
    import raymitsuba

    loaded = raymitsuba.load(WHITTED, width=16, height=8)
    with pytest.raises(ValueError, match="not within the image's 8 rows"):
        loaded.integrator.render_array(loaded.scene, rows=(4, 9))


def test_the_time_guards_rate_is_measured_by_the_scenes_first_render_and_kept(mi):
    import time

    import raymitsuba

    glass = raymitsuba.load(GLASS, width=96, height=64, spp=4)
    integrator = glass.integrator
    integrator.render_array(glass.scene)
    rate = integrator.rays_per_second
    assert rate is not None and integrator.stats.estimate.rays_per_second == rate
    start = time.perf_counter()
    integrator.render_array(glass.scene)  # warm: its kernels compiled
    seconds = time.perf_counter() - start
    assert integrator.rays_per_second == rate == integrator.stats.estimate.rays_per_second
    # an independent figure: the warm render's rays over its wall-clock time; the probe's
    # small kernels measure a lower bound of it, and a shared machine's noise is well
    # within the factor of 100 allowed each way
    wall = integrator.rays_traced / seconds
    assert wall / 100 < rate < wall * 100, (rate, wall)


def test_rays_that_carry_footprints_are_counted_at_twice_the_bytes(mi):
    """Anti-aliasing's rays carry offset rays through every bounce (differentials.py): a
    chunk's tree holds half as many of them within the same budget (measured: a 2048 x 1536
    anti-aliased render of scenes/aa_showcase.ray at --memory-budget 256M peaked 275 MB
    above the image's buffers counted at the primal's bytes, 166 MB at twice them)."""
    import raymitsuba
    from raymitsuba.plugins.whitted import chunks, guards

    plain = raymitsuba.load(GLASS, width=16, height=12)
    aa = raymitsuba.load(GLASS, width=16, height=12, aa=0.02)
    budget = 40000 * guards.BYTES_PER_RAY
    counted = [chunks.Chunker(loaded.integrator.tracer, loaded.scene,
                              loaded.scene.sensors()[0], budget).tree_rays(False)
               for loaded in (plain, aa)]
    assert counted == [40000, 40000 // guards.FOOTPRINT_FACTOR]
    assert guards.bytes_per_ray(True, True) == guards.BYTES_PER_RAY_AD * guards.FOOTPRINT_FACTOR
