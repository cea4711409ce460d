"""Milliseconds per step by phase (the columns of He et al. 2017, Table 1) for a plastic block
squashed on a plane, beside the same block elastic, in one process.

A cube of n^3 particles (spacing 1 cm, E 2e5 Pa, nu 0.3, cohesion 500 Pa, friction angle 0)
dropped from 5 cm onto a plane at h = 1/60 s, Jacobi + Chebyshev, 30 iterations a step; the
median over the steps after the first contact of: the global iterations, the plastic return
with the rest rebuild ('plasticity', t_p), the neighbour search on deformed positions
('neighbours', t_n) and the whole step, and the mean neighbour count at the end.

    python benches/plastic_phases.py [--n 20] [--steps 40]

Writes benches/results/plastic_phases.json. Timings on a shared machine are upper bounds (the
record carries the load average).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn as pd  # noqa: E402


def run(n: int, steps: int, plastic: bool) -> dict:
    s = 0.01
    x = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3) * s
    x[:, 2] += 0.05 + 0.5 * s
    law = pd.DruckerPrager(friction_angle=0.0, cohesion=500.0) if plastic else None
    body = pd.Particles(
        x, spacing=s, density=1000.0, material=pd.Elastic.from_young(2e5, 0.3), plasticity=law
    )
    solver = pd.Solver(dt=1 / 60, max_iters=30, tol=0.0)
    solver.add(body)
    solver.add_collider(pd.Plane())
    rows = []
    for _ in range(steps):
        rows.append(solver.step().timings)
    late = rows[steps // 2 :]
    offsets, _ = body.neighborhood()
    return {
        "particles": int(n**3),
        "plastic": plastic,
        "median_ms": {k: C.median([r[k] for r in late]) for k in rows[0]},
        "mean_neighbours": float(np.diff(offsets).mean()),
        "height_m": float(body.positions[:, 2].max()),
    }


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=20)
    ap.add_argument("--steps", type=int, default=40)
    args = ap.parse_args()
    results = [run(args.n, args.steps, p) for p in (False, True)]
    out = {"command": C.command_line(), "machine": C.machine(), "results": results}
    path = C.RESULTS / "plastic_phases.json"
    path.write_text(json.dumps(C._jsonable(out), indent=1))
    for r in results:
        m = r["median_ms"]
        print(
            f"{'plastic' if r['plastic'] else 'elastic'} {r['particles']}: total {m['total']:.1f} ms, "
            f"global {m['global']:.1f}, plasticity {m['plasticity']:.1f}, neighbours "
            f"{m['neighbours']:.1f}; {r['mean_neighbours']:.1f} neighbours, top at {r['height_m']:.3f} m"
        )


if __name__ == "__main__":
    main()
