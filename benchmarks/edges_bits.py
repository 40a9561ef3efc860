"""The bits of the edges benchmark's derivatives, to show that a change moved none.

    ./dev python benchmarks/edges_bits.py --save before.json    # on the code before
    ./dev python benchmarks/edges_bits.py --against before.json  # on the code after

For each of benchmarks/edges_bench.py's CASES (a kind of edge, a key, a direction) at 32 x
24: the forward-mode derivative of the image at k = 2 and k = 4, as the sha256 of its
float32 bits; the reverse-mode gradient of a weighted sum (fixed random weights) at k = 4;
and the forward-mode derivative of the benchmark's cost scene along each of its COST_KEYS
(a geometry key alone, the camera still; and with the camera's). ``--against``: the
forward-mode bits must be the same; a reverse pass's sums are atomic, their order (so their
last digits) varies from run to run: compared to 1e-5 of the gradient's norm (measured
run to run: up to 3e-6).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
sys.path.insert(0, HERE)

W, H = 32, 24
REVERSE_TOLERANCE = 1e-5  # of the gradient's norm
TANGENTS = {"translate2.offset": (0.6, -0.8, 0.0), "camera.eye": (0.6, 0.0, -0.8)}


def bits(mi):
    """{case: sha256 of a forward derivative's float32 bits, or a reverse gradient (list)}."""
    import edges_bench
    from support_edges import SPHERE_ON_CHECKER, forward, loaded, reverse, tangent_derivative

    weights = np.random.default_rng(13).random((H, W, 3))
    out = {}
    for i, (kind, label, text, key, direction, _) in enumerate(edges_bench.CASES):
        for k in (2, 4):
            grad = forward(mi, text, key, direction, k * k, width=W, height=H)
            out[f"forward {i} {kind}, {label}, k = {k}"] = \
                hashlib.sha256(grad.astype(np.float32).tobytes()).hexdigest()
        out[f"reverse {i} {kind}, {label}, k = 4"] = \
            reverse(mi, text, key, weights, 16, width=W, height=H).tolist()
    for keys in edges_bench.COST_KEYS:
        scene = loaded(mi, SPHERE_ON_CHECKER, 16, width=W, height=H)
        grad = tangent_derivative(scene, {key: TANGENTS[key] for key in keys})
        out[f"forward cost {', '.join(keys)}, k = 4"] = \
            hashlib.sha256(grad.astype(np.float32).tobytes()).hexdigest()
    return out


def compare(now, before):
    """Lines saying where ``now`` differs from ``before``; the count of the same."""
    differ, same = [], 0
    for name, value in before.items():
        if name not in now:
            differ.append(f"{name}: missing")
        elif name.startswith("reverse"):
            a, b = np.asarray(value), np.asarray(now[name])
            error = float(np.linalg.norm(a - b) / max(np.linalg.norm(a), 1e-30))
            if error > REVERSE_TOLERANCE:
                differ.append(f"{name}: {error:.1e} of the gradient's norm")
            else:
                same += 1
        elif now[name] != value:
            differ.append(f"{name}: other bits")
        else:
            same += 1
    return differ, same


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--save", help="write the bits to this JSON file")
    parser.add_argument("--against", help="compare the bits with this JSON file's")
    args = parser.parse_args(argv)
    from raymitsuba.backend import mitsuba

    now = bits(mitsuba())
    if args.save:
        with open(args.save, "w") as f:
            json.dump(now, f, indent=1)
    if args.against:
        with open(args.against) as f:
            differ, same = compare(now, json.load(f))
        print(f"{same} the same" + "".join(f"\n{line}" for line in differ))
        return 1 if differ else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
