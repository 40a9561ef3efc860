"""raymitsuba's rendering benchmark: prints medians and ratios, all measured in this run.

    ./dev bench                 # full: 1024x768, 1 and 4 spp, both scenes
    ./dev bench --quick         # fewer repeats, for a smoke run

For each benchmark scene (scenes/benchmark_reflective.ray: mirrors only;
scenes/benchmark_glass.ray: the same geometry with glass, the full
reflection + refraction tree) and each sample count it measures:

* cold first render: a fresh process whose Dr.Jit kernel cache is empty
  (HOME pointed at a new directory), so kernel compilation is included;
* first render: a fresh process with the kernel cache as it is;
* warm render: median of repeated renders in one process;
* native direct: Mitsuba's own ``direct`` integrator on the same geometry (diffuse
  materials, the same point lights, one emitter sample per point light, no BSDF
  sample), warm; the ratio is per camera ray (both trace width x height x spp
  camera rays; raywhitted also traces the reflected and refracted rays, whose
  number per camera ray is printed as rays/cam);
* process: wall time of the whole ``raymitsuba render`` command;
* POV-Ray: wall time of ``povray`` on an export of the same scene (installed with apt-get
  where missing and possible, ``povray.ensure_povray``; else its rows are skipped);

and for gradients: one step (primal + reverse-mode backpropagation of an L2
loss, to all material parameters and to the Phong terms only) at 256x256 / 8 spp
and 1024x768 / 1 spp, as a ratio to the primal render at the same settings, and
the peak memory of each (separate processes).

Memory (``raymitsuba render`` processes, peak resident memory as the kernel accounts it):
4096 x 4096 at 16 spp on the reflective scene, depth 64 on the glass scene at 1024 x 768
(with ``--bailout 1e-4``: the exact tree at depth 64 grows ~1.2x a generation, which the
render refuses up front), and with ``--huge`` 16384 x 16384 at 1 spp (minutes).

Anti-aliasing, on the reflective scene, on scenes/aa_showcase.ray (a low camera over a
rotated, slightly reflective checkerboard to the horizon, mirror spheres and a glass
sphere, four lights) and on a generated scene of sub-pixel detail (``fine_detail_scene``:
a Siemens star and thin wires) at 512 x 384 against a 256-spp (16 x 16 grid: issue 31's
reference) and a 987-spp render on a golden-ratio lattice (``TRUTH_SPP`` says why): the
share of pixels whose largest channel difference (values clamped to [0, 1]) is within
2/255 and 8/255, and the whole-process time (wall and CPU) relative to a 1-spp render, for
uniform 1, 4 and 16 spp and ``--aa`` (the variants run round-robin; for ``--aa`` also the
median of each round's ratio to that round's 1 spp, and one fresh process each with an
empty kernel cache); POV-Ray's ``+A0.3`` (adaptive, its default depth 3) and its uniform
4 spp likewise against its own 16 x 16 supersampled render. Then ``--aa`` on gallery
scenes no benchmark was tuned on (``AA_GALLERY``): its time against 1 spp and its shares
against the 987-spp render.

    ./dev bench --only memory,aa     # only these sections (also: table, grad, deep)
    ./dev bench --only batch         # batch rendering on Dask (benchmarks/batch_bench.py)

Deep trees (``--only deep``, minutes): whitted.ray and benchmark_glass.ray at 1024 x 768,
depth 64 with the default (bounded) bailout, against POV-Ray at the same depth with its
default ``adc_bailout`` and against the exact tree at depth 28 (``--bailout 0``).

Timings on shared machines are noisy: medians of several runs, and ratios of
figures taken in the same run, are what to compare.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ("benchmark_reflective", "benchmark_glass")
sys.path.insert(0, ROOT)


def scene_path(name):
    return os.path.join(ROOT, "scenes", name + ".ray")


# -- measurements inside one process ----------------------------------------------------------
def first_render(path, width, height, spp):
    t0 = time.perf_counter()
    import raymitsuba

    loaded = raymitsuba.load(path, width=width, height=height, spp=spp)
    t1 = time.perf_counter()
    raymitsuba.render(loaded).numpy()
    t2 = time.perf_counter()
    return {"load": t1 - t0, "first": t2 - t1}


def warm_render_times(loaded, repeats):
    """Seconds of ``repeats`` renders of ``loaded`` after a first one (kernels compiled)."""
    import raymitsuba

    raymitsuba.render(loaded).numpy()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        raymitsuba.render(loaded).numpy()
        times.append(time.perf_counter() - t)
    return times


def warm_renders(path, width, height, spp, repeats):
    import raymitsuba

    loaded = raymitsuba.load(path, width=width, height=height, spp=spp)
    return {"times": warm_render_times(loaded, repeats), "rays": loaded.integrator.rays_traced}


def native_direct(path, width, height, spp, repeats):
    """Mitsuba's `direct` integrator on the same geometry and point lights."""
    import raymitsuba
    from raymitsuba.backend import mitsuba
    from raymitsuba.translate import Options, translate

    mi = mitsuba()
    source = translate(raymitsuba.parse(path), Options(width=width, height=height, spp=spp))
    native = {}
    for key, value in source.items():
        kind = value.get("type") if isinstance(value, dict) else None
        if kind in ("rayphong", "raytextured"):
            native[key] = {"type": "diffuse", "id": key}
        elif kind == "raylight":
            if value["kind"] == "point":
                native[key] = {"type": "point", "position": value["position"],
                               "intensity": {"type": "rgb", "value": value["color"]}}
        elif kind == "raybackground":
            native[key] = {"type": "constant"}
        elif key == "integrator":
            # One shadow ray per point light per camera ray, as raywhitted's first generation.
            lights = sum(1 for v in source.values() if isinstance(v, dict) and v.get("kind") == "point")
            native[key] = {"type": "direct", "emitter_samples": max(lights, 1), "bsdf_samples": 0}
        else:
            native[key] = value
    scene = mi.load_dict(native)
    mi.render(scene, spp=spp).numpy()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        mi.render(scene, spp=spp).numpy()
        times.append(time.perf_counter() - t)
    return times


