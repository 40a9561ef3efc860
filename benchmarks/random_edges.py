"""Edges on random scenes: AD against the pixel-integrated finite difference, per key kind.

    ./dev python benchmarks/random_edges.py [--seeds 50] [--first-seed 0] [--size 32x24]
        [--kinds camera.eye,sphere.radius,...] [--fd-k 96] [--ks 4,8,16] [--json OUT]
        [--cases]

A scene is generated from each seed (``tests/random_scenes.py``'s :func:`generate`; both dialects: COMP 575 seeds are
even, MIT 6.837 seeds odd) -- spheres, boxes and single triangles, MIT meshes, ellipsoids
(quadrics), cones, cylinders, a floor plane (checkered or a mirror), glass and mirror
materials, point / directional / spot lights, a random camera looking at the objects --
and one key of each kind that applies (:data:`KINDS`), along a random direction. Nobody
tunes these scenes: run many seeds, not the ones that pass.

**The reference** (``random_scenes.compare``). The central difference of the image
rendered on the k_FD x k_FD lattice (``--fd-k``, spp = k_FD^2; the lattice stands for the
pixel integral) with the step h / 2, h moving the nearest edges by about EDGE_PX pixel
(:func:`step`: from the pixel's size at the object's depth; the step was h until
2026-12-07). It is validated against the step h on the k_FD lattice, and the lattice
against k_FD / 2 at the step h; the FD's own uncertainty is the larger of the two
differences (of the
weighted sum, relative to |FD|), and a case whose uncertainty exceeds FD_UNSTABLE (or
whose FD is zero: nothing visible moves) is *flagged* and not counted; so is one whose
image has a kink at the key's value (the weighted second difference above FD_KINK of the
first: an edge on the image's border, which moves into it one way only -- a horizon at the
top row -- where the central difference is the mean of two one-sided derivatives).

**The extrapolated reference.** 2 FD(h / 2) - FD(h) (``random_scenes.compare``, which says
why): each case's line (``--cases``) gives the errors against it too ("ext").

**AD.** Forward mode on the k x k lattice (``--ks``, default 4, 8, 16); once per seed
(its first key), reverse mode at the first k against forward mode (printed when they
differ by more than 1e-4 relative).

Printed, per key kind: the number of cases counted (and flagged), the median and worst
relative error of the weighted sum Sum w AD vs Sum w FD (fixed random weights), relative to
|Sum w FD| and to Sum |w FD|, at each k, the median per-pixel relative L2 ||AD - FD|| /
||FD|| (and the FD's own: the larger of its per-pixel differences at h, and at k_FD / 2,
the floor under that column: the step moves edges by EDGE_PX / 2 pixel, and an edge
running along a pixel's border is shared between two), and whether the median errors fall with k
(and in how many cases the error at the last k is not below the first's). ``--cases``
also prints each case (seed, key, errors), so that a bad one can be taken apart:
``--seeds 1 --first-seed SEED --kinds KIND``.

Cost: at 32 x 24 with k_FD = 96, about 4 s a case on this project's 2-core machine (the
FD's seven renders take most of it), 50 seeds (~400 cases) about 25-30 minutes.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time

# the scenes and a case's comparison: tests/random_scenes.py (shared with the tests)
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))
from random_scenes import FD_UNSTABLE, KINDS, compare, generate  # noqa: E402


def table(cases, ks, kinds):
    print(f"| kind | cases: counted / vs abs(FD) (flagged) | " + " | ".join(
        f"k={k}: median / worst vs abs(FD) | vs sum abs(wFD) | pixel L2" for k in ks)
        + " | falls with k (cases not falling) | FD's own pixel L2 |")
    print("| --- | --- | " + " | ".join("--- | --- | ---" for _ in ks) + " | --- | --- |")
    for kind in kinds:
        all_ = [c for c in cases if c["kind"] == kind]
        if not all_:
            continue
        good = [c for c in all_ if "flag" not in c]
        n_rel = sum(1 for c in good if c["rel_counted"])
        cells = [kind, f"{len(good)} / {n_rel} ({len(all_) - len(good)})"]
        medians = []
        for k in ks:
            if not good:
                cells += ["-", "-", "-"]
                continue
            rel = [c["errors"][k]["rel"] for c in good if c["rel_counted"]] or [math.nan]
            rs = [c["errors"][k]["rel_size"] for c in good]
            l2 = [c["errors"][k]["l2"] for c in good]
            medians.append(statistics.median(rs))
            cells += [f"{statistics.median(rel):.2%} / {max(rel):.2%}",
                      f"{statistics.median(rs):.2%} / {max(rs):.2%}",
                      f"{statistics.median(l2):.1%} / {max(l2):.1%}"]
        if good:
            falls = all(a > b for a, b in zip(medians, medians[1:]))
            not_falling = sum(1 for c in good
                              if c["errors"][ks[-1]]["rel_size"]
                              >= c["errors"][ks[0]]["rel_size"])
            cells.append(f"{'yes' if falls else 'NO'} ({not_falling})")
            cells.append(f"{statistics.median(c['fd_pixel_uncertainty'] for c in good):.1%}")
        else:
            cells += ["-", "-"]
        print("| " + " | ".join(cells) + " |", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=50)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--size", default="32x24")
    ap.add_argument("--kinds", default=",".join(KINDS))
    ap.add_argument("--fd-k", type=int, default=96)
    ap.add_argument("--ks", default="4,8,16")
    ap.add_argument("--json", default=None, help="write every case's figures here")
    ap.add_argument("--cases", action="store_true", help="print each case")
    ap.add_argument("--print-scene", action="store_true")
    args = ap.parse_args()
    from raymitsuba.backend import mitsuba

    mi = mitsuba()
    size = tuple(int(v) for v in args.size.split("x"))
    ks = [int(k) for k in args.ks.split(",")]
    kinds = [k for k in args.kinds.split(",") if k]
    cases = []
    started = time.perf_counter()
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        s = generate(seed, size)
        if args.print_scene:
            print(f"# seed {seed}\n{s.text}")
        first = True
        for kind in kinds:
            if kind not in s.keys:
                continue
            try:
                case = compare(mi, s, kind, size, args.fd_k, ks, reverse_check=first)
            except Exception as e:  # a refused key: reported, not counted
                case = dict(seed=seed, kind=kind, key=s.keys[kind][0],
                            flag=f"{type(e).__name__}: {e}")
            first = False
            cases.append(case)
            if args.cases:
                line = f"seed {seed} {kind} {case['key']}"
                if "errors" in case:
                    line += " " + " ".join(
                        f"k{k}: {e['rel']:.2%}/{e['rel_size']:.2%}/{e['l2']:.1%}"
                        for k, e in case["errors"].items())
                    line += " ext " + " ".join(
                        f"k{k}: {e['rel']:.2%}/{e['rel_size']:.2%}"
                        for k, e in case["errors_extrapolated"].items())
                    line += (f" fd_unc {case['fd_uncertainty']:.2%}/"
                             f"{case['fd_uncertainty_size']:.2%}/"
                             f"{case['fd_pixel_uncertainty']:.1%} kink {case['fd_kink']:.2%}")
                if "reverse_vs_forward" in case:
                    line += f" rev-fwd {case['reverse_vs_forward']:.1e}"
                if "flag" in case:
                    line += f" [{case['flag']}]"
                print(line, flush=True)
    print(f"\n{args.seeds} seeds from {args.first_seed}, {args.size}, FD k = {args.fd_k}, "
          f"step h/2 (validated at h, and at k = {args.fd_k // 2} at h; flagged above "
          f"{FD_UNSTABLE:.0%}), "
          f"{time.perf_counter() - started:.0f} s\n")
    table(cases, ks, kinds)
    bad = [c for c in cases if c.get("reverse_vs_forward", 0) > 1e-4]
    for c in bad:
        print(f"reverse vs forward: seed {c['seed']} {c['key']} {c['reverse_vs_forward']:.1e}")
    flagged = [c for c in cases if "flag" in c]
    for c in flagged:
        print(f"flagged: seed {c['seed']} {c['key']}: {c['flag']}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(cases, f, indent=1, default=float)


if __name__ == "__main__":
    main()
