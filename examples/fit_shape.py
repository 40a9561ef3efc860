"""Recover where a sphere is, and how large, from an image (geometry keys, edges and all).

    ./dev python examples/fit_shape.py [--iters 100] [--size 64] [--spp 16] [--lr 0.05]

A Phong sphere stands on a lit floor and casts a shadow. The target is rendered with the
sphere at ``translate2.offset`` = (0.2, 0, 0) and ``scale2.factors`` = 0.8 (uniform); the fit
starts 0.3 units to the right and 20 % larger. What tells the optimizer where the sphere is
sits mostly on edges: its silhouette against the floor and the background, and the edge of
its shadow on the floor. Their derivatives are the boundary terms of the pixel-integrated
image on the ``--spp k^2`` lattice (plugins/whitted/boundary/); the shading of the sphere
and of the floor adds the interior part. A scale of an analytic sphere stays uniform (the
three factors get one gradient; a sphere cannot become an ellipsoid during a fit).

The fitted numbers are written back into the .RAY text, every other byte unchanged.
"""

from __future__ import annotations

import argparse
import time

TRUE_SCENE = """\
eye 0 1 6
lookat 0 0 0
fov 40
background 0.2 0.3 0.4
light 1 1 1 point 2 4 5
light 0.2 0.2 0.2 ambient
material 0.9 0.9 0.8 0.3 0.7 0 1 0 0 1
translate 0 -1 0
plane
reset
material 0.8 0.4 0.3 0.3 0.7 0.3 10 0 0 1
translate 0.2 0 0
scale 0.8 0.8 0.8
sphere
"""

KEYS = ["translate2.offset", "scale1.factors"]
START = {"translate2.offset": (0.5, 0.0, 0.0), "scale1.factors": (0.96, 0.96, 0.96)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iters", type=int, default=100, help="Adam steps (default 100)")
    parser.add_argument("--size", type=int, default=64, help="image width (default 64)")
    parser.add_argument("--spp", type=int, default=16, help="samples per pixel, k^2 (default 16)")
    parser.add_argument("--lr", type=float, default=0.05, help="relative learning rate (default 0.05)")
    parser.add_argument("--quiet", action="store_true", help="no per-iteration progress")
    args = parser.parse_args(argv)

    import raymitsuba
    from raymitsuba.fit import fit, model_values, rewrite_scene, set_values

    width, height = args.size, args.size * 3 // 4
    data = TRUE_SCENE.encode()
    truth = raymitsuba.load(TRUE_SCENE, width=width, height=height, spp=args.spp)
    target = raymitsuba.render(truth).numpy()
    true_values = model_values(truth.model, KEYS, data)

    loaded = raymitsuba.load(TRUE_SCENE, width=width, height=height, spp=args.spp)
    set_values(loaded, START)  # the perturbed start

    def progress(step):
        if not args.quiet and (step.iteration % 25 == 0 or step.iteration == 1):
            values = "  ".join(f"{k}=({', '.join(f'{x:.4f}' for x in v)})"
                               for k, v in step.values.items())
            print(f"iter {step.iteration:4d}  loss {step.loss:.3e}  {values}")

    started = time.perf_counter()
    result = fit(loaded, target, KEYS, iters=args.iters, lr=args.lr, callback=progress)
    seconds = time.perf_counter() - started

    print(f"\n{'parameter':20s} {'true':>24s} {'start':>24s} {'fitted':>24s}")
    for key in KEYS:
        show = lambda v: "(" + ", ".join(f"{x:.4f}" for x in v) + ")"  # noqa: E731
        print(f"{key:20s} {show(true_values[key]):>24s} {show(result.start[key]):>24s} "
              f"{show(result.fitted[key]):>24s}")
    print(f"\n{result.iterations} iterations, {seconds:.1f} s, loss {result.losses[0]:.3e} -> "
          f"{result.final_loss:.3e}")
    print("\nthe fitted scene:\n" + rewrite_scene(data, truth.model, result.fitted).decode())
    return result, true_values


if __name__ == "__main__":
    main()
