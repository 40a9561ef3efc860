"""Recover a Phong material from an image: color, diffuse_mix, specular_mix and phong_coeff.

    ./dev python examples/fit_phong.py [--iters 800] [--size 64] [--lr 0.03]

The target is rendered from the true scene below; the material's four parameters
are then perturbed and fitted back with :func:`raymitsuba.fit.fit` (Adam on the
mean squared pixel error), and a table of true / start / fitted values is printed.

Why these four are recoverable from one image: every pixel of the sphere is

    C * (ka * A + kd * I * (N.L)) + ks * I * (R.V)^n

with the ambient light A, ka and the light I known (not fitted). The ambient
term pins the color C (it is the same everywhere on the sphere), the N.L
pattern then pins kd, and the untinted highlight pins ks (its height) and n (its
width). If ka or the light's color were fitted too, C * kd * I would only be
determined as a product: the loss would still fall, but the parameters need not
come back. The floor and the shadow are there to look at; they do not move, so
they do not disturb the derivatives.
"""

from __future__ import annotations

import argparse
import time

TRUE_SCENE = """\
# A glossy sphere on a floor (the fitted material is mat2)
eye 0.3 1.2 5
lookat 0 0 0
fov 35
light 0.9 0.9 0.85 point 3 4 5
light 0.45 0.45 0.45 ambient
material 0.7 0.7 0.75 0.3 0.6 0 1 0 0 1
translate 0 -1 0
plane
reset
material 0.85 0.35 0.2 0.5 0.65 0.45 25 0 0 1
sphere
"""

KEYS = ["mat2.color", "mat2.diffuse_mix", "mat2.specular_mix", "mat2.phong_coeff"]
START = {"mat2.color": (0.5, 0.5, 0.5), "mat2.diffuse_mix": 0.4,
         "mat2.specular_mix": 0.2, "mat2.phong_coeff": 10.0}


def show(value):
    if isinstance(value, tuple):
        return "(" + ", ".join(f"{v:.3f}" for v in value) + ")"
    return f"{value:.3f}"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iters", type=int, default=800, help="Adam steps (default 800)")
    parser.add_argument("--size", type=int, default=64, help="image width and height (default 64)")
    parser.add_argument("--lr", type=float, default=0.03, help="relative learning rate (default 0.03)")
    parser.add_argument("--quiet", action="store_true", help="no per-iteration progress")
    args = parser.parse_args(argv)

    import raymitsuba
    from raymitsuba.fit import fit, model_values, set_values

    truth = raymitsuba.load(TRUE_SCENE, width=args.size, height=args.size)
    target = raymitsuba.render(truth).numpy()
    true_values = model_values(truth.model, KEYS)

    loaded = raymitsuba.load(TRUE_SCENE, width=args.size, height=args.size)
    set_values(loaded, START)  # the perturbed start

    def progress(step):
        if not args.quiet and (step.iteration % 100 == 0 or step.iteration == 1):
            print(f"iter {step.iteration:4d}  loss {step.loss:.3e}")

    started = time.perf_counter()
    result = fit(loaded, target, KEYS, iters=args.iters, lr=args.lr, callback=progress)
    seconds = time.perf_counter() - started

    print(f"\n{'parameter':20s} {'true':>24s} {'start':>24s} {'fitted':>24s}")
    for key in KEYS:
        print(f"{key:20s} {show(true_values[key]):>24s} {show(result.start[key]):>24s} "
              f"{show(result.fitted[key]):>24s}")
    print(f"\n{result.iterations} iterations, {seconds:.1f} s, loss {result.losses[0]:.3e} -> "
          f"{result.final_loss:.3e}")
    return result, true_values


if __name__ == "__main__":
    main()
