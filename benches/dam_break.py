"""The dam break of the 2017 paper (Table 1: 312K particles, h = 1/500, 412 ms per step on a
4-core i7-2600) at sizes this machine runs in minutes: ms per step by phase, the front against
Martin and Moyce 1952, and the trend towards the paper's size.

Scene (DESIGN.md section 7): a water column a = 0.1 m wide, 2a high and a deep against the
left wall of a tank 8a long and a deep (slip walls: planes), water (1000 kg/m^3, 1e-3 Pa s) as
``ViscoelasticFluid`` particles on a cubic lattice of spacing a / na, released at rest under
g = 9.81 m/s^2, time step ``--dt``, the Jacobi global solver (a liquid has no stiffness: its
local-global iterations are the inertial prediction with the colliders). For each ``--na``:
the particle count, the median over the steps of each phase of ``StepStats.timings`` (ms; the
paper's t_n = neighbours, t_rho = density, t_d = redistribution; viscosity and the rest), the
wall time per simulated second, the density projections per step (median, and the steps
that ran to the default cap of 50) with the largest excess density ``rho / rho0 - 1`` each
left (median and worst over the steps), and the front ``Z = (max x + S/2) / a`` at Martin
and Moyce's ``T = t sqrt(2 g / a)`` points (nearest step) with its relative error. The
per-step cost is fitted as ``c N^p`` over the sizes run and extrapolated to the paper's 312K
particles (a trend, not a measurement). The machine is shared with other builds: timings
are upper bounds.

Solvers:  ``--density-solver jacobi cg`` runs each size with each density solver in turn in
one process (``ViscoelasticFluid(density_solver=...)``), and the hydrostatic column of
tests/test_fluids.py (4 x 4 x 16 particles between two layers of ghosts with adhesion, dt =
0.01 s, 200 steps) with each: passes per step (median, max), steps at the cap, worst excess
density and ms per step.

Default:  python benches/dam_break.py                 (na = 8, 12, 16: 1K, 3.5K, 8K particles)
Run:      python benches/dam_break.py --na 6 8 10     (the committed JSON: 0.4K-2K particles)
Compare:  python benches/dam_break.py --na 6 8 10 --density-solver jacobi cg \
              --out benches/results/dam_break_density_solvers.json
Paper:    python benches/dam_break.py --na 6 8 10 --paper-steps 3 --out benches/results/dam_break_paper.json
          (and the paper's size itself, 315K particles at h = 1/500 s, for 3 steps from rest)
Peers:    python benches/dam_break.py --na 6 8 --peers --out benches/results/dam_break_peers.json
          (and pySPlisHSPlasH's DFSPH and Taichi MLS-MPM at the same sizes: particles, wall s
          per simulated s, fronts against Martin and Moyce; benches/_dfsph_dam_break.py,
          benches/_mpm.py)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn as pd  # noqa: E402

G = 9.81
MARTIN_MOYCE = [(0.832, 1.217), (1.997, 2.292), (3.345, 4.134), (5.091, 6.98)]
PAPER = {"particles": 312_000, "ms_per_step": 412.0, "machine": "Intel i7-2600, 4 cores"}
PAPER_NA = 54  # 2 x 54^3 = 314,928 particles, the paper's 312K


def dam_break(na: int, a: float, dt: float, threads: int, redistribution: float,
              density_solver: str = "jacobi"):
    s = a / na
    k = np.stack(np.meshgrid(np.arange(na), np.arange(na), np.arange(2 * na), indexing="ij"),
                 -1).reshape(-1, 3)
    x = (k + 0.5) * s
    body = pd.Particles(x, spacing=s, density=1000.0,
                        material=pd.ViscoelasticFluid(viscosity=1e-3,
                                                      redistribution=redistribution,
                                                      density_solver=density_solver))
    solver = pd.Solver(dt=dt, gravity=(0, 0, -G), global_solver="jacobi", threads=threads)
    solver.add(body)
    length, depth = 8 * a, a
    for point, normal in [((0, 0, 0), (0, 0, 1)), ((0, 0, 0), (1, 0, 0)),
                          ((length, 0, 0), (-1, 0, 0)), ((0, 0, 0), (0, 1, 0)),
                          ((0, depth, 0), (0, -1, 0))]:
        solver.add_collider(pd.Plane(point=point, normal=normal))
    return body, solver, s


def run(na: int, args, density_solver: str = "jacobi") -> dict:
    a, dt = args.a, args.dt
    body, solver, s = dam_break(na, a, dt, args.threads, args.redistribution, density_solver)
    c = np.sqrt(2 * G / a)
    phases: dict = {}
    totals, fronts, passes, errors = [], [], [], []
    k = 0
    started = time.perf_counter()
    for T, Z in MARTIN_MOYCE:
        while k < round(T / (c * dt)):
            stats = solver.step()
            k += 1
            for key, value in stats.timings.items():
                phases.setdefault(key, []).append(value)
            totals.append(stats.timings["total"])
            passes.append(stats.particles["density_passes"])
            errors.append(stats.particles["density_error"])
        front = (body.positions[:, 0].max() + 0.5 * s) / a
        fronts.append({"T": T, "Z_martin_moyce": Z, "Z": front, "error": front / Z - 1.0})
        print(f"  na={na} {density_solver}: T={T} Z={front:.3f} (Martin and Moyce {Z})",
              flush=True)
    wall = time.perf_counter() - started
    return {
        "na": na, "density_solver": density_solver, "spacing_m": s,
        "particles": body.positions.shape[0], "steps": k,
        "ms_per_step_median": C.median(totals),
        "phases_ms_median": {key: C.median(v) for key, v in phases.items()},
        "density_passes_median": C.median(passes), "density_passes_max": max(passes),
        "steps_at_the_pass_cap": int(sum(p >= 50 for p in passes)),
        "density_error_median": C.median(errors), "density_error_max": max(errors),
        "wall_seconds_per_simulated_second": wall / (k * dt),
        "fronts": fronts,
    }


def column(density_solver: str, threads: int) -> dict:
    """The hydrostatic column of tests/test_fluids.py (4 x 4 x 16 particles of spacing 1 cm
    in a container of two layers of pinned ghosts, adhesion, planes on its faces; dt = 0.01
    s, 200 steps): density passes (median, max, steps at the cap), the worst excess density
    each step left, ms per step, and the top's largest relative drift."""
    s, n, height, layers = 0.01, 4, 16, 2
    axes = [np.arange(-layers, n + layers)] * 2 + [np.arange(-layers, height)]
    k = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)
    inside = (k[:, 0] >= 0) & (k[:, 0] < n) & (k[:, 1] >= 0) & (k[:, 1] < n) & (k[:, 2] >= 0)
    body = pd.Particles((k + 0.5) * s, spacing=s, density=1000.0,
                        material=pd.ViscoelasticFluid(adhesion=True,
                                                      density_solver=density_solver))
    body.pin(np.flatnonzero(~inside))
    solver = pd.Solver(dt=0.01, gravity=(0, 0, -G), global_solver="jacobi", threads=threads)
    solver.add(body)
    for point, normal in [((0, 0, 0), (0, 0, 1)), ((0, 0, 0), (1, 0, 0)),
                          ((n * s, 0, 0), (-1, 0, 0)), ((0, 0, 0), (0, 1, 0)),
                          ((0, n * s, 0), (0, -1, 0))]:
        solver.add_collider(pd.Plane(point=point, normal=normal))
    top0 = (height - 0.5) * s
    passes, errors, totals, tops = [], [], [], []
    for _ in range(200):
        stats = solver.step()
        passes.append(stats.particles["density_passes"])
        errors.append(stats.particles["density_error"])
        totals.append(stats.timings["total"])
        tops.append(abs(body.positions[inside, 2].max() / top0 - 1.0))
    print(f"  column {density_solver}: {C.median(passes)} passes, worst excess "
          f"{max(errors):.4f}, top drift {max(tops):.4f}", flush=True)
    return {"density_solver": density_solver, "particles": int(inside.sum()),
            "density_passes_median": C.median(passes), "density_passes_max": max(passes),
            "steps_at_the_pass_cap": int(sum(p >= 50 for p in passes)),
            "density_error_median": C.median(errors), "density_error_max": max(errors),
            "ms_per_step_median": C.median(totals), "top_drift_max": max(tops)}


