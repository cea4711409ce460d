"""Resting contact (issue 41, item 3): two 15 x 15 cloths of 1 mm (0.3 m, StretchA3 s0 = 2e4 Pa,
density 200, bending 1e-3) dropped 5 and 15 mm onto a table (`Plane`, friction 0.5), dt = 2 ms,
tol = 1e-5, max_iters = 60, `Contact(thickness=1e-3)` with the default `d_hat` or `--d-hat`,
friction between the cloths `--friction` (default 0).

Recorded: per step the global iterations, whether it converged, the largest speed of the upper
cloth, and the gap between the two cloths' mean heights; summarised after ``--settle`` steps
(the upper cloth lands within about 60 ms).

Default (about a minute):  python benches/resting_stack.py [--friction 0.5] [--out ...]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn  # noqa: E402


def cloth(z: float, friction: float) -> peridyn.Membrane:
    V, F = peridyn.grid(15, 15, size=(0.3, 0.3))
    V = V - np.array([0.15, 0.15, -z])
    return peridyn.Membrane(V, F, thickness=1e-3, density=200.0,
                            material=peridyn.StretchA3(s0=2e4), bending=1e-3, friction=friction)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--steps", type=int, default=600)
    ap.add_argument("--settle", type=int, default=50)
    ap.add_argument("--d-hat", type=float, default=None, help="barrier range (m)")
    ap.add_argument("--friction", type=float, default=0.0,
                    help="the cloths' friction against each other")
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    run = C.Record("resting_stack", args)
    contact = peridyn.Contact(thickness=1e-3, d_hat=args.d_hat)
    lower, upper = cloth(5e-3, args.friction), cloth(15e-3, args.friction)
    s = peridyn.Solver(dt=2e-3, tol=1e-5, max_iters=60, gravity=(0.0, 0.0, -9.81),
                       contact=contact)
    s.add(lower)
    s.add(upper)
    s.add_collider(peridyn.Plane(point=(0, 0, 0), normal=(0, 0, 1), friction=0.5))
    iterations, converged, speed, gap = [], [], [], []
    for _ in range(args.steps):
        stats = s.step()
        iterations.append(stats.iterations)
        converged.append(bool(stats.converged))
        speed.append(float(np.linalg.norm(upper.velocities, axis=1).max()))
        gap.append(float(upper.positions[:, 2].mean() - lower.positions[:, 2].mean()))
    after = slice(args.settle, None)
    summary = {
        "d_hat_m": contact.d_hat,
        "iterations_max_after_settling": max(iterations[after]),
        "iterations_median_after_settling": C.median(iterations[after]),
        "unconverged_steps_after_settling": int(sum(not c for c in converged[after])),
        "upper_speed_max_after_settling_m_s": max(speed[after]),
        "gap_at_end_m": gap[-1],
    }
    print(summary, flush=True)
    run.data["summary"] = summary
    run.data["per_step"] = {"iterations": iterations, "converged": converged,
                            "upper_speed_m_s": speed, "gap_m": gap}
    run.write(args.out)


if __name__ == "__main__":
    main()
