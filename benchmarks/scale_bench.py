"""raymitsuba's scale benchmark: how each stage's cost grows with the size of the scene.

    ./dev bench --scale                      # the full ladder
    ./dev bench --scale --quick              # the small half of the ladder, one run each
    ./dev bench --scale --family spheres --max-size 1000

Three families of generated scenes (the generators are below), each on a ladder of sizes:

* ``spheres``: N spheres (similarity transforms), each with its own ``material``;
  N = 10, 10^2, 10^3, 10^4, 10^5;
* ``quadrics``: N spheres, cylinders and cones under non-uniform scales and rotations,
  in seven materials, one of them glass (so one object in seven is glass);
  N = 10, 10^2, 10^3, 10^4;
* ``triangles``: one height-field mesh of N ``triangle`` lines, one material;
  N = 10^3, 10^4, 10^5, 10^6.

For each scene, at 512x384 and 1 sample per pixel, it prints (seconds; medians of
``--repeat`` runs, each in a fresh process):

* parse, translate (model to scene dict), load (``mi.load_dict``), cold first render
  (Dr.Jit's kernel cache empty: HOME pointed at a new directory), warm render (the
  median of renders after the first, in the same process);
* process: the wall time of the whole ``raymitsuba render`` command writing a PNG (as a
  user would; ``--output exr`` for the EXR), after one warm-up run (so with the kernel cache filled, as for a user's second render; the
  cold figure above includes compiling the kernels), and its peak resident memory (MB);
* POV-Ray's wall time on the same scene (benchmarks/povray.py's export, 2 threads),
  when ``povray`` is installed, and the ratio process / POV-Ray;

then the growth exponent of each figure over the ladder: the slope of the log-log least
squares fit of figure against N (1: linear; 0: constant).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

WIDTH, HEIGHT = 512, 384
LADDERS = {"spheres": (10, 100, 1000, 10000, 100000),
           "quadrics": (10, 100, 1000, 10000),
           "triangles": (1000, 10000, 100000, 1000000)}
QUICK_LADDERS = {"spheres": (10, 100, 1000), "quadrics": (10, 100, 1000),
                 "triangles": (1000, 10000, 100000)}


# -- scene generators --------------------------------------------------------------------------
def header(extent):
    """Camera framing a square of half-size ``extent`` about the origin in the z = 0 plane,
    an ambient light and two point lights."""
    distance = extent / math.tan(math.radians(40.0) / 2.0) * 1.05
    return (f"eye 0 {-0.35 * distance:.6g} {distance:.6g}\nlookat 0 0 0\nup 0 1 0\nfov 40\n"
            "background 0.3 0.4 0.55\n"
            "light 0.15 0.15 0.15 ambient\n"
            f"light 0.7 0.68 0.62 point {extent:.6g} {extent:.6g} {distance:.6g}\n"
            f"light 0.35 0.38 0.45 point {-extent:.6g} {0.5 * extent:.6g} {distance:.6g}\n")


def grid(n):
    """(columns, the centre (x, y) of cell k) of a square grid of n cells of unit pitch."""
    cols = math.ceil(math.sqrt(n))
    half = (cols - 1) / 2.0
    return cols, lambda k: (k % cols - half, k // cols - half)


def spheres(n):
    """n spheres of radius 0.4 on a unit grid, each with its own material (one in four a
    mirror)."""
    cols, at = grid(n)
    lines = [header(cols / 2.0)]
    for k in range(n):
        x, y = at(k)
        r, g, b = 0.3 + 0.7 * (k % 7) / 6, 0.3 + 0.7 * (k % 5) / 4, 0.3 + 0.7 * (k % 3) / 2
        kr = 0.3 if k % 4 == 0 else 0.0
        lines.append(f"material {r:.3g} {g:.3g} {b:.3g}  0.2 0.7 0.3 30  {kr} 0 1\n"
                     f"scale 0.4 0.4 0.4\ntranslate {x:g} {y:g} 0\nsphere\npop\npop\n")
    return "".join(lines)


QUADRIC_MATERIALS = ("0.9 0.3 0.2  0.2 0.7 0.3 30  0 0 1", "0.2 0.8 0.3  0.2 0.7 0.3 30  0 0 1",
                     "0.3 0.4 0.9  0.2 0.7 0.3 30  0 0 1", "0.9 0.8 0.2  0.2 0.7 0.3 30  0 0 1",
                     "0.8 0.8 0.8  0.1 0.3 0.6 60  0.5 0 1", "0.6 0.3 0.8  0.2 0.7 0.3 30  0 0 1",
                     "1 1 1  0 0.05 0.6 120  0.1 0.85 1.5")  # the seventh: glass
QUADRIC_KINDS = ("sphere", "cylinder", "cone")


def quadrics(n):
    """n spheres, cylinders and cones on a unit grid, each non-uniformly scaled and rotated;
    object k has material k mod 7 (the seventh is glass), written grouped by material."""
    cols, at = grid(n)
    lines = [header(cols / 2.0)]
    for m, material in enumerate(QUADRIC_MATERIALS):
        lines.append(f"material {material}\n")
        for k in range(m, n, len(QUADRIC_MATERIALS)):
            x, y = at(k)
            sx, sy, sz = 0.3 + 0.1 * (k % 3), 0.25 + 0.15 * (k % 4) / 3, 0.35
            # (the first transform line is applied first: scale, rotate, then move into place)
            lines.append(f"scale {sx:.3g} {sy:.3g} {sz:.3g}\nrotateY {29 * k % 360}\n"
                         f"rotateX {17 * k % 90 - 45}\ntranslate {x:g} {y:g} 0\n"
                         f"{QUADRIC_KINDS[k % 3]}\npop\npop\npop\npop\n")
    return "".join(lines)


def triangles(n):
    """One height field of n triangles (two per grid cell) over a square, one material."""
    import numpy as np

    cells = max(round(math.sqrt(n / 2.0)), 1)
    u = np.linspace(-4.0, 4.0, cells + 1)
    x, y = np.meshgrid(u, u)
    z = 0.4 * np.sin(1.7 * x) * np.cos(1.3 * y)
    p = np.stack([x, y, z], -1)
    a, b, c, d = p[:-1, :-1], p[:-1, 1:], p[1:, 1:], p[1:, :-1]
    tris = np.concatenate([np.stack([a, b, c], -2).reshape(-1, 9),
                           np.stack([a, c, d], -2).reshape(-1, 9)])[:n]
    body = "\n".join("triangle " + " ".join(f"{v:.6g}" for v in row) for row in tris.tolist())
    return (header(4.0) + "material 0.8 0.75 0.6  0.2 0.7 0.4 40  0.1 0 1\nrotateX -20\n"
            + body + "\n")


FAMILIES = {"spheres": spheres, "quadrics": quadrics, "triangles": triangles}


# -- measurements in a child process -----------------------------------------------------------
def stages(path, warm_repeats):
    """Seconds of each stage of loading and rendering ``path`` in this (fresh) process, and
    its peak resident memory."""
    import resource

    from raymitsuba.backend import mitsuba

    mi = mitsuba(mitsuba_integrators=False)
    from raymitsuba.format.parser import parse_file
    from raymitsuba.translate import Options, translate

    from raymitsuba.util import no_cyclic_gc

    out = {}
    t = time.perf_counter()
    model = parse_file(path)
    out["parse"], t = time.perf_counter() - t, time.perf_counter()
    with no_cyclic_gc():  # as api.load: translate and load_dict with the collector paused
        scene_dict = translate(model, Options(width=WIDTH, height=HEIGHT, spp=1))
        out["translate"], t = time.perf_counter() - t, time.perf_counter()
        # as api.load (parallel: 1.7x slower; unoptimized: the dict's shapes in its order)
        scene = mi.load_dict(scene_dict, parallel=False, optimize=False)
    out["load"], t = time.perf_counter() - t, time.perf_counter()
    mi.render(scene, spp=1).numpy()
    out["cold"] = time.perf_counter() - t
    warm = []
    for _ in range(warm_repeats):
        t = time.perf_counter()
        mi.render(scene, spp=1).numpy()
        warm.append(time.perf_counter() - t)
    out["warm"] = statistics.median(warm)
    out["stages_mb"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return out


# -- measurements of whole processes -----------------------------------------------------------
class TimedOut(Exception):
    pass


def measure(cmd, cwd=None):
    """Run ``cmd`` (from a fresh process whose only child it is) and return its wall seconds and
    peak resident memory (MB)."""
    import resource

    t = time.perf_counter()
    done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=cwd)
    wall = time.perf_counter() - t
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr[-2000:]}")
    return {"wall": wall, "peak_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024}


def child(job, timeout, env=None):
    """Run one measurement (``job``: {"what": "stages" | "measure", ...}) in a fresh process."""
    try:
        done = subprocess.run([sys.executable, __file__, "--child", json.dumps(job)],
                              capture_output=True, text=True, env=env, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise TimedOut() from None
    if done.returncode != 0:
        raise RuntimeError(done.stderr[-3000:])
    return json.loads(done.stdout.strip().splitlines()[-1])


def povray_command(path, workdir):
    """The POV-Ray command line for an export of ``path`` (None: povray not installed)."""
    if not shutil.which("povray"):
        return None
    from povray import export
    from raymitsuba.format.parser import parse_file

    pov = os.path.join(workdir, os.path.basename(path)[:-4] + ".pov")
    with open(pov, "w") as f:
        f.write(export(parse_file(path), WIDTH, HEIGHT))
    return ["povray", f"+I{pov}", f"+O{pov[:-4]}.png", f"+W{WIDTH}", f"+H{HEIGHT}", "-D", "-V",
            "+WT2", "-A"]


def measure_size(family, n, args, workdir):
    """Every figure of one scene: medians over ``args.repeat`` runs (None: timed out)."""
    path = os.path.join(workdir, f"{family}_{n}.ray")
    with open(path, "w") as f:
        f.write(FAMILIES[family](n))
    runs = []
    for _ in range(args.repeat):
        cold_home = tempfile.mkdtemp(prefix="home-", dir=workdir)  # an empty kernel cache
        runs.append(child({"what": "stages", "path": path, "warm_repeats": 3}, args.timeout,
                          env=dict(os.environ, HOME=cold_home)))
        shutil.rmtree(cold_home, ignore_errors=True)
    row = {key: statistics.median(r[key] for r in runs) for key in runs[0]}
    render = [sys.executable, "-m", "raymitsuba", "render", path, "-o", f"{path[:-4]}.{args.output}",
              "--width", str(WIDTH), "--height", str(HEIGHT)]
    child({"what": "measure", "cmd": render}, args.timeout)  # warm-up: fills the kernel cache
    process = [child({"what": "measure", "cmd": render}, args.timeout) for _ in range(args.repeat)]
    row["process"] = statistics.median(p["wall"] for p in process)
    row["peak_mb"] = max(p["peak_mb"] for p in process)
    pov = povray_command(path, workdir)
    if pov is not None:
        row["povray"] = statistics.median(child({"what": "measure", "cmd": pov, "cwd": workdir},
                                                args.timeout)["wall"] for _ in range(args.repeat))
    return row


# -- the report --------------------------------------------------------------------------------
COLUMNS = (("parse", "parse"), ("translate", "transl"), ("load", "load"), ("cold", "cold 1st"),
           ("warm", "warm"), ("process", "process"), ("peak_mb", "peak MB"), ("povray", "POV-Ray"))


def growth_exponent(sizes, values):
    """The slope of the least-squares line through (log N, log figure): cost ~ N^slope."""
    import numpy as np

    points = [(math.log(n), math.log(v)) for n, v in zip(sizes, values) if v and v > 0]
    if len(points) < 2:
        return None
    x, y = np.array(points).T
    return float(np.polyfit(x, y, 1)[0])


def table(family, rows):
    """Markdown rows of one family: a row per size, then the growth exponents."""
    unit = "triangles" if family == "triangles" else "objects"
    head = f"| {family} ({unit}) | " + " | ".join(label for _, label in COLUMNS) + " | process / POV |"
    lines = [head, "|" + "---:|" * (len(COLUMNS) + 2)]
    for n, row in rows.items():
        if row is None:
            lines.append(f"| {n:,} | " + " | ".join("timeout" if i == 0 else "" for i in range(len(COLUMNS)))
                         + " | |")
            continue
        cells = [fmt(row.get(key), key) for key, _ in COLUMNS]
        ratio = row["process"] / row["povray"] if row.get("povray") else None
        lines.append(f"| {n:,} | " + " | ".join(cells) + f" | {fmt(ratio, 'ratio')} |")
    done = {n: r for n, r in rows.items() if r is not None}
    slopes = [growth_exponent(list(done), [r.get(key) for r in done.values()]) for key, _ in COLUMNS]
    ratio = growth_exponent(list(done), [r["process"] / r["povray"] if r.get("povray") else None
                                         for r in done.values()])
    lines.append("| growth exponent | " + " | ".join(fmt(s, "slope") for s in slopes)
                 + f" | {fmt(ratio, 'slope')} |")
    return "\n".join(lines)


def fmt(value, key):
    if value is None:
        return "n/a"
    if key == "peak_mb":
        return f"{value:.0f}"
    if key in ("slope", "ratio"):
        return f"{value:.2f}"
    return f"{value:.3f}" if value < 10 else f"{value:.1f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true",
                    help="the small half of each ladder, one run each")
    ap.add_argument("--family", choices=list(FAMILIES), action="append",
                    help="only these families (repeatable; default: all three)")
    ap.add_argument("--max-size", type=int, help="skip sizes above this N")
    ap.add_argument("--min-size", type=int, help="skip sizes below this N")
    ap.add_argument("--output", choices=("png", "exr"), default="png",
                    help="the image format the timed `raymitsuba render` writes (default png)")
    ap.add_argument("--repeat", type=int, help="runs per figure, the median is shown (default 3; quick: 1)")
    ap.add_argument("--timeout", type=float, default=600.0,
                    help="seconds one run may take; past it the size and the larger ones are skipped")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        job = json.loads(args.child)
        what = job.pop("what")
        print(json.dumps(stages(**job) if what == "stages" else measure(**job)))
        return
    args.repeat = args.repeat or (1 if args.quick else 3)
    ladders = QUICK_LADDERS if args.quick else LADDERS
    from povray import ensure_povray

    ensure_povray()
    workdir = tempfile.mkdtemp(prefix="raymitsuba-scale-")
    print(f"raymitsuba scale benchmark: {WIDTH}x{HEIGHT}, 1 spp; seconds (peak: MB of the whole "
          f"`raymitsuba render`), medians of {args.repeat} run(s)"
          + ("" if shutil.which("povray") else "; POV-Ray not installed"), flush=True)
    try:
        for family in args.family or list(FAMILIES):
            rows = {}
            for n in ladders[family]:
                if (args.max_size and n > args.max_size) or (args.min_size and n < args.min_size):
                    continue
                print(f"  {family} {n:,} ...", flush=True)
                try:
                    rows[n] = measure_size(family, n, args, workdir)
                except TimedOut:
                    print(f"  {family} {n:,}: a run took more than {args.timeout:.0f} s; "
                          f"larger sizes skipped", flush=True)
                    rows[n] = None
                    break
            print("\n" + table(family, rows) + "\n", flush=True)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


if __name__ == "__main__":
    main()