PHONG_FIELDS = ("color", "diffuse_mix", "specular_mix", "phong_coeff")


def gradient_step(path, width, height, spp, repeats, mode, fields=None):
    """Times of ``mode`` ("primal" render, or "step": primal + reverse-mode gradient of an
    L2 loss to the material parameters named by ``fields``, all when None), and this
    process's peak resident memory (MB)."""
    import resource

    import drjit as dr
    import raymitsuba

    loaded = raymitsuba.load(path, width=width, height=height, spp=spp)
    params = loaded.params
    keys = [k for k in params.keys()
            if k.startswith("mat") and (fields is None or k.split(".", 1)[1] in fields)]
    target = raymitsuba.render(loaded)
    dr.eval(target)

    def primal():
        raymitsuba.render(loaded).numpy()

    def step():
        for key in keys:
            dr.enable_grad(params[key])
        params.update()
        image = raymitsuba.render(loaded)
        loss = dr.mean(dr.square(image - target), axis=None)
        dr.backward(loss)
        [dr.grad(params[key]).numpy() for key in keys]
        for key in keys:
            dr.disable_grad(params[key])
        params.update()

    fn = step if mode == "step" else primal
    fn()
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return {"times": times, "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}


# -- measurements of whole processes ----------------------------------------------------------
def child(args, env=None):
    """Run this script in a fresh process for one measurement; returns its JSON result."""
    out = subprocess.run([sys.executable, __file__, "--child", json.dumps(args)],
                         capture_output=True, text=True, env=env, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def wall(cmd, repeats, **kwargs):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        subprocess.run(cmd, check=True, capture_output=True, **kwargs)
        times.append(time.perf_counter() - t)
    return times


def povray_times(path, width, height, spp, repeats, workdir):
    if not shutil.which("povray"):
        return None
    import raymitsuba
    from povray import export

    pov = os.path.join(workdir, "scene.pov")
    with open(pov, "w") as f:
        f.write(export(raymitsuba.parse(path), width, height))
    # 4 spp: POV-Ray's non-adaptive supersampling with a 2x2 grid per pixel (+AM1 +R2, threshold 0).
    aa = ["+A0.0", "+AM1", "+R2"] if spp > 1 else ["-A"]
    cmd = ["povray", f"+I{pov}", f"+O{workdir}/pov.png", f"+W{width}", f"+H{height}", "-D", "-V",
           "+WT2", *aa]
    return wall(cmd, repeats, cwd=workdir)


def median(xs):
    return statistics.median(xs) if xs else float("nan")


def process(cmd, **kwargs):
    """Run ``cmd``; (wall seconds, cpu seconds, peak resident MB) of that process alone."""
    t = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, **kwargs)
    _, status, usage = os.wait4(p.pid, 0)
    wall_s = time.perf_counter() - t
    err = p.stderr.read().decode()
    p.stderr.close()
    p.returncode = os.waitstatus_to_exitcode(status)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))}: exit {p.returncode}: {err.strip()}")
    return wall_s, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def render_cmd(path, out, *args):
    return [sys.executable, "-m", "raymitsuba", "render", path, "-o", out, *map(str, args)]


