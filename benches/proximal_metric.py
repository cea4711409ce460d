"""What the metric of the local step's proximal term (``Contact(proximal=...)``) buys and costs:
the paper's identity against the global step's Jacobi blocks (the default), side by side in one
process, on two scenes.

1. **Collision of a light and a heavy sheet.** Two 7x7 sheets of 0.1 m, 200 and 1600 kg/m^3,
   meet at 0.5 m/s in zero gravity, offset by half a spacing (:func:`peridyn.colliding_sheets`,
   as in ``tests/test_contact.py``). Records the largest change of the total momentum over the
   steps, over the light sheet's momentum before impact (0 for exact conservation), both
   sheets' mean velocity at the end (m/s), the iterations per step (median and largest) and
   ms per step (median).
2. **Stacked layers over the ball** (``_common.layers_over_ball``): iterations and local
   iterations per step, steps at the cap, ms per step, smallest distance, intersections.

Default (two to three minutes):  python benches/proximal_metric.py
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn  # noqa: E402

METRICS = ("identity", "jacobi")


def collision(proximal: str, args) -> dict:
    """Scene 1 for ``proximal``: ``args.collision_steps`` steps of 1 ms at
    ``args.collision_tol``."""
    scene = peridyn.colliding_sheets(
        densities=(200.0, 1600.0), speed=0.5, tol=args.collision_tol, max_iters=args.max_iters,
        contact=peridyn.Contact(thickness=2e-3, d_hat=4e-3, proximal=proximal),
        threads=args.threads)
    solver, light, heavy = scene.solver, scene.lower, scene.upper

    def momentum():
        return sum(b.masses @ b.velocities for b in (light, heavy))

    before, drift, iterations, ms = momentum(), 0.0, [], []
    start = time.perf_counter()
    for _ in range(args.collision_steps):
        stats = solver.step()
        drift = max(drift, float(np.linalg.norm(momentum() - before)))
        iterations.append(stats.iterations)
        ms.append(stats.timings["total"])
    return {
        "proximal": proximal,
        "tol_m": args.collision_tol,
        "wall_s": time.perf_counter() - start,
        "momentum_drift_over_light": drift / (light.masses.sum() * 0.25),
        "light_velocity_end_m_s": float(light.velocities[:, 2].mean()),
        "heavy_velocity_end_m_s": float(heavy.velocities[:, 2].mean()),
        "iterations_median": C.median(iterations),
        "iterations_max": max(iterations),
        "ms_per_step_median": C.median(ms),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--n", type=int, default=16, help="vertices per side of each layer")
    ap.add_argument("--layers", type=int, default=3)
    ap.add_argument("--steps", type=int, default=500, help="steps of the layers over the ball")
    ap.add_argument("--tol", type=float, default=1e-6, help="the layers' tolerance (m)")
    ap.add_argument("--collision-steps", type=int, default=40)
    ap.add_argument("--collision-tol", type=float, default=1e-7, help="m")
    ap.add_argument("--max-iters", type=int, default=200)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--out", default=None)
    args = ap.parse_args()
    record = C.Record("proximal_metric", args)
    collisions, layers = [], []
    for proximal in METRICS:
        r = collision(proximal, args)
        collisions.append(r)
        print(f"collision, {proximal}: momentum off by {r['momentum_drift_over_light']:.3g} of "
              f"the light sheet's, end velocities {r['light_velocity_end_m_s']:.3f} and "
              f"{r['heavy_velocity_end_m_s']:.3f} m/s, {r['iterations_median']:.0f} iterations "
              f"median ({r['iterations_max']} at most), {r['ms_per_step_median']:.1f} ms per step",
              flush=True)
    for proximal in METRICS:
        r = C.layers_over_ball({"proximal": proximal}, args.tol, args, layers=args.layers)
        layers.append(r)
        print(f"{args.layers} layers, {proximal}: {C.layers_summary(r)}", flush=True)
    record.data["collision"] = collisions
    record.data["layers_over_ball"] = layers
    record.write(args.out)


if __name__ == "__main__":
    main()
