"""Water poured on a cloth (He et al. 2017, Fig. 18, at a small size): milliseconds per step
by phase, medians over the steps, and the share of the particle-membrane coupling.

Usage: python benches/fluid_on_cloth.py [--cloth 41] [--column 8 8 16] [--steps 60]

Writes benches/results/fluid_on_cloth.json. Timings on a shared machine are upper bounds (see
the recorded load average).
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


def run(cloth_n: int, column, steps: int) -> dict:
    size, thickness, s = 0.4, 1e-3, 0.01
    V, T = pd.grid(cloth_n, cloth_n, (size, size))
    V = V - np.array([size / 2, size / 2, 0.0])
    sheet = pd.Membrane(V, T, thickness=thickness, density=200.0,
                        material=pd.StretchA3.from_young(2e6), bending=1e-6)
    sheet.pin(np.flatnonzero((np.abs(np.abs(V[:, :2]) - size / 2) < 1e-9).any(axis=1)))
    axes = [np.arange(k) * s for k in column]
    X = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    X = X - np.array([(column[0] - 1) * s / 2, (column[1] - 1) * s / 2, -(s / 2 + 0.01)])
    water = pd.Particles(X, spacing=s, density=1000.0,
                         material=pd.ViscoelasticFluid(viscosity=1e-3))
    solver = pd.Solver(dt=0.005, gravity=(0, 0, -9.81), global_solver="jacobi")
    solver.add(sheet)
    solver.add(water)
    phases = {}
    iterations = []
    for _ in range(steps):
        stats = solver.step()
        iterations.append(stats.iterations)
        for k, v in stats.timings.items():
            phases.setdefault(k, []).append(v)
    medians = {k: float(np.median(v)) for k, v in phases.items()}
    return {
        "cloth_vertices": sheet.num_vertices,
        "particles": water.num_particles,
        "steps": steps,
        "median_ms_per_step": medians,
        "coupling_share": medians["coupling"] / medians["total"],
        "median_iterations": float(np.median(iterations)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cloth", type=int, default=41)
    parser.add_argument("--column", type=int, nargs=3, default=[8, 8, 16])
    parser.add_argument("--steps", type=int, default=60)
    args = parser.parse_args()
    result = run(args.cloth, args.column, args.steps)
    out = {"command": C.command_line(), "machine": C.machine(), "results": [result]}
    path = C.RESULTS / "fluid_on_cloth.json"
    path.write_text(json.dumps(C._jsonable(out), indent=1))
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()