def memory_section(work, huge):
    print("\npeak memory of whole `raymitsuba render` processes (default --memory-budget 2G):")
    jobs = [("benchmark_reflective", ("--width", 4096, "--height", 4096, "--spp", 16)),
            ("benchmark_glass", ("--width", 1024, "--height", 768, "--max-depth", 64,
                                 "--bailout", "1e-4"))]
    if huge:
        jobs.append(("benchmark_reflective", ("--width", 16384, "--height", 16384, "--spp", 1)))
    for name, args in jobs:
        out = os.path.join(work, "big.png")
        wall_s, cpu_s, peak = process(render_cmd(scene_path(name), out, *args))
        print(f"  {name:22} {' '.join(map(str, args)):45} {wall_s:7.1f} s  peak {peak:6.0f} MB")


def shares(image, reference):
    """Shares (%) of pixels within 2/255 and 8/255 of the reference (largest channel
    difference, values clamped to [0, 1])."""
    import numpy as np

    d = np.abs(np.clip(image, 0, 1) - np.clip(reference, 0, 1)).max(axis=-1)
    return 100 * float(np.mean(d <= 2 / 255 + 1e-6)), 100 * float(np.mean(d <= 8 / 255 + 1e-6))


# The truth the anti-aliasing shares are read against: the render at this many samples a
# pixel, which camera.py places on a golden-ratio lattice (x stratified in spp steps, y by
# the golden ratio; 987 is a Fibonacci number: a Fibonacci lattice). A regular n x n grid
# sees an edge along a row or column of pixels at only n + 1 coverages: the 1024-spp grid
# (32 x 32) is off by up to 1/64 of the contrast there (2.2/255 on whitted.ray's floor
# lines), and was within 2/255 of a 4096-spp grid on only 99.13-99.77 % of the pixels of
# whitted, mirror_hall, the reflective scene and the showcase; this lattice, as costly, on
# 99.99-100 % (mirror_hall 99.71 %: its horizon, where the 4096-spp grid aliases too;
# 2026-12-07, 512 x 384, one render each)
TRUTH_SPP = 987
AA_THRESHOLDS = ("", 0.05, 0.01)  # "": --aa alone, the default threshold
# Scenes of the gallery that no anti-aliasing benchmark was tuned on (aa_gallery_section)
AA_GALLERY = ("whitted", "mirror_hall", "cornell_box", "benchmark_glass")


