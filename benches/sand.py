"""Dry sand: the axisymmetric column collapse (R = 0.05 m, a = H / R = 1, friction angle 30
degrees) in peridyn at three sizes, with a peer (Taichi MLS-MPM with Drucker-Prager sand,
benches/_mpm.py) at equal particle count, in one run.

Scene: a cylinder of radius R and height a R sampled on a cubic lattice of spacing
``R / n`` (``--sizes`` lists n), density 1600 kg/m^3, standing on a plane at z = 0 with
Coulomb friction 0.3, released under gravity 9.81 m/s^2 and simulated for ``--duration`` s.
The runout ``dR / R`` (98th percentile of the distance from the axis, as in
tests/test_granular.py) against Lube et al. 2004 (``dR / R = 1.24 a`` for a < 1.7).

peridyn: ``Granular(friction_angle=30)`` with its defaults, ``dt`` 1/500 s (the paper's),
Jacobi + Chebyshev, ``--iters`` iterations a step. Per size: milliseconds per step by phase
(the columns of He et al. 2017, Table 1: ``neighbours`` t_n, ``density`` t_d, ``plasticity``
t_p (the return and the rest rebuild), ``elasticity`` = the global solve), medians over the
steps; the peak resident memory per particle (the worker process's VmHWM less that of a
process that only imported peridyn and built nothing). The paper's size (1.18M particles) is
shown by the trend of time and memory per particle over the sizes (a least-squares power
law, extrapolated).

MPM: the same particles (one per lattice site, volume spacing^3), grid spacing twice the
particle spacing, E = ``--mpm-young`` Pa, nu 0.3, the outer (compression) Drucker-Prager cone
at 30 degrees, explicit steps at CFL 0.4: wall seconds per simulated second (after a warm-up
that compiles the kernels, which is not counted) and the runout.

Every solver runs in its own worker process (for its memory figure), one after the other
(never two at once), with ``--threads`` threads.

    python benches/sand.py                      # sizes 5 8 12, MPM at 8 (about 10 min)
    python benches/sand.py --sizes 5 --mpm 5    # a quick look
    python benches/sand.py --sizes 5 8 12 20 --mpm --paper-steps 3   # and 1.17M particles
    python benches/sand.py --sizes 5 --mpm --stream   # and the stream of Fig. 15, small

``--paper-steps K`` also runs the paper's size itself (72 spacings per radius, 1,169,352
particles) for K steps in its own worker: ms per step by phase, set-up seconds and the
peak memory per particle, measured rather than extrapolated.

Writes benches/results/sand.json and sand.png. Timings on a shared machine are upper bounds
(the record carries the load average).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

RADIUS, ASPECT, ANGLE, DENSITY, FLOOR = 0.05, 1.0, 30.0, 1600.0, 0.3
PAPER_PARTICLES = 1_177_000
# Spacings per radius that give about the paper's particle count (1,169,352 particles).
PAPER_N = 72


def column(n: int) -> tuple:
    """The column's particles ((N, 3) m) at ``n`` spacings per radius, and the spacing (m)."""
    s = RADIUS / n
    g = np.arange(-n, n + 1) * s
    layers = int(round(ASPECT * RADIUS / s))
    x, y, z = np.meshgrid(g, g, (np.arange(layers) + 0.5) * s, indexing="ij")
    p = np.stack([x, y, z], -1).reshape(-1, 3)
    return p[np.hypot(p[:, 0], p[:, 1]) <= RADIUS + 1e-9], s


def runout(p: np.ndarray) -> float:
    """``dR / R`` of the deposit (the 98th percentile of the distances from the axis)."""
    return float((np.percentile(np.hypot(p[:, 0], p[:, 1]), 98) - RADIUS) / RADIUS)


def peridyn_worker(a) -> dict:
    import peridyn as pd

    base = C.vm_kib("VmHWM")
    x, s = column(a.n)
    t = time.perf_counter()
    body = pd.Particles(x, spacing=s, density=DENSITY,
                        material=pd.Granular(friction_angle=ANGLE))
    solver = pd.Solver(dt=a.dt, max_iters=a.iters, tol=0.0, threads=a.threads)
    solver.add_collider(pd.Plane(friction=FLOOR))
    solver.add(body)
    setup = time.perf_counter() - t
    rows = []
    t = time.perf_counter()
    for _ in range(int(round(a.duration / a.dt))):
        rows.append(solver.step().timings)
    wall = time.perf_counter() - t
    phases = {k: C.median([r[k] for r in rows]) for k in ("neighbours", "density", "plasticity",
                                                          "global", "total")}
    phases["elasticity"] = phases.pop("global")
    bonds = body.rest_bonds["offsets"][-1]
    return {"particles": len(x), "spacing_m": s, "dt": a.dt, "steps": len(rows), "wall_s": wall,
            "setup_s": setup, "bonds_per_particle": float(bonds) / len(x),
            "wall_seconds_per_simulated_second": wall / a.duration, "median_ms": phases,
            "first_step_ms": {k: rows[0][k] for k in ("neighbours", "density", "plasticity",
                                                      "global", "total")},
            "runout": runout(body.positions), "peak_kib_over_import": C.vm_kib("VmHWM") - base}