def paper_size(args) -> dict:
    """The paper's size itself (na = 54: 314,928 particles, spacing 1.85 mm, h = 1/500 s as
    in its Table 1) for ``--paper-steps`` steps from rest: ms per step by phase (each step),
    density passes, set-up seconds and the peak memory per particle. The first steps of the
    collapse, not the run's average the paper quotes: the projections a step needs grow as
    the column falls."""
    base = C.vm_kib("VmHWM")
    started = time.perf_counter()
    body, solver, s = dam_break(PAPER_NA, args.a, 1.0 / 500.0, args.threads,
                                args.redistribution, args.density_solver[0])
    setup = time.perf_counter() - started
    steps = []
    for _ in range(args.paper_steps):
        stats = solver.step()
        steps.append({"ms": dict(stats.timings),
                      "density_passes": stats.particles["density_passes"],
                      "density_error": stats.particles["density_error"]})
        print(f"  paper size: {stats.timings['total']:.0f} ms, "
              f"{stats.particles['density_passes']} passes", flush=True)
    n = body.positions.shape[0]
    return {"na": PAPER_NA, "particles": n, "spacing_m": s, "dt": 1.0 / 500.0,
            "setup_s": setup, "steps": steps,
            "ms_per_step_median": C.median([r["ms"]["total"] for r in steps]),
            "peak_kib_per_particle": (C.vm_kib("VmHWM") - base) / n}