def fine_detail_scene(width=512, height=384, spokes=48, wires=12):
    """.RAY text of a scene of detail finer than a pixel at ``width`` x ``height``, seen from
    the default camera (z = 5, vertical field of view 45 degrees): a Siemens star of
    ``spokes`` spokes, whose tips converge below a pixel, and ``wires`` slanted wires from
    0.2 to 1.5 pixels wide; ambient light only, so each surface is one flat colour over a
    black background."""
    import math

    pixel = 2 * 5 * math.tan(math.radians(22.5)) / height  # world units at z = 0
    lines = ["light 1 1 1 ambient", "background 0 0 0", "material 1 0.9 0.6  1 0 0 1  0 0 1"]
    cx, cy, r = -1.0, 0.0, 1.5
    for k in range(spokes):
        a0, a1 = 2 * math.pi * k / spokes, 2 * math.pi * (k + 0.5) / spokes
        lines.append(f"triangle {cx} {cy} 0  {cx + r * math.cos(a0)} {cy + r * math.sin(a0)} 0"
                     f"  {cx + r * math.cos(a1)} {cy + r * math.sin(a1)} 0")
    lines.append("material 0.5 0.8 1  1 0 0 1  0 0 1")
    for k in range(wires):
        w = (0.2 + 1.3 * k / (wires - 1)) * pixel / 2  # half the width
        x0, x1 = 0.9 + 0.18 * k, 1.5 + 0.18 * k  # bottom and top of the wire's axis
        lines += [f"triangle {x0 - w} -1.9 0  {x0 + w} -1.9 0  {x1 + w} 1.9 0",
                  f"triangle {x0 - w} -1.9 0  {x1 + w} 1.9 0  {x1 - w} 1.9 0"]
    return "\n".join(lines) + "\n"


def references(work, path, width, height, counts=(256, TRUTH_SPP)):
    """{spp: image} of the scene at ``path`` for each spp of ``counts``: its 256-spp render
    (a 16 x 16 grid a pixel, issue 31's reference) and its TRUTH_SPP one, the truth the
    shares are read against (see TRUTH_SPP). Towards a checkerboard's horizon a regular grid
    aliases, while the filtered board of ``--aa`` converges to the pixel's average: on the
    benchmark's reflective scene the 256-spp render is itself within 2/255 of the 987-spp
    one on only 99.06 % of the pixels (of the 1024-spp grid on 98.5 %)."""
    import numpy as np

    out = {}
    for spp in counts:
        ref = os.path.join(work, f"ref{spp}.npy")
        process(render_cmd(path, ref, "--width", width, "--height", height, "--spp", spp,
                           "--time-limit", 0))
        out[spp] = np.load(ref)
    return out