def stream_worker(a) -> dict:
    """Fig. 15 at a small size: a stream of sand (3 x 3 x 16 grains of 1 cm, the column a
    third of a spacing off the axis) released 4 cm above a sphere (radius 3 cm, friction
    0.3) standing on the ground (friction 0.3), stepped as the column (``--dt``,
    ``--iters``) for 0.6 s. Records every 0.1 s the shares of the grains on top of the
    sphere (within its radius of the axis, above its centre) and on the ground (below 1.5
    spacings), the median and 98th percentile distance from the axis, and the closest any
    grain came to each collider over the run, in units of its margin (half a spacing)."""
    import peridyn as pd

    s = 0.01
    g = (np.arange(3) - 1) * s
    centre, radius = np.array([0.0, 0.0, 0.03]), 0.03
    x = np.stack(np.meshgrid(g, g, centre[2] + radius + 0.04 + np.arange(16) * s,
                             indexing="ij"), -1).reshape(-1, 3) + [s / 3, 0.0, 0.0]
    body = pd.Particles(x, spacing=s, density=DENSITY, material=pd.Granular(friction_angle=ANGLE))
    solver = pd.Solver(dt=a.dt, max_iters=a.iters, tol=0.0, threads=a.threads)
    solver.add_collider(pd.Plane(friction=FLOOR))
    solver.add_collider(pd.Sphere(center=tuple(centre), radius=radius, friction=FLOOR))
    solver.add(body)
    closest = {"plane": np.inf, "sphere": np.inf}
    frames, steps = [], int(round(0.6 / a.dt))
    t = time.perf_counter()
    for k in range(steps):
        solver.step()
        y = body.positions
        closest["plane"] = min(closest["plane"], y[:, 2].min() / (s / 2))
        gap = np.linalg.norm(y - centre, axis=1) - radius
        closest["sphere"] = min(closest["sphere"], gap.min() / (s / 2))
        if (k + 1) % int(round(0.1 / a.dt)) == 0:
            r = np.hypot(y[:, 0], y[:, 1])
            frames.append({"t": (k + 1) * a.dt,
                           "on_sphere": float(np.mean((r < radius) & (y[:, 2] > centre[2]))),
                           "on_ground": float(np.mean(y[:, 2] < 1.5 * s)),
                           "r_median_m": float(np.median(r)),
                           "r_98_m": float(np.percentile(r, 98))})
    return {"particles": len(x), "wall_s": time.perf_counter() - t, "frames": frames,
            "closest_over_margin": {k: float(v) for k, v in closest.items()}}


def mpm_worker(a) -> dict:
    from _mpm import sand_column

    base = C.vm_kib("VmHWM")
    x, s = column(a.n)
    mpm = sand_column(x, spacing=s, radius=RADIUS, height=ASPECT * RADIUS, density=DENSITY,
                      young=a.mpm_young, friction_angle=ANGLE, floor_friction=FLOOR,
                      threads=a.threads)
    steps, wall = mpm.timed(a.duration)
    return {"particles": len(x), "spacing_m": s, "dt": mpm.dt, "steps": steps, "wall_s": wall,
            "wall_seconds_per_simulated_second": wall / a.duration,
            "grid_cells": list(mpm.cells), "runout": runout(mpm.positions()),
            "peak_kib_over_import": C.vm_kib("VmHWM") - base}


def import_baseline() -> int:
    import peridyn  # noqa: F401

    return C.vm_kib("VmHWM")


def in_worker(kind: str, n: int, args) -> dict:
    argv = [sys.executable, __file__, "--worker", kind, "--n", str(n), "--dt", str(args.dt),
            "--iters", str(args.iters), "--duration", str(args.duration),
            "--threads", str(args.threads), "--mpm-young", str(args.mpm_young)]
    done = subprocess.run(argv, capture_output=True, text=True)
    if done.returncode != 0:
        return {"error": done.stderr[-2000:]}
    return json.loads(done.stdout.strip().splitlines()[-1])


