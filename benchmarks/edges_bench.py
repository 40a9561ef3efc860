"""Derivatives through moving edges: accuracy against finite differences, and cost.

    ./dev python benchmarks/edges_bench.py [--width 32 --height 24] [--cost-size 256x192]
                                           [--only accuracy,cost] [--repeats 5]

**Accuracy.** For each kind of discontinuity and parameter (a scene made for it), the
derivative of the image along a fixed direction by forward-mode AD on the k x k lattice
(``--spp k^2``, k = 2, 4, 8) against the reference: central finite differences on a 256 x
256 lattice per pixel (the image at 4 x 4 times the size, 64^2 samples per pixel, averaged
over 4 x 4 blocks), with a step that moves the edges by about 0.02 pixel
(``support_edges.fine_difference``; tests/support_edges.py says why: the tests' coarser
reference, 64^2 samples and 0.1 pixel, is as good for sums but shares an edge between two
pixels where it runs along their border, 7-8 % per pixel on a sphere). Printed: the weighted
sum's error (fixed random weights) relative to the reference's weighted sum, and relative to
the sum of the terms' sizes (sum |w ref|: a derivative of both signs may nearly cancel in the
sum itself), and the per-pixel relative L2 error ||AD - ref|| / ||ref||.

**Cost.** At 256 x 192 (``--cost-size``), k = 4 (spp 16): the primal render, and a gradient
step as a fit takes it (new values, ``params.update()``, render + backward of an L2 loss),
on one loaded scene, for each of COST_KEYS: a geometry key (the ball's translate: the camera
still, only the ball's edges move) and a geometry key with the camera's (the eye: every
edge moves). Medians of 5, in this process, after two steps that compile the kernels; the
ratio of render + backward to the primal (the step less the move), and of the whole step;
then the kernels' own execution times of a step by part (the render, the adjoint pass, the
boundary terms) and the step's time outside kernels (Python, numpy, graph building,
launches).
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

from support_edges import (GLASS, MIRRORED_SHADOW, SNELL, SPOT,  # noqa: E402
                           SPHERE_ON_CHECKER as SCENE, TERMINATOR)

FLAT = """\
eye 0 0 5
fov 40
background 0.2 0.3 0.4
light 1 1 1 point 2 3 6
light 0.2 0.2 0.2 ambient
material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
"""
SHADED_SPHERE = FLAT + "translate 0.1 0.05 0\nscale 1.2 1.2 1.2\nsphere\n"
MIT_SPHERE = """\
eye 0 0 10 fov 30
background 0.2 0.3 0.4
surface 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
light 1 1 1 point 2 3 9
sphere 0.1 0.05 0 1.3
"""
TRIANGLE = FLAT + "rotateZ 10\ntriangle -1.1 -1 0  1.3 -0.7 0.3  0.2 1.2 0\n"
# the keys of the cost's gradient steps (see the module docstring)
COST_KEYS = (("translate2.offset",), ("translate2.offset", "camera.eye"))



# (kind of edge, parameter, scene, key, direction, step moving edges ~0.1 px at 32 x 24)
CASES = [
    ("silhouette", "sphere centre", MIT_SPHERE, "sphere1.center", (0.6, -0.8, 0.0), 0.03),
    ("silhouette", "sphere radius", MIT_SPHERE, "sphere1.radius", (1.0,), 0.03),
    ("silhouette", "translate", SHADED_SPHERE, "translate1.offset", (0.6, -0.8, 0.0), 0.015),
    ("silhouette", "scale", SHADED_SPHERE, "scale1.factors", (1.0, 1.0, 1.0), 0.015),
    ("outline", "rotate", TRIANGLE, "rotateZ1.angle", (1.0,), 0.5),
    ("outline", "triangle vertex", TRIANGLE, "triangle1.v1", (0.6, -0.8, 0.0), 0.015),
    ("all primary", "eye", SCENE, "camera.eye", (0.6, 0.0, -0.8), 0.02),
    ("all primary", "lookat", SCENE, "camera.lookat", (0.6, -0.8, 0.0), 0.01),
    ("all primary", "fov", SCENE, "camera.fov", (1.0,), 0.1),
    ("shadow", "point light position", SCENE, "light1.position", (0.6, 0.0, -0.8), 0.05),
    ("terminator", "point light position", TERMINATOR, "light1.position", (0.0, 0.6, 0.8),
     0.05),
    ("checker seen through glass", "eta", GLASS, "mat2.ior", (1.0,), 0.002),
    ("total internal reflection", "eta", SNELL, "mat1.ior", (1.0,), 0.002),
    ("shadow seen in a mirror", "point light position", MIRRORED_SHADOW, "light1.position",
     (0.6, 0.0, -0.8), 0.05),
    ("spot cone", "spot position", SPOT, "light1.position", (0.6, 0.0, 0.8), 0.02),
    ("spot cone", "spot direction", SPOT, "light1.direction", (0.0, 0.0, 1.0), 0.02),
]


def accuracy(mi, width, height):
    from support_edges import fine_difference, forward, relative_l2

    rng = np.random.default_rng(13)
    weights = rng.random((height, width, 3))
    print(f"accuracy at {width} x {height}: AD on the k x k lattice vs finite differences "
          "of the 256 x 256 lattice (steps moving the edges about 0.02 pixel)")
    print("| edge | parameter | k | weighted sum: error | error / sum of sizes | "
          "per-pixel relative L2 |")
    print("| --- | --- | --- | --- | --- | --- |")
    for kind, label, text, key, direction, h in CASES:
        options = dict(width=width, height=height)
        reference = fine_difference(mi, text, key, direction, h, **options)
        ref_sum = float(np.sum(weights * reference))
        size = float(np.sum(np.abs(weights * reference)))
        for k in (2, 4, 8):
            grad = forward(mi, text, key, direction, k * k, **options)
            error = abs(float(np.sum(weights * grad)) - ref_sum)
            print(f"| {kind} | {label} | {k} | {error / abs(ref_sum):.2%} | {error / size:.2%} | "
                  f"{relative_l2(grad, reference):.2%} |", flush=True)


def cost(mi, width, height, keys, repeats=5):
    """The primal render and a gradient step with respect to ``keys`` as a fit takes it, on
    one loaded scene: new values of the keys (a move of 1e-3 either way; new leaves,
    detached from the last step's as an optimizer's are: a value computed from the last one
    would chain every step's backward to all the earlier ones), ``params.update()`` (the
    geometry moved, the Jacobians computed again), render and backward. Medians of
    ``repeats`` of each, the two alternated, after two steps that compile the kernels; wall
    time, and the process's CPU time (all its threads: steadier than wall time on a shared
    machine). Then where a step's time goes: its kernels' own execution times by part
    (:func:`kernel_times`), and the rest."""
    import drjit as dr
    import raymitsuba

    from raymitsuba.plugins.whitted import boundary

    plain = raymitsuba.load(SCENE, width=width, height=height, spp=16)

    def primal():
        started = time.perf_counter()
        raymitsuba.render(plain).numpy()
        return time.perf_counter() - started

    target = mi.TensorXf(raymitsuba.render(plain).numpy())
    scene = raymitsuba.load(SCENE, width=width, height=height, spp=16)
    params = scene.params
    pairs = []
    surrogates = boundary.Boundary.surrogates

    def counted(self, all_pairs, lo, hi):  # (the boundary pass's pair count)
        if lo == 0:
            pairs.append(len(all_pairs["kind"]))
        return surrogates(self, all_pairs, lo, hi)

    def move(i):
        for key in keys:
            v = dr.detach(params[key])  # (a new leaf, as an optimizer's step makes it)
            shift = 1e-3 if i % 2 == 0 else -1e-3
            params[key] = mi.Point3f(v.x + shift, v.y, v.z + shift)
            dr.enable_grad(params[key])
        params.update()

    def render_and_backward(ran=lambda part: None):
        image = raymitsuba.render(scene)
        ran("render")
        dr.backward(dr.mean(dr.square(image - target), axis=None))
        dr.grad(params[keys[-1]]).numpy()
        ran("boundary terms")

    def step(i):
        started, cpu = time.perf_counter(), time.process_time()
        move(i)
        moved = time.perf_counter()
        render_and_backward()
        done = time.perf_counter()
        return done - started, moved - started, time.process_time() - cpu

    primal(), step(0), step(1)  # (compile the kernels)
    # (alternated, so that both see the same share of a shared machine)
    primals, steps = [], []
    boundary.Boundary.surrogates = counted
    try:
        for i in range(repeats):
            primals.append(primal())
            steps.append(step(i))
    finally:
        boundary.Boundary.surrogates = surrogates
    p = statistics.median(primals)
    s = statistics.median(t for t, _, _ in steps)
    u = statistics.median(m for _, m, _ in steps)
    c = statistics.median(c for _, _, c in steps)
    r = statistics.median(t - m for t, m, _ in steps)  # (render + backward)
    print(f"\ncost at {width} x {height}, spp 16 (k = 4), medians of {repeats}, keys "
          f"{', '.join(keys)}: primal {p * 1e3:.1f} ms; render + backward {r * 1e3:.1f} ms, "
          f"ratio {r / p:.2f}; the whole step {s * 1e3:.1f} ms (with the move, "
          f"params.update(), {u * 1e3:.1f} ms; CPU time {c * 1e3:.1f} ms), ratio {s / p:.2f}; "
          f"boundary pairs {pairs[-1]} ({pairs[-1] / (width * height):.2f} per pixel)")
    kernels = kernel_times(mi, move, render_and_backward, repeats)
    parts = ", ".join(f"{part} {t:.1f} ms ({t / (p * 1e3):.2f} x the primal)"
                      for part, t in kernels.items())
    print("the kernels' own execution times in a step (Dr.Jit's kernel history, medians of "
          f"{repeats} more steps, synchronized after each part): {parts}; the step's time "
          "outside kernels (its wall time less theirs: Python, numpy, graph building, "
          f"launches) {s * 1e3 - sum(kernels.values()):.1f} ms")


def kernel_times(mi, move, render_and_backward, repeats):
    """{part of a gradient step: its kernels' execution time, ms} (medians of ``repeats``
    steps): the render (the primal kernels of mi.render's forward evaluation), the adjoint
    pass (its chunks' kernels, up to the boundary terms), the boundary terms (every kernel
    after). Each part is synchronized at its end (dr.sync_thread: waiting adds nothing to
    a kernel's own time), so these steps are not the timed ones."""
    import drjit as dr

    from raymitsuba.plugins.whitted import boundary

    times = {"render": [], "adjoint pass": [], "boundary terms": []}

    def ran(part):
        dr.sync_thread()
        times[part].append(sum(k.get("execution_time", 0.0) for k in dr.kernel_history()))

    backward = boundary.Boundary.backward

    def timed(self, grad_in):
        ran("adjoint pass")
        return backward(self, grad_in)

    dr.set_flag(dr.JitFlag.KernelHistory, True)
    boundary.Boundary.backward = timed
    try:
        for i in range(repeats):
            move(i)
            dr.sync_thread()
            dr.kernel_history()  # (the move's kernels left out)
            render_and_backward(ran)
    finally:
        boundary.Boundary.backward = backward
        dr.set_flag(dr.JitFlag.KernelHistory, False)
    return {part: statistics.median(t) for part, t in times.items()}


def figure(mi, path, width=64, height=48):
    """The derivative images of a moving light (its shadow edge and shading), in a picture:
    the reference, AD with the boundary terms (k = 4) and AD without them (the interior
    term alone, as before issue 13)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from raymitsuba.plugins.whitted import boundary
    from support_edges import finite_difference, forward

    case = dict(text=SCENE, key="light1.position", direction=(0.6, 0.0, -0.8))
    options = dict(width=width, height=height)
    reference = finite_difference(mi, h=0.05, **case, **options)
    full = forward(mi, spp=16, **case, **options)
    moving_kinds = boundary.moving_kinds
    boundary.moving_kinds = lambda tracer, scene: set()
    try:
        interior = forward(mi, spp=16, **case, **options)
    finally:
        boundary.moving_kinds = moving_kinds
    panels = [("finite differences, 64 x 64 lattice", reference),
              ("AD, k = 4, with boundary terms", full), ("AD, k = 4, interior only", interior)]
    limit = np.percentile(np.abs(reference.sum(-1)), 99)
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.4))
    for ax, (title, image) in zip(axes, panels):
        ax.imshow(image.sum(-1), cmap="RdBu_r", vmin=-limit, vmax=limit)
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.suptitle("d image / d light1.position (along (0.6, 0, -0.8)), summed over r, g, b")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    print(f"wrote {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--width", type=int, default=32)
    ap.add_argument("--height", type=int, default=24)
    ap.add_argument("--cost-size", default="256x192")
    ap.add_argument("--repeats", type=int, default=5, help="steps timed (medians)")
    ap.add_argument("--only", default="accuracy,cost")
    ap.add_argument("--figure", default=None, help="also write the derivative images (PNG)")
    args = ap.parse_args()
    from raymitsuba.backend import mitsuba

    mi = mitsuba()
    only = set(args.only.split(","))
    if "accuracy" in only:
        accuracy(mi, args.width, args.height)
    if "cost" in only:
        w, h = (int(v) for v in args.cost_size.split("x"))
        for keys in COST_KEYS:
            cost(mi, w, h, keys, args.repeats)
    if args.figure:
        figure(mi, args.figure)


if __name__ == "__main__":
    main()