def aa_section(work, repeats, width=512, height=384, name=SCENES[0], path=None,
               povray_too=True):
    import numpy as np

    from raymitsuba import images

    path = path or scene_path(name)
    print(f"\nanti-aliasing on {name} at {width}x{height}, against a 256-spp and a {TRUTH_SPP}-spp "
          f"render (pixels within 2/255 and 8/255 of each; whole `raymitsuba render` "
          f"processes, median of {repeats}, the variants run round-robin, relative to 1 spp):")
    refs = references(work, path, width, height)
    r2, r8 = shares(refs[256], refs[TRUTH_SPP])
    print(f"  the 256-spp render against the {TRUTH_SPP}-spp: {r2:6.2f} % {r8:6.2f} %")
    rows = []
    variants = [("1 spp", ("--spp", 1)), ("4 spp", ("--spp", 4)), ("16 spp", ("--spp", 16))]
    variants += [(f"--aa {t}".strip(), ("--aa", t) if t else ("--aa",)) for t in AA_THRESHOLDS]
    outs = [os.path.join(work, f"aa{i}.npy") for i in range(len(variants))]
    cmds = [render_cmd(path, out, "--width", width, "--height", height, *args)
            for out, (_, args) in zip(outs, variants)]
    for cmd in cmds:
        process(cmd)  # warm the kernel cache
    runs = [[] for _ in cmds]
    for _ in range(repeats):  # round-robin: the machine's load changes alike for every variant
        for cmd, times in zip(cmds, runs):
            times.append(process(cmd))
    for (label, _), out, times in zip(variants, outs, runs):
        image = np.load(out)
        rows.append((label, median([r[0] for r in times]), median([r[1] for r in times]),
                     *shares(image, refs[256]), *shares(image, refs[TRUTH_SPP])))
    base_wall, base_cpu = rows[0][1], rows[0][2]
    print(f"                        vs 256 spp         vs {TRUTH_SPP} spp")
    for label, wall_s, cpu_s, *within in rows:
        print(f"  raymitsuba {label:12} {within[0]:6.2f} % {within[1]:6.2f} %   {within[2]:6.2f} % "
              f"{within[3]:6.2f} %   time x{wall_s / base_wall:5.2f} (cpu x{cpu_s / base_cpu:5.2f};"
              f" {wall_s:.2f} s)")
    aa = [label for label, _ in variants].index("--aa")
    # each round's --aa against the same round's 1 spp, a few seconds apart: the load of a
    # shared machine moves both alike
    paired = [(a[0] / b[0], a[1] / b[1]) for a, b in zip(runs[aa], runs[0])]
    print(f"  --aa / 1 spp, whole process: wall x{median([p[0] for p in paired]):.2f}, cpu "
          f"x{median([p[1] for p in paired]):.2f} (median of the rounds' ratios; within "
          f"2/255 and 8/255: {rows[aa][3]:.2f} %, {rows[aa][4]:.2f} % of the 256-spp render, "
          f"{rows[aa][5]:.2f} %, {rows[aa][6]:.2f} % of the {TRUTH_SPP}-spp)")
    cold = []
    for label, cmd in (("1 spp", cmds[0]), ("--aa", cmds[aa])):
        home = tempfile.mkdtemp(prefix="home-", dir=work)  # an empty Dr.Jit kernel cache
        cold.append(process(cmd, env=dict(os.environ, HOME=home)))
        shutil.rmtree(home, ignore_errors=True)
    print(f"  cold kernel cache (one fresh process each): 1 spp {cold[0][0]:.2f} s, --aa "
          f"{cold[1][0]:.2f} s: x{cold[1][0] / cold[0][0]:.2f} (cpu x{cold[1][1] / cold[0][1]:.2f})")
    if not povray_too:
        return
    if not shutil.which("povray"):
        print("  POV-Ray: not installed")
        return
    import raymitsuba
    from povray import export

    pov = os.path.join(work, "scene.pov")
    with open(pov, "w") as f:
        f.write(export(raymitsuba.parse(path), width, height))

    def povray(out, *aa):
        return ["povray", f"+I{pov}", f"+O{out}", f"+W{width}", f"+H{height}", "-D", "-V",
                "+WT2", *aa]

    pref = os.path.join(work, "pov_ref.png")
    process(povray(pref, "+A0.0", "+AM1", "+R16"), cwd=work)
    reference = images.read(pref)
    rows = []
    for label, aa in (("plain", ("-A",)), ("4 spp", ("+A0.0", "+AM1", "+R2")), ("+A0.3", ("+A0.3",))):
        out = os.path.join(work, "pov.png")
        runs = [process(povray(out, *aa), cwd=work) for _ in range(repeats)]
        rows.append((label, median([r[0] for r in runs]), median([r[1] for r in runs]),
                     *shares(images.read(out), reference)))
    base_wall, base_cpu = rows[0][1], rows[0][2]
    for label, wall_s, cpu_s, within2, within8 in rows:
        print(f"  POV-Ray {label:15} {within2:6.2f} % {within8:6.2f} %   time x{wall_s / base_wall:5.2f}"
              f" (cpu x{cpu_s / base_cpu:5.2f}; {wall_s:.2f} s)")


def aa_gallery_section(work, repeats, width=512, height=384, names=AA_GALLERY):
    """``--aa`` on gallery scenes that no benchmark tunes for: per scene the median of
    ``repeats`` rounds' whole-process ratio --aa / 1 spp (wall, cpu), and --aa's shares
    within 2/255 and 8/255 of the TRUTH_SPP render."""
    import numpy as np

    print(f"\n--aa on the gallery's scenes at {width}x{height} (whole processes, median of "
          f"{repeats} rounds' ratios --aa / 1 spp; within 2/255 and 8/255 of a {TRUTH_SPP}-spp "
          "render):")
    for name in names:
        path = scene_path(name)
        truth = references(work, path, width, height, (TRUTH_SPP,))[TRUTH_SPP]
        out = os.path.join(work, "gallery.npy")
        cmds = [render_cmd(path, out, "--width", width, "--height", height, *args)
                for args in (("--spp", 1), ("--aa",))]
        for cmd in cmds:
            process(cmd)  # warm the kernel cache
        rounds = []
        for _ in range(repeats):
            plain, aa = (process(cmd) for cmd in cmds)
            rounds.append((aa[0] / plain[0], aa[1] / plain[1], plain[0]))
        within2, within8 = shares(np.load(out), truth)  # (the last command's image: --aa)
        print(f"  {name:18} {within2:6.2f} % {within8:6.2f} %   wall x"
              f"{median([r[0] for r in rounds]):5.2f} (cpu x{median([r[1] for r in rounds]):5.2f};"
              f" 1 spp {median([r[2] for r in rounds]):.2f} s)")


