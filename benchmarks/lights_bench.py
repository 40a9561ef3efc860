"""How render cost grows with the number of lights (they are unrolled in the shading kernel).

    ./dev python benchmarks/lights_bench.py [--lights 1,8,64] [--width 512 --height 384]

For each count k, the scale benchmark's scene of 100 spheres (``scale_bench.spheres``)
with k point lights (of total intensity 1, spread on a ring above the scene) is rendered
in a fresh process with an empty Dr.Jit kernel cache: the first render (kernel
compilation included) and the median of 10 warm renders.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench import warm_render_times  # noqa: E402
from scale_bench import spheres  # noqa: E402


def scene(k):
    lights = "".join(
        f"light {1 / k:.6g} {1 / k:.6g} {1 / k:.6g} point "
        f"{10 * math.cos(2 * math.pi * i / k):.4f} 10 {10 * math.sin(2 * math.pi * i / k):.4f}\n"
        for i in range(k))
    return spheres(100) + lights


def measure(text, width, height):
    """(first render, median warm render) in this process."""
    import raymitsuba

    loaded = raymitsuba.load(text, width=width, height=height)
    t = time.perf_counter()
    raymitsuba.render(loaded).numpy()
    first = time.perf_counter() - t
    return first, statistics.median(warm_render_times(loaded, 10))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lights", default="1,8,64")
    ap.add_argument("--width", type=int, default=512)
    ap.add_argument("--height", type=int, default=384)
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        print(json.dumps(measure(scene(int(args.child)), args.width, args.height)))
        return
    print(f"100 spheres with k point lights, {args.width}x{args.height}, 1 spp, empty kernel cache")
    print(f"{'lights':>7} {'first s':>8} {'warm s':>8}")
    for k in (int(n) for n in args.lights.split(",")):
        with tempfile.TemporaryDirectory() as home:
            done = subprocess.run([sys.executable, __file__, "--child", str(k), "--width",
                                   str(args.width), "--height", str(args.height)],
                                  env=dict(os.environ, HOME=home), capture_output=True,
                                  text=True, check=True)
        first, warm = json.loads(done.stdout.strip().splitlines()[-1])
        print(f"{k:>7} {first:>8.3f} {warm:>8.3f}", flush=True)


if __name__ == "__main__":
    main()