def dfsph(na: int, a: float) -> dict:
    """The same dam break in pySPlisHSPlasH's DFSPH (benches/_dfsph_dam_break.py), in a
    subprocess with ``LD_PRELOAD=libGLdispatch.so.0`` (its import needs it without a
    display); its JSON, or the reason it failed."""
    import json
    import os
    import subprocess
    import tempfile

    out = Path(tempfile.mkdtemp(prefix="dfsph_")) / "run.json"
    env = {**os.environ, "LD_PRELOAD": "libGLdispatch.so.0"}
    script = Path(__file__).resolve().parent / "_dfsph_dam_break.py"
    done = subprocess.run([sys.executable, str(script), str(na), str(a), str(out)], env=env,
                          capture_output=True, text=True)
    if not out.exists():
        return {"na": na, "failed": done.stderr[-2000:] or f"exit code {done.returncode}"}
    return json.loads(out.read_text())


def mpm_water(na: int, a: float, threads: int) -> dict:
    """The same dam break in Taichi MLS-MPM with a weakly compressible liquid
    (benches/_mpm.py: speed of sound ten times the column's free-fall speed sqrt(2 g 2a), grid
    spacing twice the particles', slip walls at the tank's faces), in this process: particles,
    wall s per simulated s (after a warm-up that compiles the kernels), fronts against Martin
    and Moyce; or the reason it failed."""
    try:
        from _mpm import Mpm

        s = a / na
        k = np.stack(np.meshgrid(np.arange(na), np.arange(na), np.arange(2 * na),
                                 indexing="ij"), -1).reshape(-1, 3)
        sound = 10.0 * np.sqrt(2 * G * 2 * a)
        mpm = Mpm((k + 0.5) * s, volume=s ** 3, density=1000.0, dx=2 * s, low=(0, 0, 0),
                  high=(8 * a, a, 3 * a), material="water", sound_speed=sound,
                  threads=threads)
    except Exception as e:  # a peer that is missing or fails is recorded, not fatal
        return {"na": na, "failed": f"{type(e).__name__}: {e}"}
    mpm.warm_up()
    c = np.sqrt(2 * G / a)
    fronts, elapsed, wall = [], 0.0, 0.0
    for T, Z in MARTIN_MOYCE:
        started = time.perf_counter()
        steps = mpm.advance(T / c - elapsed)
        wall += time.perf_counter() - started
        elapsed += steps * mpm.dt
        front = (mpm.positions()[:, 0].max() + 0.5 * s) / a
        fronts.append({"T": T, "Z_martin_moyce": Z, "Z": front, "error": front / Z - 1.0})
        print(f"  MPM na={na}: T={T} Z={front:.3f} (Martin and Moyce {Z})", flush=True)
    return {"solver": "taichi MLS-MPM, weakly compressible", "na": na, "particles": mpm.n,
            "dt": mpm.dt, "sound_speed_m_s": sound, "grid_cells": list(mpm.cells),
            "wall_seconds_per_simulated_second": wall / elapsed, "fronts": fronts}