def deep_section(work, repeats, width=1024, height=768, depth=64, exact_depth=28):
    """Depth 64 with the default (bounded) bailout, against POV-Ray at the same depth with
    its default adc_bailout, and its largest pixel error against the exact tree at
    ``exact_depth`` (``--bailout 0``; deeper generations no longer change it: shown by the
    exact tree 8 generations less deep). The exact renders take about a minute."""
    import numpy as np

    import raymitsuba
    from povray import export

    print(f"\ndepth {depth} at {width}x{height}, default bailout, whole processes (median of "
          f"{repeats}), against POV-Ray (max_trace_level {depth + 1}, adc_bailout 1/255) and the "
          f"exact tree at depth {exact_depth} (--bailout 0):")
    size = ("--width", width, "--height", height)
    for name in ("whitted", "benchmark_glass"):
        path = scene_path(name)
        out, exact, shallower = (os.path.join(work, f"{n}.npy") for n in ("deep", "ex", "ex8"))
        cmd = render_cmd(path, out, *size, "--max-depth", depth)
        process(cmd)  # warm the kernel cache
        runs = [process(cmd) for _ in range(repeats)]
        process(render_cmd(path, exact, *size, "--max-depth", exact_depth, "--bailout", 0,
                           "--time-limit", 0))
        process(render_cmd(path, shallower, *size, "--max-depth", exact_depth - 8, "--bailout", 0,
                           "--time-limit", 0))
        error = np.abs(np.load(out) - np.load(exact)).max() * 255
        settled = np.abs(np.load(shallower) - np.load(exact)).max() * 255
        wall_s, cpu_s = median([r[0] for r in runs]), median([r[1] for r in runs])
        line = (f"  {name:22} {wall_s:6.2f} s (cpu {cpu_s:.2f} s, peak {median([r[2] for r in runs]):.0f} MB)"
                f"  max error {error:.3f}/255 (exact depth {exact_depth - 8} vs {exact_depth}: "
                f"{settled:.3f}/255)")
        if shutil.which("povray"):
            pov = os.path.join(work, "deep.pov")
            with open(pov, "w") as f:
                f.write(export(raymitsuba.parse(path), width, height, max_depth=depth))
            pov_runs = [process(["povray", f"+I{pov}", f"+O{work}/pov.png", f"+W{width}",
                                 f"+H{height}", "-D", "-V", "+WT2", "-A"], cwd=work)
                        for _ in range(repeats)]
            pov_wall = median([r[0] for r in pov_runs])
            line += f"  POV-Ray {pov_wall:.2f} s, process / POV-Ray {wall_s / pov_wall:.2f}"
        print(line)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer repeats")
    ap.add_argument("--width", type=int, default=1024)
    ap.add_argument("--height", type=int, default=768)
    ap.add_argument("--only", default="table,grad,memory,aa",
                    help="comma-separated sections: table, grad, memory, aa, deep (minutes), "
                         "batch (benchmarks/batch_bench.py)")
    ap.add_argument("--huge", action="store_true",
                    help="memory section: also 16384 x 16384 at 1 spp (minutes)")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        job = json.loads(args.child)
        fn = {"first": first_render, "warm": warm_renders, "direct": native_direct,
              "grad": gradient_step}[job.pop("what")]
        print(json.dumps(fn(**job)))
        return

    from povray import ensure_povray

    ensure_povray()
    repeats = 3 if args.quick else 7
    w, h = args.width, args.height
    work = tempfile.mkdtemp(prefix="raymitsuba-bench-")
    only = set(args.only.split(","))
    if "table" in only:
        table(args, repeats, w, h, work)
    if "grad" in only:
        gradients(repeats, w, h)
    if "memory" in only:
        memory_section(work, args.huge)
    if "aa" in only:
        aa_section(work, repeats)
        aa_section(work, repeats, name="aa_showcase", povray_too=False)
        fine = os.path.join(work, "fine_detail.ray")
        with open(fine, "w") as f:
            f.write(fine_detail_scene())
        aa_section(work, repeats, name="fine_detail (generated)", path=fine, povray_too=False)
        aa_gallery_section(work, repeats)
    if "deep" in only:
        deep_section(work, repeats)
    if "batch" in only:
        import batch_bench

        batch_bench.run(args.quick)
    shutil.rmtree(work, ignore_errors=True)


