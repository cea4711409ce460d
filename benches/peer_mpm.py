"""Peer comparison, side by side in one process: peridyn's elastic particles against MLS-MPM
(Hu et al. 2018) written in Taichi on the CPU (``ti.init(arch=ti.x64)``).

The scene of issue 38: an elastic cube, 0.1 m on a side, Young's modulus E = 2e5 Pa, Poisson
ratio 0.25, density 1000 kg/m^3, its bottom 0.15 m above a frictionless floor (z = 0),
dropped from rest under gravity -9.81 m/s^2 along z and simulated for ``--duration`` s. Both
solvers get the same particles: a regular lattice of ``--n`` x ``--n`` x ``--n`` points, spacing
0.1 / n m, volume spacing^3 and mass density x spacing^3 each.

- peridyn: ``Particles(..., material=Elastic.from_young(E, nu))``, implicit Euler, time step
  ``--dt`` (default 1/240 s), its default global solver and tolerance; a Plane collider.
- MLS-MPM: explicit, fixed-corotated hyperelasticity with the Lame parameters of (E, nu), quadratic
  B-spline weights, APIC transfer, a grid of spacing 2 x the particle spacing (two particles per
  cell per axis, as MPM practice has it) over a box around the motion, a separating slip floor on
  the grid; its time step from the CFL and elastic wave speed, ``dt = cfl dx / sqrt((lam + 2 mu) /
  rho)`` with ``--cfl`` 0.3.

Reported per solver: wall seconds per simulated second (median of ``--repeats`` runs after one
warm-up run that also compiles Taichi's kernels), the time step and steps taken, the cube's final
centre height and height (m, at rest both should hold it at about 0.05 m + its sag: E is soft, so
the cube sags under its weight by about ``rho g L^2 / (2 E)`` = 0.25 mm), the peak memory of the
process. Both run in this process with the same threads (``--threads``, default 2: Taichi's
``cpu_max_num_threads`` and peridyn's ``threads``).

Default:  python benches/peer_mpm.py            (n = 20, 8,000 particles, 1 s)
Install:  pip install taichi
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn  # noqa: E402

GRAVITY = 9.81


def lattice(n: int, side: float, lift: float) -> np.ndarray:
    """An n^3 lattice filling a cube of ``side`` (m), cell-centred, its bottom at ``lift`` (m)."""
    h = side / n
    axis = (np.arange(n) + 0.5) * h
    x, y, z = np.meshgrid(axis - side / 2, axis - side / 2, axis + lift, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def heights(x: np.ndarray) -> dict:
    return {"centre_z": float(x[:, 2].mean()), "height": float(x[:, 2].max() - x[:, 2].min()),
            "lowest_z": float(x[:, 2].min())}


class PeridynRun:
    name = "peridyn"

    def __init__(self, args):
        self.args = args

    def run(self) -> dict:
        a = self.args
        x = lattice(a.n, a.side, a.lift)
        spacing = a.side / a.n
        cube = peridyn.Particles(x, spacing=spacing, density=a.density,
                                 material=peridyn.Elastic.from_young(a.young, a.nu))
        solver = peridyn.Solver(dt=a.dt, gravity=(0.0, 0.0, -GRAVITY), threads=a.threads)
        solver.add(cube)
        solver.add_collider(peridyn.Plane())
        steps = int(round(a.duration / a.dt))
        iterations = []
        t = time.perf_counter()
        for _ in range(steps):
            iterations.append(solver.step().iterations)
        wall = time.perf_counter() - t
        return {"dt": a.dt, "steps": steps, "wall_s": wall, "iterations_median": float(np.median(iterations)),
                **heights(np.asarray(cube.positions))}


class TaichiMpmRun:
    """MLS-MPM (Hu et al. 2018, eq. 16-18 with APIC) in Taichi, fixed-corotated elasticity
    (benches/_mpm.py)."""

    name = "taichi MLS-MPM"

    def __init__(self, args):
        from _mpm import Mpm

        a = self.args = args
        spacing = a.side / a.n
        # The grid covers the cube's fall and its spread at the floor (a slip floor at z = 0).
        self.mpm = Mpm(lattice(a.n, a.side, a.lift), volume=spacing ** 3, density=a.density,
                       dx=2 * spacing, low=(-a.side, -a.side, 0.0),
                       high=(a.side, a.side, a.lift + 1.5 * a.side), material="elastic",
                       young=a.young, nu=a.nu, cfl=a.cfl, threads=a.threads)

    def run(self) -> dict:
        mpm = self.mpm
        mpm.reset()
        t = time.perf_counter()
        steps = mpm.advance(self.args.duration)
        wall = time.perf_counter() - t
        return {"dt": mpm.dt, "steps": steps, "wall_s": wall, "grid_cells": list(mpm.cells),
                **heights(mpm.positions())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=20, help="particles per cube edge")
    ap.add_argument("--side", type=float, default=0.1, help="cube edge (m)")
    ap.add_argument("--lift", type=float, default=0.15, help="height of the cube's bottom (m)")
    ap.add_argument("--young", type=float, default=2e5, help="Young's modulus (Pa)")
    ap.add_argument("--nu", type=float, default=0.25, help="Poisson ratio")
    ap.add_argument("--density", type=float, default=1000.0, help="kg/m^3")
    ap.add_argument("--duration", type=float, default=1.0, help="simulated time (s)")
    ap.add_argument("--dt", type=float, default=1 / 240, help="peridyn's time step (s)")
    ap.add_argument("--cfl", type=float, default=0.3, help="MPM's CFL number")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3, help="timed runs per solver (median)")
    ap.add_argument("--only", choices=["peridyn", "mpm"], help="run one solver only")
    ap.add_argument("--out", help="JSON path (default benches/results/peer_mpm.json)")
    args = ap.parse_args()

    rec = C.Record("peer_mpm", args)
    makers = {"peridyn": PeridynRun, "mpm": TaichiMpmRun}
    results = {}
    for key, make in makers.items():
        if args.only and key != args.only:
            continue
        try:
            runner = make(args)
            runner.run()  # warm-up: JIT compilation, first touch
            runs = [runner.run() for _ in range(args.repeats)]
        except Exception as e:  # a peer that is missing or fails is recorded, not fatal
            traceback.print_exc()
            results[key] = {"error": f"{type(e).__name__}: {e}"}
            continue
        walls = [r["wall_s"] for r in runs]
        summary = {**runs[-1], "name": runner.name, "wall_s_runs": walls,
                   "wall_seconds_per_simulated_second": C.median(walls) / args.duration}
        results[key] = summary
        print(f"{runner.name}: {summary['wall_seconds_per_simulated_second']:.3f} wall s per "
              f"simulated s (dt {summary['dt']:.3g} s, {summary['steps']} steps), centre at "
              f"{summary['centre_z']:.4f} m, height {summary['height']:.4f} m", flush=True)
    rec.data["particles"] = args.n ** 3
    rec.data["results"] = results
    rec.data["peak_rss_kib"] = C.vm_kib("VmHWM")
    rec.write(args.out)


if __name__ == "__main__":
    main()
