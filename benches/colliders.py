"""What colliders cost without contact: ms per step by component on a cloth over analytic
colliders, with a fixed number of iterations (tol = 0) so that every run does the same work.

Scenarios (an n x n cloth of 0.8 m, 1 mm thick, StretchA3 s0 = 2e4 Pa, dt = 2 ms):
  drape   falling from 0.25 m onto a box (0.4 x 0.4 x 0.2 m) and a ball (r = 0.1 m) beside it;
  impact  shot down at 20 m/s onto a plate 2 mm thick (dt = 10 ms: each step moves the cloth
          0.2 m, past the plate; every collider pass then follows the paths that reach it).
Recorded per scenario: the median over the steps after ``--warmup`` of the total, global
(Jacobi, with its collider pass in the D-metric) and collider-pass (projection after the
global step) times per step, and the smallest clearance to the colliders at the end (m; the
target is the half thickness, 0.5 mm).

Default (about a minute):  python benches/colliders.py
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn  # noqa: E402


def cloth(n: float, height: float) -> peridyn.Membrane:
    V, F = peridyn.grid(n, n, size=(0.8, 0.8), diagonal="alternate")
    V = V - np.array([0.4, 0.4, -height])
    return peridyn.Membrane(V, F, thickness=1e-3, density=300.0,
                            material=peridyn.StretchA3(s0=2e4), bending=1e-6)


def scenario(name: str, n: int, iterations: int, threads: int):
    if name == "drape":
        m = cloth(n, 0.25)
        colliders = [peridyn.Box(center=(0, 0, 0), half_extents=(0.2, 0.2, 0.1)),
                     peridyn.Sphere(center=(0.3, 0.3, 0.1), radius=0.1)]
        dt = 2e-3
    else:
        m = cloth(n, 0.05)
        m.velocities = np.tile([0.0, 0.0, -20.0], (m.positions.shape[0], 1))
        colliders = [peridyn.Box(center=(0, 0, 0), half_extents=(0.5, 0.5, 1e-3))]
        dt = 1e-2
    s = peridyn.Solver(dt=dt, tol=0.0, max_iters=iterations, threads=threads)
    s.add(m)
    for c in colliders:
        s.add_collider(c)
    return s, m, colliders


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=100, help="vertices per side")
    ap.add_argument("--steps", type=int, default=120)
    ap.add_argument("--warmup", type=int, default=20)
    ap.add_argument("--iterations", type=int, default=30, help="global iterations per step")
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    run = C.Record("colliders", args)
    results = {}
    for name in ("drape", "impact"):
        s, m, colliders = scenario(name, args.n, args.iterations, args.threads)
        parts = {"total": [], "global": [], "colliders": []}
        for k in range(args.steps):
            timings = s.step().timings
            if k >= args.warmup:
                for key in parts:
                    parts[key].append(timings[key])
        clearance = min(float(c.signed_distance(m.positions, time=s.time).min())
                        for c in colliders)
        results[name] = {
            "vertices": int(m.positions.shape[0]),
            "colliders": len(colliders),
            "median_ms": {key: C.median(v) for key, v in parts.items()},
            "min_clearance_m": clearance,
        }
        ms = results[name]["median_ms"]
        print(f"{name}: {ms['total']:.2f} ms per step (global {ms['global']:.2f}, "
              f"colliders {ms['colliders']:.2f}), clearance {clearance * 1e3:.3f} mm", flush=True)
    run.data["results"] = results
    run.write(args.out)


if __name__ == "__main__":
    main()
