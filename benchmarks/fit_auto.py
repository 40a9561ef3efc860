"""Issue 30's three fits through a checkered wall, with ``fit``'s defaults (no hand-chosen
scan): eta of a glass ball from 1.15 (true 1.5; the loss has a basin per checker square
seen through the ball), the camera's fov from 10 % off (33 and 27 degrees, true 30) and a
point light's position from 10 % off (every coordinate x 1.1); and the fov from 20 % off
(36 degrees: the steps alone end in another basin). Prints, for each, the
automatic scan's renders and time, the iterations, the wall time and the final value's
error; ``--scan none`` runs the same fits without the scan (the steps alone).

    ./dev python benchmarks/fit_auto.py [--size 64x48] [--iters 100] [--scan auto|none]
                                        [--only eta,eta+kt,fov+,fov-,fov20,light]

The scene is ``GLASS_OVER_CHECKER`` of tests/test_fit.py (that of ``examples/fit_glass.py
--checker 0.4``); spp 16 (a 4 x 4 lattice: the checker edges' derivatives).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

# the scene of tests/test_fit.py (one copy; lookat is the default origin)
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from test_fit import GLASS_OVER_CHECKER as SCENE  # noqa: E402

# name: (keys, start values, the key whose error is reported, its true value)
FITS = {
    "eta": (["mat2.ior"], {"mat2.ior": 1.15}, "mat2.ior", 1.5),
    "eta+kt": (["mat2.refractivity", "mat2.ior"], {"mat2.refractivity": 0.5, "mat2.ior": 1.15},
               "mat2.ior", 1.5),
    "fov+": (["camera.fov"], {"camera.fov": 33.0}, "camera.fov", 30.0),
    "fov-": (["camera.fov"], {"camera.fov": 27.0}, "camera.fov", 30.0),
    "fov20": (["camera.fov"], {"camera.fov": 36.0}, "camera.fov", 30.0),  # 20 % off
    "light": (["light1.position"], {"light1.position": (-1.32, 0.88, -2.42)}, "light1.position",
              (-1.2, 0.8, -2.2)),
}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="64x48", help="WxH (default 64x48)")
    parser.add_argument("--iters", type=int, default=100, help="Adam steps (default 100)")
    parser.add_argument("--scan", default="auto", choices=["auto", "none"])
    parser.add_argument("--only", default=",".join(FITS), help="which fits, comma-separated")
    args = parser.parse_args(argv)

    import raymitsuba
    from raymitsuba.fit import fit, set_values

    width, height = (int(v) for v in args.size.split("x"))
    target = raymitsuba.render(raymitsuba.load(SCENE, width=width, height=height,
                                               spp=16)).numpy()
    print(f"{width}x{height}, spp 16, {args.iters} iterations, scan={args.scan}")
    print(f"{'fit':8s} {'start':>22s} {'fitted':>30s} {'|error|':>9s} {'scan':>14s} "
          f"{'iters':>5s} {'wall':>7s}")
    rows = []
    for name in args.only.split(","):
        keys, start, key, true = FITS[name]
        loaded = raymitsuba.load(SCENE, width=width, height=height, spp=16)
        set_values(loaded, start)
        started = time.perf_counter()
        result = fit(loaded, target, keys, iters=args.iters, scan=args.scan)
        wall = time.perf_counter() - started
        error = float(np.max(np.abs(np.subtract(result.fitted[key], true))))
        show = (lambda v: f"{v:.4f}" if isinstance(v, float)
                else "(" + ", ".join(f"{x:.4f}" for x in v) + ")")
        scan = (f"{len(result.scanned)} r, {result.scan_seconds:.1f} s" if result.scanned
                else "-")
        print(f"{name:8s} {show(start[key]):>22s} {show(result.fitted[key]):>30s} "
              f"{error:9.2e} {scan:>14s} {result.iterations:5d} {wall:6.1f}s", flush=True)
        rows.append((name, error, result.iterations, wall))
    return rows


if __name__ == "__main__":
    main()
