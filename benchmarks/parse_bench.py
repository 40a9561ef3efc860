"""Parser throughput: time to parse generated scenes of 10^4, 10^5 and 10^6 lines.

    .venv/bin/python benchmarks/parse_bench.py [--max-exponent 6] [--repeat 3]

Two tables. The first, below. The second reads the scale ladder's scenes
(``scale_bench.py``), whose every line is *simple* (a command word and its numbers, no
comment): the spheres scene (six lines an object: its own material, scale, translate,
sphere, two pops; the translations all distinct) against issue 31's target of 10^6 lines a
second, and the triangles scene (one line of nine distinct numbers a triangle); then the
MIT 6.837 dialect's: spheres each with its own ``surface`` (two lines an object), and one
mesh block of ``v`` and ``f`` lines (a height field, two faces a vertex).

The scene mixes every kind of line (objects, transforms with matching pops,
materials, lights, comments, blank lines). The parser is linear when the time
grows about tenfold per tenfold of lines, which the `ratio` column shows. The
`x floor` column compares with the least any parser must do (split the text into
lines and each line into tokens), which makes numbers from different machines
comparable. Timings live here, never in the tests.

Times are CPU seconds of this process (``time.process_time``; the parser is
single-threaded, so on an idle machine they equal the wall-clock time), the
median of ``--repeat`` runs: on a shared machine both choices make the figures
much steadier than one wall-clock reading.
"""

from __future__ import annotations

import argparse
import statistics
import time

from raymitsuba.format.parser import parse_text
from scale_bench import spheres, triangles

#: Issue 31: simple lines read per second, at least.
SIMPLE_TARGET = 1e6


def mit_spheres(n: int) -> str:
    """MIT 6.837: n spheres on a grid, each after a ``surface`` of its own colour."""
    lines = ["eye 0 0 400", "light 1 1 1 point 5 5 5"]
    for k in range(n):
        lines.append(f"surface {0.3 + 0.7 * (k % 7) / 6:.3g} 0.5 0.5 0.1 0.7 0.3 20 0 0 1")
        lines.append(f"sphere {k % 300} {k // 300} 0 0.4")
    return "\n".join(lines) + "\n"


def mit_mesh(n: int) -> str:
    """MIT 6.837: one block of about n vertices on a height field and two faces a vertex."""
    side = max(int(n ** 0.5), 2)
    lines = ["eye 0 0 10", "light 1 1 1 point 5 5 5",
             "surface 0.8 0.2 0.2 0.1 0.7 0.3 20 0 0 1", "triangles"]
    lines += [f"v {i / side:.6f} {j / side:.6f} {((i * 7 + j * 13) % 17) / 170:.6f}"
              for j in range(side) for i in range(side)]
    for j in range(side - 1):
        for i in range(side - 1):
            a = j * side + i
            lines += [f"f {a} {a + 1} {a + side + 1}", f"f {a} {a + side + 1} {a + side}"]
    return "\n".join(lines + ["end"]) + "\n"

BLOCK = """\
# a block of 20 lines that leaves the stack as it found it
material 0.8 0.2 0.1 0.1 0.7 0.3 20 0.1 0 1
translate 1 2 3
rotateY 30
scale 0.5 0.5 0.5   # a trailing comment
sphere
cylinder
pop
cone
triangle 0 0 0 1 0 0 0 1 0
pop
rotateX 90
plane
checkerboard 0.5
pop

light 0.2 0.2 0.2 point 1 5 1
ROTATEZ -45
triangle 1 1 1 2 1 1 1 2 1
reset
"""
BLOCK_LINES = BLOCK.count("\n")


def scene_text(lines: int) -> str:
    return BLOCK * (lines // BLOCK_LINES)


def split_only(text: str) -> None:
    """Split ``text`` into lines and tokens: the floor for any parser."""
    for line in text.split("\n"):
        line.split()


def timed(function, argument, repeat: int):
    """(median CPU seconds of ``repeat`` calls of ``function(argument)``, the last result).

    A result is freed before the next clock starts: freeing is not parsing.
    """
    times, result = [], None
    for _ in range(repeat):
        result = None
        start = time.process_time()
        result = function(argument)
        times.append(time.process_time() - start)
    return statistics.median(times), result


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-exponent", type=int, default=6, help="largest power of ten of lines")
    ap.add_argument("--repeat", type=int, default=3, help="runs per size; the median is shown")
    args = ap.parse_args()
    previous = None
    print(f"{'lines':>10} {'seconds':>9} {'lines/s':>11} {'ratio':>6} {'x floor':>8}")
    for exponent in range(4, args.max_exponent + 1):
        text = scene_text(10 ** exponent)
        seconds, scene = timed(parse_text, text, args.repeat)
        floor, _ = timed(split_only, text, args.repeat)
        ratio = f"{seconds / previous:6.1f}" if previous else "     -"
        print(f"{10 ** exponent:>10} {seconds:9.3f} {10 ** exponent / seconds:11.0f} {ratio}"
              f" {seconds / floor:8.1f}   ({len(scene.objects)} objects)")
        previous = seconds
    print(f"\n{'simple lines':>22} {'lines':>9} {'seconds':>9} {'lines/s':>11}  target")
    for exponent in range(4, min(args.max_exponent, 5) + 1):
        for name, family in (("spheres", spheres), ("triangles", triangles),
                             ("MIT spheres", mit_spheres), ("MIT mesh", mit_mesh)):
            text = family(10 ** exponent)
            lines = text.count("\n")
            seconds, scene = timed(parse_text, text, args.repeat)
            rate = lines / seconds
            verdict = (f"{'met' if rate >= SIMPLE_TARGET else 'NOT met'} "
                       f"({rate / SIMPLE_TARGET:.2f} of 10^6)") if name == "spheres" else ""
            print(f"{f'{name} 10^{exponent}':>22} {lines:>9} {seconds:9.3f} {rate:11.0f}  "
                  f"{verdict}")


if __name__ == "__main__":
    main()