def plot(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
    mm = np.array(MARTIN_MOYCE)
    left.plot(mm[:, 0], mm[:, 1], "ks", label="Martin and Moyce 1952")
    left.fill_between(mm[:, 0], 0.9 * mm[:, 1], 1.1 * mm[:, 1], color="0.85", label="10 %")
    for r in result["runs"]:
        f = r["fronts"]
        left.plot([p["T"] for p in f], [p["Z"] for p in f], "o-",
                  label=f"peridyn {r.get('density_solver', 'jacobi')}, "
                  f"{r['particles']} particles")
    for r in result.get("peers", []):
        if "fronts" in r:
            f = r["fronts"]
            name = "MLS-MPM" if "MPM" in r.get("solver", "") else "DFSPH"
            left.plot([p["T"] for p in f], [p["Z"] for p in f], "x--",
                      label=f"{name}, {r['particles']} particles")
    left.set_xlabel("T = t sqrt(2g/a)")
    left.set_ylabel("Z = front / a")
    left.legend()
    n = np.array([r["particles"] for r in result["runs"]], dtype=float)
    ms = np.array([r["ms_per_step_median"] for r in result["runs"]])
    right.loglog(n, ms, "o", label="peridyn (median ms/step)")
    fit = result["trend"]
    grid = np.geomspace(n.min(), PAPER["particles"], 50)
    right.loglog(grid, fit["c"] * grid ** fit["p"], "--", label=f"fit c N^{fit['p']:.2f}")
    right.loglog([PAPER["particles"]], [PAPER["ms_per_step"]], "k*", markersize=12,
                 label="paper (312K, 4 cores)")
    right.set_xlabel("particles")
    right.set_ylabel("ms per step")
    right.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--na", type=int, nargs="+", default=[8, 12, 16],
                    help="particles across the column's width a")
    ap.add_argument("--a", type=float, default=0.1, help="column width (m)")
    ap.add_argument("--dt", type=float, default=0.005, help="time step (s)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--redistribution", type=float, default=0.0)
    ap.add_argument("--peers", action="store_true",
                    help="also run pySPlisHSPlasH's DFSPH (benches/_dfsph_dam_break.py) and "
                    "Taichi MLS-MPM (benches/_mpm.py) at each size")
    ap.add_argument("--paper-steps", type=int, default=0,
                    help="also run the paper's size (315K particles, h = 1/500 s) this many steps")
    ap.add_argument("--density-solver", nargs="+", default=["jacobi"],
                    choices=["jacobi", "cg"],
                    help="density solvers to run side by side (with more than one, also the "
                    "hydrostatic column)")
    ap.add_argument("--out", help="JSON path (default benches/results/dam_break.json)")
    args = ap.parse_args()
    rec = C.Record("dam_break", args)
    runs = []
    for na in args.na:
        for density_solver in args.density_solver:
            print(f"na = {na}, {density_solver}", flush=True)
            runs.append(run(na, args, density_solver))
    first = [r for r in runs if r["density_solver"] == args.density_solver[0]]
    n = np.log([r["particles"] for r in first])
    ms = np.log([r["ms_per_step_median"] for r in first])
    p, logc = np.polyfit(n, ms, 1) if len(first) > 1 else (1.0, ms[0] - n[0])
    trend = {"c": float(np.exp(logc)), "p": float(p),
             "ms_per_step_at_312K": float(np.exp(logc) * PAPER["particles"] ** p)}
    rec.data.update({"paper": PAPER, "runs": runs, "trend": trend})
    if len(args.density_solver) > 1:
        rec.data["column"] = [column(d, args.threads) for d in args.density_solver]
    if args.paper_steps:
        print(f"paper size, na = {PAPER_NA}", flush=True)
        rec.data["paper_size"] = paper_size(args)
    if args.peers:
        peers = []
        for na in args.na:
            print(f"DFSPH na = {na}", flush=True)
            peers.append(dfsph(na, args.a))
            print(f"MLS-MPM na = {na}", flush=True)
            peers.append(mpm_water(na, args.a, args.threads))
        rec.data["peers"] = peers
    rec.note(f"fitted ms/step = {trend['c']:.3g} N^{trend['p']:.2f}: "
             f"{trend['ms_per_step_at_312K']:.0f} ms at 312K (paper 412 ms on 4 cores)")
    path = rec.write(args.out)
    plot(rec.data, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
