"""What the fade of nearly parallel edge-edge pairs (``Contact(parallel_angle=...)``) buys and
costs: two stacked layers dropped over a ball, solved at a tight and at the default tolerance,
for fade angles from 0 (the paper's barrier) up, side by side in one process.

The scene is ``paper_scenes.cloths_over_ball(layers=2, n=--n, size=0.5)``: the layers drape over
the ball onto the ground, and each edge of the upper layer lies along an edge of the lower one.
Per fade angle and tolerance it records the iterations per step (median and largest), the steps
that ran to ``--max-iters``, ms per step (median), the local step's iterations per step
(median), and at the end the smallest distance between non-adjacent primitives (m; the local
step keeps it above ``eps xi``) and whether any two triangles intersect.

Default (about half a minute):  python benches/parallel_fade.py
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn  # noqa: E402

#: The default fade angle (radians), IPC's: asin(sqrt(1e-3)).
DEFAULT_ANGLE = peridyn.Contact().parallel_angle


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=12, help="vertices per side of each layer")
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--max-iters", type=int, default=200)
    ap.add_argument("--tols", type=float, nargs="+", default=[1e-6, 1e-4],
                    help="solver tolerances (m)")
    ap.add_argument("--angles", type=float, nargs="+",
                    default=[0.0, 0.5 * DEFAULT_ANGLE, DEFAULT_ANGLE, 3 * DEFAULT_ANGLE],
                    help="fade angles (radians); the default is IPC's, asin(sqrt(1e-3))")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    record = C.Record("parallel_fade", args)
    results = []
    for tol in args.tols:
        for angle in args.angles:
            r = C.layers_over_ball({"parallel_angle": angle}, tol, args)
            results.append(r)
            print(f"tol {tol:g} m, fade {math.degrees(angle):.2f} deg: {C.layers_summary(r)}",
                  flush=True)
    record.data["results"] = results
    record.write(args.out)


if __name__ == "__main__":
    main()
