"""How a fit step's cost grows with the number of objects: one material fitted among N.

    ./dev python benchmarks/fit_scale.py [--sizes 10,100,1000] [--width 256 --height 192]

For each N, the scale benchmark's sphere scene (``scale_bench.spheres``: N spheres on a
grid that fills the view, each with its own material) is rendered as the target; the
start perturbs mat1's diffuse_mix; ``raymitsuba.fit`` then fits mat1's color, diffuse_mix
and specular_mix for 16 iterations. It prints the median time of steps 4..15 (the first
ones compile kernels), the median warm render of the same scene, and both as ratios to
the smallest N, measured in this run.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench import warm_render_times  # noqa: E402
from scale_bench import spheres  # noqa: E402

KEYS = ["mat1.color", "mat1.diffuse_mix", "mat1.specular_mix"]


def fit_step(text, width, height):
    import raymitsuba
    from raymitsuba.fit import fit

    target = np.array(raymitsuba.render(raymitsuba.load(text, width=width, height=height)))
    loaded = raymitsuba.load(text, width=width, height=height)
    render = statistics.median(warm_render_times(loaded, 10))
    loaded.params["mat1.diffuse_mix"] = 0.3
    loaded.params.update()
    stamps = []
    fit(loaded, target, KEYS, iters=16, callback=lambda step: stamps.append(time.perf_counter()))
    return statistics.median(np.diff(stamps)[3:]), render


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10,100,1000")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=192)
    args = ap.parse_args()
    sizes = [int(n) for n in args.sizes.split(",")]
    print(f"fit step of one material among N spheres, {args.width}x{args.height}, 1 spp "
          f"(medians; ratios to N = {sizes[0]})")
    print(f"{'N':>7} {'step s':>8} {'render s':>9} {'step ratio':>11} {'render ratio':>13} "
          f"{'step/render':>12}")
    base = None
    for n in sizes:
        step, render = fit_step(spheres(n), args.width, args.height)
        base = base or (step, render)
        print(f"{n:>7} {step:>8.3f} {render:>9.3f} {step / base[0]:>11.2f} "
              f"{render / base[1]:>13.2f} {step / render:>12.2f}", flush=True)


if __name__ == "__main__":
    main()