def power_law(sizes, values) -> tuple:
    """``values ~ c sizes^p`` by least squares in logs: (c, p)."""
    p, logc = np.polyfit(np.log(sizes), np.log(values), 1)
    return float(np.exp(logc)), float(p)


def plot(results: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [r for r in results["peridyn"] if "error" not in r]
    n = np.array([r["particles"] for r in runs])
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.8))
    for key in ("neighbours", "density", "plasticity", "elasticity", "total"):
        ax[0].loglog(n, [r["median_ms"][key] for r in runs], "o-", label=key)
    ax[0].set_xlabel("particles")
    ax[0].set_ylabel("ms per step (median)")
    ax[0].legend(fontsize=8)
    ax[0].set_title("peridyn by phase (Table 1's columns)")
    ax[1].loglog(n, [r["peak_kib_over_import"] * 1024 / r["particles"] for r in runs], "o-")
    ax[1].set_xlabel("particles")
    ax[1].set_ylabel("peak bytes per particle")
    ax[1].set_title("memory")
    ax[2].axhline(1.24 * ASPECT, color="k", ls="--", label="Lube et al. 2004")
    ax[2].plot(n, [r["runout"] for r in runs], "o-", label="peridyn")
    mpm = [r for r in results["mpm"] if "error" not in r]
    if mpm:
        ax[2].plot([r["particles"] for r in mpm], [r["runout"] for r in mpm], "s", label="MLS-MPM")
    ax[2].set_xscale("log")
    ax[2].set_xlabel("particles")
    ax[2].set_ylabel("dR / R")
    ax[2].legend(fontsize=8)
    ax[2].set_title(f"runout, a = {ASPECT:g}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[5, 8, 12],
                    help="particle spacings per column radius")
    ap.add_argument("--mpm", type=int, nargs="*", default=[8], help="sizes the peer runs at")
    ap.add_argument("--duration", type=float, default=0.6, help="simulated time (s)")
    ap.add_argument("--dt", type=float, default=1 / 500, help="peridyn's time step (s)")
    ap.add_argument("--iters", type=int, default=10, help="peridyn's iterations a step")
    ap.add_argument("--mpm-young", type=float, default=3.5e5, help="MPM's Young's modulus (Pa)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--paper-steps", type=int, default=0,
                    help="also run the paper's size (1.17M particles) for this many steps")
    ap.add_argument("--stream", action="store_true",
                    help="also run the stream of Fig. 15 at a small size (stream_worker)")
    ap.add_argument("--worker", choices=["peridyn", "mpm", "baseline", "stream"],
                    help=argparse.SUPPRESS)
    ap.add_argument("--n", type=int, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        work = {"peridyn": peridyn_worker, "mpm": mpm_worker, "stream": stream_worker,
                "baseline": lambda a: {"kib": import_baseline()}}[args.worker]
        print(json.dumps(work(args)))
        return

    rec = C.Record("sand", args)
    results = {"peridyn": [], "mpm": []}
    for n in args.sizes:
        r = in_worker("peridyn", n, args)
        results["peridyn"].append(r)
        print("peridyn", n, json.dumps(r)[:400], flush=True)
    if args.paper_steps:
        paper = argparse.Namespace(**{**vars(args), "duration": args.paper_steps * args.dt})
        results["paper_size"] = in_worker("peridyn", PAPER_N, paper)
        print("paper size", json.dumps(results["paper_size"])[:600], flush=True)
    if args.stream:
        results["stream"] = in_worker("stream", 0, args)
        print("stream", json.dumps(results["stream"])[:600], flush=True)
    for n in args.mpm:
        r = in_worker("mpm", n, args)
        results["mpm"].append(r)
        print("mpm", n, json.dumps(r)[:400], flush=True)
    runs = [r for r in results["peridyn"] if "error" not in r]
    if len(runs) >= 2:
        n = np.array([r["particles"] for r in runs], dtype=float)
        trend = {}
        for name, values in (("ms_per_step", [r["median_ms"]["total"] for r in runs]),
                             ("peak_kib", [r["peak_kib_over_import"] for r in runs])):
            c, p = power_law(n, values)
            trend[name] = {"coefficient": c, "exponent": p,
                           "at_paper_size": c * PAPER_PARTICLES ** p}
        trend["paper_ms_per_step"] = 1081.7
        trend["paper_particles"] = PAPER_PARTICLES
        results["trend"] = trend
    results["lube_runout"] = 1.24 * ASPECT
    rec.data["results"] = results
    rec.write()
    plot(results, C.RESULTS / "sand.png")


if __name__ == "__main__":
    main()
