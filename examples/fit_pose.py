"""Recover the camera's pose -- where the eye is and what it looks at -- from an image.

    ./dev python examples/fit_pose.py [--iters 150] [--size 64] [--spp 16] [--lr 0.01]
                                      [--final-lr 0.2]

Two spheres stand on a checkered floor under a point light. The target is rendered from
the scene as written; the fit starts with ``camera.eye`` moved by (0.2, 0, 0) and
``camera.lookat`` by (0, 0.1, 0) and moves them back by Adam on the mean squared pixel error
(:func:`raymitsuba.fit.fit`). The camera's rays are rebuilt in Dr.Jit from the eye, the
look-at point, the up vector and the field of view (plugins/whitted/geometry_ad.py); what
the pose changes are mostly edges -- the spheres' silhouettes, their shadows, the checker
lines -- whose derivatives are the boundary terms of the ``--spp k^2`` lattice
(plugins/whitted/boundary/).
"""

from __future__ import annotations

import argparse
import time

TRUE_SCENE = """\
eye 0.5 2.5 6
lookat 0 0.2 0
fov 35
background 0.2 0.3 0.4
light 1 1 1 point 2 5 4
light 0.25 0.25 0.25 ambient
material 0.9 0.85 0.7 0.4 0.6 0 1 0 0 1
translate 0 -1 0
checkerboard 1.2
plane
reset
material 0.8 0.3 0.2 0.3 0.7 0.3 10 0 0 1
translate -0.9 0 0
sphere
reset
material 0.2 0.5 0.8 0.3 0.7 0.3 10 0 0 1
translate 1 -0.4 0.8
scale 0.6 0.6 0.6
sphere
"""

KEYS = ["camera.eye", "camera.lookat"]
START = {"camera.eye": (0.7, 2.5, 6.0), "camera.lookat": (0.0, 0.3, 0.0)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iters", type=int, default=150, help="Adam steps (default 150)")
    parser.add_argument("--size", type=int, default=64, help="image width (default 64)")
    parser.add_argument("--spp", type=int, default=16, help="samples per pixel, k^2 (default 16)")
    parser.add_argument("--lr", type=float, default=0.01, help="relative learning rate (default 0.01)")
    parser.add_argument("--final-lr", type=float, default=0.2,
                        help="the last step's rate as a share of --lr (default 0.2; 0.1 and 0.02 "
                             "end further from the truth in 150 steps)")
    parser.add_argument("--quiet", action="store_true", help="no per-iteration progress")
    args = parser.parse_args(argv)

    import raymitsuba
    from raymitsuba.fit import fit, model_values, set_values

    width, height = args.size, args.size * 3 // 4
    truth = raymitsuba.load(TRUE_SCENE, width=width, height=height, spp=args.spp)
    target = raymitsuba.render(truth).numpy()
    true_values = model_values(truth.model, KEYS, TRUE_SCENE)

    loaded = raymitsuba.load(TRUE_SCENE, width=width, height=height, spp=args.spp)
    set_values(loaded, START)  # the perturbed start

    def progress(step):
        if not args.quiet and (step.iteration % 25 == 0 or step.iteration == 1):
            values = "  ".join(f"{k}=({', '.join(f'{x:.4f}' for x in v)})"
                               for k, v in step.values.items())
            print(f"iter {step.iteration:4d}  loss {step.loss:.3e}  {values}")

    started = time.perf_counter()
    result = fit(loaded, target, KEYS, iters=args.iters, lr=args.lr, final_lr=args.final_lr,
                 callback=progress)
    seconds = time.perf_counter() - started

    print(f"\n{'parameter':16s} {'true':>24s} {'start':>24s} {'fitted':>24s}")
    for key in KEYS:
        show = lambda v: "(" + ", ".join(f"{x:.4f}" for x in v) + ")"  # noqa: E731
        print(f"{key:16s} {show(true_values[key]):>24s} {show(result.start[key]):>24s} "
              f"{show(result.fitted[key]):>24s}")
    print(f"\n{result.iterations} iterations, {seconds:.1f} s, loss {result.losses[0]:.3e} -> "
          f"{result.final_loss:.3e}")
    across, along = lookat_error(true_values, result.fitted)
    print(f"camera.lookat error across the line of sight {across:.2e}, along it {along:.2e} "
          f"(moving the look-at point along the line of sight changes no pixel: that part "
          f"cannot be recovered from an image)")
    return result, true_values


def lookat_error(true_values, fitted):
    """(|error across the true line of sight|, |error along it|) of the fitted look-at point:
    the image depends on the eye, the direction from it to the look-at point, the up vector
    and the fov, not on how far along that direction the look-at point lies."""
    import numpy as np

    eye, lookat = (np.asarray(true_values[k], float) for k in KEYS)
    view = (lookat - eye) / np.linalg.norm(lookat - eye)
    error = np.asarray(fitted["camera.lookat"], float) - lookat
    along = float(error @ view)
    return float(np.linalg.norm(error - along * view)), abs(along)


if __name__ == "__main__":
    main()
