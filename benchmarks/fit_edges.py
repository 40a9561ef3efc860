"""The issue 13 fit targets at 64 x 48, k = 4 (spp 16), 100 Adam steps each: a sphere moved 0.3
units back (``translate2.offset``) and a point light moved 0.5 (``light1.position``), fitted
back to the target rendered from the true scene; prints the largest component error.

    ./dev python benchmarks/fit_edges.py [--lr 0.05] [--final-lr 0.02]

The learning rate starts at ``--lr`` and decays geometrically to ``--final-lr`` times it
(:func:`raymitsuba.fit.fit`): Adam's steps keep a size of about the rate, so the last
rate bounds how close the fit settles (with the library's defaults, 0.02 and 0.1, the
sphere settled 2e-3 from the truth; with 0.05 and 0.02, 1.4e-4).

(The camera pose and the glass: ``examples/fit_pose.py``, ``examples/fit_glass.py``.)
"""
import argparse
import time

import numpy as np
import raymitsuba
from raymitsuba.fit import fit, set_values

SCENE = """eye 0 1 6
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
sphere
"""
parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("--lr", type=float, default=0.05, help="first learning rate (relative)")
parser.add_argument("--final-lr", type=float, default=0.02, help="last rate / first rate")
args = parser.parse_args()
truth = raymitsuba.load(SCENE, width=64, height=48, spp=16)
target = raymitsuba.render(truth).numpy()
for key, start, true in [("translate2.offset", (0.2, 0.0, -0.3), (0.2, 0.0, 0.0)),
                         ("light1.position", (2.5, 4.0, 5.0), (2.0, 4.0, 5.0))]:
    l = raymitsuba.load(SCENE, width=64, height=48, spp=16)
    set_values(l, {key: start})
    t = time.time()
    r = fit(l, target, [key], iters=100, lr=args.lr, final_lr=args.final_lr)
    err = np.max(np.abs(np.array(r.fitted[key]) - np.array(true)))
    print(key, "start", start, "fitted", r.fitted[key], "max error", err, f"{time.time()-t:.0f} s", flush=True)
