"""Batch rendering on Dask (raymitsuba.batch): prints medians and ratios, all from one run.

    ./dev bench --only batch            # or: ./dev python benchmarks/batch_bench.py
    ./dev bench --only batch --quick    # fewer repeats, a smaller poster

1. **Many scenes**: 24 small scenes at 512 x 384 -- the gallery's (``scenes/``) and
   generated sweeps of a sphere grid (each its own number of spheres and reflectivity)
   -- rendered three ways, each the whole wall time of the commands (cluster start
   included): a shell loop of 24 ``raymitsuba render`` processes; one ``raymitsuba render
   SCENE... -j 1`` (in process, no cluster); one ``raymitsuba render SCENE... -j 2`` (a
   local cluster of 2 workers, one Dr.Jit thread each). Targets: -j 2 <= 0.6 x the loop
   and <= 0.9 x -j 1. Then -j 1 and -j 2 on 96 scenes (the sweeps repeated), to show how
   the cluster's fixed start is amortized as the batch grows.
2. **Cluster start + stop**: ``raymitsuba.batch.cluster.connect(jobs=2)`` entered and left
   (the workers spawned, their versions checked, their kernels warmed). Target: <= 5 s.
3. **One big image**: ``benchmark_reflective.ray`` at 4096 x 4096 (``--quick``: 2048 x
   2048) to PNG on one 2-worker cluster: one task (one worker renders it all) against 8
   tiles (bands of rows over both workers). Target: tiled <= 1.1 x untiled.
4. **Comparisons** (``raymitsuba compare 'subs/{stem}.png' SCENE... --report R --csv C``,
   each comparison 4 renders of its scene): 24 and 96 scenes at 320 x 240 against
   submissions rendered beforehand, ``-j 1`` (in process: the serial loop it replaces)
   against ``-j 2``, the whole command; the two reports must be the same file.
   ``--compare``: this part only.

Throughput per worker count is scenes per second of -j 1 and -j 2. Timings on a shared
machine are noisy: medians, and ratios of figures taken in the same run, are what to
compare.
"""

from __future__ import annotations

import argparse
import glob
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

SCENES = 24
SIZE = ("--width", "512", "--height", "384")
POSTER = "benchmark_reflective.ray"


def sweep_scene(k: int) -> str:
    """A generated scene: a grid of 4 + k spheres over a checkerboard, reflectivity (k mod 10) / 10."""
    lines = ["eye 0 2 7", "lookat 0 0.5 0", "fov 40", "background 0.3 0.5 0.8",
             "light 0.2 0.2 0.2 ambient", "light 0.8 0.8 0.8 point 3 6 5",
             "material 0.9 0.9 0.9 0.2 0.8 0 1 0 0 1", "checkerboard 1", "plane",
             "checkerboard -1", f"material 0.8 0.3 0.2 0.1 0.6 0.5 40 {k % 10 / 10:.2f} 0 1"]
    for i in range(4 + k):
        x, z = (i % 4) * 1.2 - 1.8, -(i // 4) * 1.2
        lines += ["scale 0.5 0.5 0.5", f"translate {x:.2f} 0.5 {z:.2f}", "sphere", "pop", "pop"]
    return "\n".join(lines) + "\n"


def scenes(work: str, count: int = SCENES) -> list:
    """The gallery's scenes, then generated sweeps, ``count`` in all."""
    found = sorted(glob.glob(os.path.join(ROOT, "scenes", "*.ray")))[:count]
    k = 0
    while len(found) < count:
        path = os.path.join(work, f"sweep{k:02d}.ray")
        with open(path, "w") as f:
            f.write(sweep_scene(k))
        found.append(path)
        k += 1
    return found


def raymitsuba() -> str:
    return os.path.join(os.path.dirname(sys.executable), "raymitsuba")


def timed(command: list, **kw) -> float:
    start = time.perf_counter()
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                   **kw)
    return time.perf_counter() - start


def many_scenes(work: str, repeats: int) -> dict:
    paths = scenes(work)
    out = os.path.join(work, "out")
    loop = ("for f in " + " ".join(paths) + "; do " + raymitsuba() + " render \"$f\" -o "
            + out + "/loop-$(basename \"$f\" .ray).png " + " ".join(SIZE) + " || exit 1; done")
    times = {"loop": [], "j1": [], "j2": []}
    os.makedirs(out, exist_ok=True)
    for _ in range(repeats):  # interleaved: the machine's load falls on each alike
        times["loop"].append(timed(["bash", "-c", loop]))
        for jobs in ("1", "2"):
            times["j" + jobs].append(timed([raymitsuba(), "render", *paths, "-o",
                                            os.path.join(out, "j" + jobs + "-{stem}.png"),
                                            *SIZE, "-j", jobs]))
    return {name: statistics.median(t) for name, t in times.items()}


def growth(work: str, repeats: int, count: int) -> dict:
    """-j 1 and -j 2 on ``count`` scenes (how the cluster's fixed start is amortized)."""
    paths = scenes(work, count)
    out = os.path.join(work, f"out{count}")
    times = {"j1": [], "j2": []}
    for _ in range(repeats):
        for jobs in ("1", "2"):
            times["j" + jobs].append(timed([raymitsuba(), "render", *paths, "-o",
                                            os.path.join(out, "j" + jobs + "-{stem}.png"),
                                            *SIZE, "-j", jobs]))
    return {name: statistics.median(t) for name, t in times.items()}


