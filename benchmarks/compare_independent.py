"""The table of README's "Checking your own ray tracer": how images of ``scenes/`` made by
another tracer (tests/reference_tracer.py, numpy float64) score against raymitsuba's
references, correct and with the mistakes students make.

    ./dev python benchmarks/compare_independent.py [--size 64x48] [SCENE ...]

Per scene: the correct image's score and the pixels left out (unstable), then each
mistake's score and the share of the pixels it changes (n/a: the scene has nothing the
mistake touches). Same checks as tests/compare/test_independent.py, on every scene the
independent tracer can trace (also the two large MIT 6.837 meshes).
"""

from __future__ import annotations

import argparse
import glob
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path[:0] = [os.path.join(REPO, "tests"), os.path.join(REPO, "tests", "compare")]

import numpy as np  # noqa: E402

import reference_tracer as rt  # noqa: E402
import test_independent as ti  # noqa: E402
from raymitsuba.compare.score import TOLERANCE, difference, score  # noqa: E402
from raymitsuba.compare.stable import reference  # noqa: E402
from raymitsuba.format import parser  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="*")
    ap.add_argument("--size", default="64x48")
    args = ap.parse_args()
    width, height = map(int, args.size.split("x"))
    ti.W, ti.H = width, height
    names = args.scenes or sorted(os.path.basename(p)[:-4]
                                  for p in glob.glob(os.path.join(REPO, "scenes", "*.ray")))
    print(f"| scene | correct | left out | {' | '.join(ti.BUGS)} | numpy tracer |")
    print("|---|---:|---:|" + "---:|" * len(ti.BUGS) + "---:|")
    for name in names:
        path = os.path.join(REPO, "scenes", name + ".ray")
        model = parser.parse_file(path)
        try:
            rt.from_model(model, width, height)
        except NotImplementedError as e:
            print(f"| {name} | not traced by the numpy tracer ({e}) |")
            continue
        ref = reference(model, width, height, TOLERANCE)
        scored = ~ref.unstable
        start = time.perf_counter()
        correct = ti.independent(model)
        seconds = time.perf_counter() - start
        cells = [f"{score(correct, ref.image, scored=scored).match:.3f} %",
                 f"{ref.unstable.mean() * 100:.1f} %"]
        for bug in ti.BUGS:
            if bug == "stack_reversed":
                if model.dialect == "mit6837":
                    cells.append("n/a")
                    continue
                image = ti.independent(ti.stack_reversed(model, open(path).read()))
            else:
                image = ti.independent(model, (bug,))
            changed = (difference(image, correct) > TOLERANCE).mean() * 100
            cells.append("n/a" if changed == 0 else
                         f"{score(image, ref.image, scored=scored).match:.1f} % ({changed:.1f} %)")
        print(f"| {name} | {' | '.join(cells)} | {seconds:.1f} s |", flush=True)


if __name__ == "__main__":
    main()
