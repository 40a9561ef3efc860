"""Recover the refractivity kt and the index of refraction eta of a glass sphere.

    ./dev python examples/fit_glass.py [--iters 150] [--size 64] [--lr 0.02]
    ./dev python examples/fit_glass.py --checker 0.4 [--scan auto|none|LOW:HIGH:N]

A glass sphere stands in front of a wall lit by two colored point lights placed
between the sphere and the wall, so the wall is a smooth color gradient and the
sphere casts no shadow on it. The target is rendered with kt = 0.85, eta = 1.5;
the fit starts from kt = 0.5, eta = 1.15 and recovers both by Adam on the mean
squared pixel error (:func:`raymitsuba.fit.fit`).

How the information gets there: a pixel inside the sphere's disk shows the wall
point that its refracted ray reaches, times kt (entering and leaving are each
weighted by kt, and the ray tree multiplies them). kt scales that image; eta
bends the rays, i.e. moves *which* wall point each pixel sees (it magnifies and
inverts the wall). The derivative with respect to eta is therefore
d(wall color)/d(wall point) x d(wall point)/d(eta): it exists only because the
wall's shading varies smoothly from point to point.

**A checkerboard background** (``--checker SIZE``: the wall checkered). The classic
picture (a glass ball in front of a checkered wall) is piecewise constant in the wall
point: inside a square the color does not change as the refracted ray moves, so most of
the information about eta lies in the checker *edges* moving across pixels. With
``--spp k^2`` lattices the derivative includes them (the boundary terms along the specular
chain, plugins/whitted/boundary/; docs/gradients.md measures them), but the loss is full
of basins: each checker square seen through the ball makes one. Scanned at kt = 0.5 (the
start) with ``checkerboard 0.4``, 64 x 64, spp 16, the loss has its least value at eta =
1.5 in a basin from about 1.35 to 1.7, and a barrier at about 1.25: from 1.15 the steps
alone (``--scan none``) walk away from it (to 1.13, or 1.06 coarse to fine). So
:func:`raymitsuba.fit.fit` first scans eta by itself (its default, ``scan="auto"``: the
start and 32 values from 1.15 / 1.5 to 1.15 x 1.5, spacing 0.031, finer than the basin;
33 primal renders), and the steps start from the best of them. ``--scan LOW:HIGH:N``
scans a grid of your own instead (:class:`raymitsuba.fit.Scan`).

The glass has no diffuse or specular term (kd = ks = 0) and kr = 0: a highlight
seen on the inside of the sphere ends where N.L crosses 0, another moving
discontinuity.
"""

from __future__ import annotations

import argparse
import time

TRUE_SCENE = """\
# A glass sphere in front of a wall lit by two lights between them (mat2 is the glass)
eye 0.15 0.1 6
lookat 0 0 0
fov 30
light 1 0.55 0.3 point -1.2 0.8 -2.2
light 0.3 0.6 1 point 1.3 -0.6 -2.4
light 0.15 0.15 0.15 ambient
material 0.9 0.9 0.9 0.5 0.9 0 1 0 0 1
rotateX 90
translate 0 0 -3
plane
reset
material 1 1 1 0 0 0 1 0 0.85 1.5
sphere
"""

KEYS = ["mat2.refractivity", "mat2.ior"]
START = {"mat2.refractivity": 0.5, "mat2.ior": 1.15}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iters", type=int, default=150, help="Adam steps (default 150)")
    parser.add_argument("--size", type=int, default=64, help="image width and height (default 64)")
    parser.add_argument("--lr", type=float, default=0.02, help="relative learning rate (default 0.02)")
    parser.add_argument("--checker", type=float, default=None, metavar="SIZE",
                        help="checker the wall with squares of SIZE")
    parser.add_argument("--scan", default="auto", metavar="auto|none|LOW:HIGH:N",
                        help="the values of eta tried before the steps: 'auto' (default: "
                             "fit's automatic scan), 'none' (no scan), or a grid LOW:HIGH:N")
    parser.add_argument("--spp", type=int, default=None, help="samples per pixel (default 1; "
                        "with --checker 16, a 4 x 4 lattice: the checker edges' derivatives)")
    parser.add_argument("--quiet", action="store_true", help="no per-iteration progress")
    args = parser.parse_args(argv)

    import raymitsuba
    from raymitsuba.fit import Scan, fit, model_values, set_values

    scene = TRUE_SCENE if args.checker is None else TRUE_SCENE.replace(
        "translate 0 0 -3\n", f"translate 0 0 -3\ncheckerboard {args.checker:g}\n")
    spp = args.spp or (1 if args.checker is None else 16)
    scan = args.scan if args.scan in ("auto", "none") else [Scan.parse("mat2.ior=" + args.scan)]
    truth = raymitsuba.load(scene, width=args.size, height=args.size, spp=spp)
    target = raymitsuba.render(truth).numpy()
    true_values = model_values(truth.model, KEYS)

    loaded = raymitsuba.load(scene, width=args.size, height=args.size, spp=spp)
    set_values(loaded, START)  # the perturbed start

    def progress(step):
        if not args.quiet and (step.iteration % 50 == 0 or step.iteration == 1):
            values = "  ".join(f"{k}={v:.4f}" for k, v in step.values.items())
            print(f"iter {step.iteration:4d}  loss {step.loss:.3e}  {values}")

    started = time.perf_counter()
    result = fit(loaded, target, KEYS, iters=args.iters, lr=args.lr, callback=progress,
                 scan=scan)
    seconds = time.perf_counter() - started
    if result.scanned:
        best, loss = min(result.scanned, key=lambda item: item[1])
        print(f"scanned eta over {len(result.scanned)} values ({result.scan_seconds:.1f} s): "
              f"best {best['mat2.ior']:.4f} (loss {loss:.3e}); the steps started there")

    print(f"\n{'parameter':20s} {'true':>8s} {'start':>8s} {'fitted':>8s}")
    for key in KEYS:
        print(f"{key:20s} {true_values[key]:8.4f} {START[key]:8.4f} "
              f"{result.fitted[key]:8.4f}")
    print(f"\n{result.iterations} iterations, {seconds:.1f} s, loss {result.losses[0]:.3e} -> "
          f"{result.final_loss:.3e}")
    return result, true_values


if __name__ == "__main__":
    main()
