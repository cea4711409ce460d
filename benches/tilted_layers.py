"""How the angle at which a tilted layer flows depends on its thickness (issue 39, round ab:
Pouliquen 1999's ``h_stop(theta)``, the thickness below which a layer on a rough base stops,
which diverges near the angle of repose and falls to zero some 10-13 degrees steeper).

Scene: tests/test_granular.py's `layer_moves` (12 x 6 x ``layers`` spacings of 1 cm on a
pinned base layer of the same jittered body, in a box of frictionless walls, settled 0.3 s,
then stepped ``--window`` s with gravity turned by the tilt), sites jittered by 0.1 spacings
(``--seeds``). Measured per run: the surface layer's mean move over the last 0.1 s (m; the
repose test calls a layer flowing above 0.05 mm and at rest below 0.01 mm) and the largest
move over the window (m).

Sands (``--sand``): ``rolling`` is round ab's, ``contact_friction = tan(phi)``,
``rolling_resistance`` 0.1; ``disordered`` the repose tests' `disordered_sand`
(``0.1 tan(phi)``, no rolling).

    python benches/tilted_layers.py --sand rolling --layers 4 8 12 --out ...
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
import _common as C  # noqa: E402
import test_granular as tg  # noqa: E402

import peridyn as pd  # noqa: E402


def material(sand: str, angle: float, rolling: float) -> pd.Granular:
    if sand == "rolling":
        return tg.sand(angle, contact_friction=float(np.tan(np.radians(angle))),
                       rolling_resistance=rolling)
    return tg.disordered_sand(angle)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sand", choices=["rolling", "disordered"], default="rolling")
    ap.add_argument("--angle", type=float, default=30.0, help="friction angle (degrees)")
    ap.add_argument("--rolling", type=float, default=0.1, help="mu_r of the rolling sand")
    ap.add_argument("--layers", type=int, nargs="+", default=[4, 8, 12])
    ap.add_argument("--tilts", type=float, nargs="+", default=[-10.0, 0.0, 5.0, 10.0, 15.0],
                    help="tilts relative to the friction angle (degrees)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1])
    ap.add_argument("--window", type=float, default=0.3, help="s")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    rec = C.Record("tilted_layers", args)
    runs = []
    for layers in args.layers:
        for seed in args.seeds:
            for tilt in args.tilts:
                t0 = time.perf_counter()
                surface, largest = tg.layer_moves(
                    args.angle + tilt, jitter=0.1, seed=seed, window=args.window,
                    layers=layers, material=material(args.sand, args.angle, args.rolling))
                r = {"sand": args.sand, "friction_angle_deg": args.angle, "layers": layers,
                     "seed": seed, "tilt_deg": args.angle + tilt,
                     "surface_move_m": float(surface), "largest_move_m": float(largest),
                     "wall_s": time.perf_counter() - t0}
                print(r, flush=True)
                runs.append(r)
                rec.data["results"] = runs
                rec.write(args.out)


if __name__ == "__main__":
    main()
