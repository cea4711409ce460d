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


def lame(E: float, nu: float) -> tuple:
    return E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))


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
    """MLS-MPM (Hu et al. 2018, eq. 16-18 with APIC) in Taichi, fixed-corotated elasticity."""

    name = "taichi MLS-MPM"

    def __init__(self, args):
        import taichi as ti

        self.ti = ti
        self.args = args
        ti.init(arch=ti.x64, cpu_max_num_threads=args.threads, default_fp=ti.f32,
                offline_cache=True, log_level=ti.WARN)
        a = args
        spacing = a.side / a.n
        self.dx = 2 * spacing
        mu, lam = lame(a.young, a.nu)
        self.dt = a.cfl * self.dx / np.sqrt((lam + 2 * mu) / a.density)
        # The grid covers the cube's fall and its spread at the floor, with 3 cells of padding.
        self.origin = np.array([-a.side, -a.side, 0.0]) - 3 * self.dx
        extent = np.array([2 * a.side, 2 * a.side, a.lift + 1.5 * a.side]) + 6 * self.dx
        self.cells = tuple(int(np.ceil(e / self.dx)) for e in extent)
        n_particles = a.n ** 3
        vol = spacing ** 3
        self.x = ti.Vector.field(3, ti.f32, n_particles)
        self.v = ti.Vector.field(3, ti.f32, n_particles)
        self.C = ti.Matrix.field(3, 3, ti.f32, n_particles)
        self.F = ti.Matrix.field(3, 3, ti.f32, n_particles)
        self.grid_v = ti.Vector.field(3, ti.f32, self.cells)
        self.grid_m = ti.field(ti.f32, self.cells)
        inv_dx, dx, dt = 1.0 / self.dx, self.dx, self.dt
        p_mass, p_vol = a.density * vol, vol
        floor = int(round(-self.origin[2] / self.dx))  # the grid layer at z = 0
        g = GRAVITY
        x, v, C_, F = self.x, self.v, self.C, self.F
        grid_v, grid_m = self.grid_v, self.grid_m
        origin = ti.Vector(list(self.origin.astype(np.float32)))

        @ti.kernel
        def substep():
            for I in ti.grouped(grid_m):
                grid_v[I] = ti.Vector.zero(ti.f32, 3)
                grid_m[I] = 0.0
            for p in x:
                xp = (x[p] - origin) * inv_dx
                base = int(xp - 0.5)
                fx = xp - base
                w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
                F[p] = (ti.Matrix.identity(ti.f32, 3) + dt * C_[p]) @ F[p]
                R, _ = ti.polar_decompose(F[p])
                J = F[p].determinant()
                stress = 2.0 * mu * (F[p] - R) @ F[p].transpose() + ti.Matrix.identity(ti.f32, 3) * lam * J * (J - 1.0)
                stress = -dt * p_vol * 4.0 * inv_dx * inv_dx * stress
                affine = stress + p_mass * C_[p]
                for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
                    offset = ti.Vector([i, j, k])
                    dpos = (offset.cast(ti.f32) - fx) * dx
                    weight = w[i][0] * w[j][1] * w[k][2]
                    grid_v[base + offset] += weight * (p_mass * v[p] + affine @ dpos)
                    grid_m[base + offset] += weight * p_mass
            for I in ti.grouped(grid_m):
                if grid_m[I] > 0:
                    grid_v[I] = grid_v[I] / grid_m[I]
                    grid_v[I][2] -= dt * g
                    # A separating slip floor at z = 0; the sides of the box stop the grid.
                    if I[2] < floor + 1 and grid_v[I][2] < 0:
                        grid_v[I][2] = 0.0
                    for d in ti.static(range(3)):
                        if I[d] < 3 and grid_v[I][d] < 0:
                            grid_v[I][d] = 0.0
                        if I[d] > grid_m.shape[d] - 4 and grid_v[I][d] > 0:
                            grid_v[I][d] = 0.0
            for p in x:
                xp = (x[p] - origin) * inv_dx
                base = int(xp - 0.5)
                fx = xp - base
                w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
                new_v = ti.Vector.zero(ti.f32, 3)
                new_C = ti.Matrix.zero(ti.f32, 3, 3)
                for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
                    offset = ti.Vector([i, j, k])
                    dpos = offset.cast(ti.f32) - fx
                    weight = w[i][0] * w[j][1] * w[k][2]
                    gv = grid_v[base + offset]
                    new_v += weight * gv
                    new_C += 4.0 * inv_dx * weight * gv.outer_product(dpos)
                v[p], C_[p] = new_v, new_C
                x[p] += dt * new_v

        self.substep = substep

    def run(self) -> dict:
        a, ti = self.args, self.ti
        self.x.from_numpy(lattice(a.n, a.side, a.lift).astype(np.float32))
        self.v.fill(0.0)
        self.C.fill(0.0)
        self.F.from_numpy(np.tile(np.eye(3, dtype=np.float32), (a.n ** 3, 1, 1)))
        steps = int(np.ceil(a.duration / self.dt))
        t = time.perf_counter()
        for _ in range(steps):
            self.substep()
        ti.sync()
        wall = time.perf_counter() - t
        return {"dt": self.dt, "steps": steps, "wall_s": wall, "grid_cells": list(self.cells),
                **heights(self.x.to_numpy().astype(np.float64))}


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