def cluster_start_stop(repeats: int) -> float:
    from raymitsuba.batch import cluster

    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        with cluster.connect(jobs=2, threads=1) as client:
            client.wait_for_workers(2)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def poster(work: str, repeats: int, size: int) -> dict:
    from raymitsuba.batch import cluster, render_many

    scene = os.path.join(ROOT, "scenes", POSTER)
    times = {"untiled": [], "tiled": []}
    with cluster.connect(jobs=2, threads=1) as client:
        client.wait_for_workers(2)
        for _ in range(repeats):
            for name, tiles in (("untiled", None), ("tiled", 8)):
                out = os.path.join(work, f"poster-{name}.png")
                start = time.perf_counter()
                [item] = render_many([scene], [out], client=client, tiles=tiles,
                                     manifest=None, width=size, height=size)
                assert item.ok, item.error
                times[name].append(time.perf_counter() - start)
    with open(os.path.join(work, "poster-untiled.png"), "rb") as a, \
            open(os.path.join(work, "poster-tiled.png"), "rb") as b:
        assert a.read() == b.read(), "the tiled poster differs from the untiled one"
    return {name: statistics.median(t) for name, t in times.items()}


COMPARE_SIZE = ("--width", "320", "--height", "240")


def compare_batches(work: str, repeats: int, count: int) -> dict:
    """``raymitsuba compare`` of ``count`` scenes, -j 1 and -j 2 (see the docstring)."""
    paths = scenes(work, count)
    subs = os.path.join(work, f"subs{count}")
    subprocess.run([raymitsuba(), "render", *paths, "-o", os.path.join(subs, "{stem}.png"),
                    *COMPARE_SIZE, "-j", "1"], check=True, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    times = {"j1": [], "j2": []}
    for _ in range(repeats):
        for jobs in ("1", "2"):
            report = os.path.join(work, f"compare{count}-j{jobs}.html")
            times["j" + jobs].append(timed([raymitsuba(), "compare",
                                            os.path.join(subs, "{stem}.png"), *paths,
                                            "--report", report, "-j", jobs]))
    with open(os.path.join(work, f"compare{count}-j1.html"), "rb") as a, \
            open(os.path.join(work, f"compare{count}-j2.html"), "rb") as b:
        assert a.read() == b.read(), "the report of -j 2 differs from that of -j 1"
    return {name: statistics.median(t) for name, t in times.items()}


def print_compare(work: str, repeats: int) -> None:
    for count in (SCENES, 4 * SCENES):
        c = compare_batches(work, repeats, count)
        print(f"  compare {count} scenes at 320x240 (4 renders each): -j 1 {c['j1']:.2f} s "
              f"({count / c['j1']:.2f} scenes/s), -j 2 {c['j2']:.2f} s "
              f"({count / c['j2']:.2f} scenes/s), -j 2 / -j 1 {c['j2'] / c['j1']:.2f}; "
              "the same report")


def run(quick: bool = False, only_compare: bool = False) -> None:
    repeats = 3 if quick else 5
    work = tempfile.mkdtemp(prefix="raymitsuba-batch-bench-")
    try:
        print(f"batch benchmark: medians of {repeats} runs, {os.cpu_count()} cores")
        if only_compare:
            return print_compare(work, repeats)
        t = many_scenes(work, repeats)
        print(f"  {SCENES} scenes at 512x384, whole commands:")
        print(f"    shell loop of {SCENES} processes  {t['loop']:7.2f} s  "
              f"{SCENES / t['loop']:5.2f} scenes/s")
        print(f"    -j 1 (in process)           {t['j1']:7.2f} s  {SCENES / t['j1']:5.2f} scenes/s")
        print(f"    -j 2 (2 workers)            {t['j2']:7.2f} s  {SCENES / t['j2']:5.2f} scenes/s")
        print(f"    -j 2 / loop {t['j2'] / t['loop']:.2f} (target <= 0.6), "
              f"-j 2 / -j 1 {t['j2'] / t['j1']:.2f} (target <= 0.9), "
              f"-j 1 / loop {t['j1'] / t['loop']:.2f}")
        big = growth(work, repeats, 4 * SCENES)
        print(f"  {4 * SCENES} scenes: -j 1 {big['j1']:.2f} s ({4 * SCENES / big['j1']:.2f} "
              f"scenes/s), -j 2 {big['j2']:.2f} s ({4 * SCENES / big['j2']:.2f} scenes/s), "
              f"-j 2 / -j 1 {big['j2'] / big['j1']:.2f}")
        start_stop = cluster_start_stop(repeats)
        print(f"  cluster start + stop (2 workers, warmed): {start_stop:.2f} s (target <= 5 s)")
        size = 2048 if quick else 4096
        p = poster(work, repeats, size)
        print(f"  {POSTER} {size}x{size} PNG on 2 workers: untiled {p['untiled']:.2f} s, "
              f"8 tiles {p['tiled']:.2f} s, tiled / untiled {p['tiled'] / p['untiled']:.2f} "
              "(target <= 1.1); the same file")
        print_compare(work, repeats)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats, a smaller poster")
    ap.add_argument("--compare", action="store_true", help="only the comparisons (part 4)")
    args = ap.parse_args()
    run(args.quick, args.compare)


if __name__ == "__main__":
    main()