def table(args, repeats, w, h, work):
    rows = []
    print(f"raymitsuba benchmark: {w}x{h}, medians of {repeats} runs (first renders: of 1-3 fresh processes)")
    for name in SCENES:
        path = scene_path(name)
        for spp in (1, 4):
            common = {"path": path, "width": w, "height": h, "spp": spp}
            cold_home = tempfile.mkdtemp(prefix="home-", dir=work)
            cold = child({"what": "first", **common}, env=dict(os.environ, HOME=cold_home))
            first = [child({"what": "first", **common})["first"] for _ in range(1 if args.quick else 3)]
            warm_run = child({"what": "warm", "repeats": repeats, **common})
            warm, rays = warm_run["times"], warm_run["rays"]
            direct = child({"what": "direct", "repeats": repeats, **common})
            out = os.path.join(work, "out.exr")
            process = wall([sys.executable, "-m", "raymitsuba", "render", path, "-o", out,
                            "--width", str(w), "--height", str(h), "--spp", str(spp)], max(3, repeats // 2))
            pov = povray_times(path, w, h, spp, max(3, repeats // 2), work)
            rows.append({"scene": name, "spp": spp, "cold_first": cold["first"], "first": median(first),
                         "warm": median(warm), "direct": median(direct), "process": median(process),
                         "povray": median(pov) if pov else None,
                         "rays": rays / (w * h * spp)})
    print()
    print(f"{'scene':22} {'spp':>3} {'cold 1st':>9} {'1st':>7} {'warm':>7} {'direct':>7} "
          f"{'warm/dir':>8} {'process':>8} {'povray':>7} {'pov/proc':>8} {'rays/cam':>8}")
    for r in rows:
        pov = f"{r['povray']:7.2f}" if r["povray"] else "    n/a"
        ratio = f"{r['povray'] / r['process']:8.2f}" if r["povray"] else "     n/a"
        print(f"{r['scene']:22} {r['spp']:3d} {r['cold_first']:9.2f} {r['first']:7.2f} {r['warm']:7.3f} "
              f"{r['direct']:7.3f} {r['warm'] / r['direct']:8.1f} {r['process']:8.2f} {pov} {ratio}"
              f" {r['rays']:8.2f}")
    for spp in (1, 4):
        refl = [r for r in rows if r["spp"] == spp and r["scene"] == SCENES[0]][0]
        glass = [r for r in rows if r["spp"] == spp and r["scene"] == SCENES[1]][0]
        print(f"glass / reflective warm render at {spp} spp: {glass['warm'] / refl['warm']:.2f}")


def gradients(repeats, w, h):
    print("\ngradient step (primal + reverse-mode gradient of an L2 loss) vs primal, on "
          f"{SCENES[1]}; each figure from its own process (time median, peak memory):")
    for (gw, gh, gspp) in ((256, 256, 8), (w, h, 1)):
        common = {"what": "grad", "path": scene_path(SCENES[1]), "width": gw, "height": gh,
                  "spp": gspp, "repeats": repeats}
        primal = child({**common, "mode": "primal"})
        for label, fields in (("all material parameters", None), ("Phong terms only", PHONG_FIELDS)):
            step = child({**common, "mode": "step", "fields": fields})
            print(f"  {gw}x{gh} {gspp} spp, {label:23}: primal {median(primal['times']):.3f} s "
                  f"({primal['peak_mb']:.0f} MB), step {median(step['times']):.3f} s "
                  f"({step['peak_mb']:.0f} MB), ratio {median(step['times']) / median(primal['times']):.2f}")


if __name__ == "__main__":
    main()
