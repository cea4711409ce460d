"""Speed of elastic particle bodies (issue 38, Benchmarks): ms per step by phase at the issue's
size, the cost's growth with the particle count, and memory per particle.

Scene: a cube of n^3 particles (spacing 0.1 / 29 m, so 25K particles at n = 29), E 2e5 Pa,
nu 0.25, density 1000 kg/m^3, dropped from 0.05 m onto a frictionless Plane under gravity at
h = 1/30 s in f32 (``--precision``) with the default global solver (chebyshev) and tolerance,
``--steps`` steps (the drop, the impact and the rebound). Reported per size: median ms per step and per phase
(StepStats.particles: kernel, residual, solve, line search, projection), the median CPU time per
step of the process (all threads: on a shared machine the wall time is an upper bound, the CPU
time what the step itself cost), median iterations (and each step's count) and
kernel passes per step, the cost of one iteration (wall and CPU ms: each summed over the
steps and divided by their iterations summed), whether every step converged, the body's build time, and the process's
peak resident memory growth over the build and run divided by the particle count (KiB).

Scaling: the same scene at each ``--sizes`` (n per side), each in a fresh process (so that peak
memory is the size's own), in ascending order, stopping once a size's run took more than
``--budget`` s: the ms per step per particle should stay flat (linear cost).

Default:  python benches/particle_speed.py
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

PHASES = ["kernel_ms", "residual_ms", "solve_ms", "line_search_ms", "project_ms"]


def cube(n: int, side: float, lift: float) -> np.ndarray:
    h = side / n
    axis = (np.arange(n) + 0.5) * h
    x, y, z = np.meshgrid(axis, axis, axis + lift, indexing="ij")
    return np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)


def one_size(args) -> dict:
    """Runs one size in this process and returns its figures."""
    import peridyn

    rss0 = C.vm_kib("VmHWM")
    x = cube(args.n, args.side, args.lift)
    t = time.perf_counter()
    body = peridyn.Particles(x, spacing=args.side / args.n, density=1000.0,
                             material=peridyn.Elastic.from_young(2e5, 0.25))
    solver = peridyn.Solver(dt=args.dt, gravity=(0, 0, -9.81), precision=args.precision,
                            threads=args.threads, chebyshev_rho=args.chebyshev_rho)
    solver.add(body)
    solver.add_collider(peridyn.Plane())
    first = solver.step()  # builds the rest data and working set
    build_s = time.perf_counter() - t
    rows = []
    for _ in range(args.steps):
        cpu = time.process_time()
        s = solver.step()
        rows.append({"total_ms": s.timings["total"], "iterations": s.iterations,
                     "cpu_ms": 1e3 * (time.process_time() - cpu),
                     "converged": s.converged, **s.particles})
    peak = C.vm_kib("VmHWM")
    med = lambda k: float(np.median([r[k] for r in rows]))  # noqa: E731
    total = lambda k: float(sum(r[k] for r in rows))  # noqa: E731
    iterations = total("iterations")
    return {
        "n": args.n, "particles": len(x), "build_and_first_step_s": build_s,
        "first_step_ms": first.timings["total"],
        "ms_per_step": med("total_ms"), "cpu_ms_per_step": med("cpu_ms"),
        "iterations_median": med("iterations"),
        "iterations_per_step": [r["iterations"] for r in rows],
        "ms_each_step": [r["total_ms"] for r in rows],
        "cpu_ms_each_step": [r["cpu_ms"] for r in rows],
        "factorizations_per_step": [r.get("factorizations", 0) for r in rows],
        "two_level_ms_each_step": [r.get("two_level_ms", 0.0) for r in rows],
        "evaluations_median": med("evaluations"),
        # The cost of one iteration: the steps' times summed over their iterations summed.
        "ms_per_iteration": total("total_ms") / iterations,
        "cpu_ms_per_iteration": total("cpu_ms") / iterations,
        "cpu_ns_per_iteration_per_particle": 1e6 * total("cpu_ms") / iterations / len(x),
        "all_converged": all(r["converged"] for r in rows),
        "phases_ms_median": {k: med(k) for k in PHASES},
        "us_per_step_per_particle": 1e3 * med("total_ms") / len(x),
        "peak_rss_growth_kib_per_particle": (peak - rss0) / len(x),
        "lowest_z_end": float(np.asarray(body.positions)[:, 2].min()),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 15, 20, 29, 40, 50, 63],
                    help="particles per side of each run (29: 24,389, the issue's 25K)")
    ap.add_argument("--side", type=float, default=0.1, help="cube side (m)")
    ap.add_argument("--lift", type=float, default=0.05, help="drop height of the bottom (m)")
    ap.add_argument("--dt", type=float, default=1 / 30)
    ap.add_argument("--steps", type=int, default=10, help="timed steps per size")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--precision", choices=["f32", "f64"], default="f32")
    ap.add_argument("--chebyshev-rho", type=float, default=None,
                    help="the particles' Chebyshev rho (default: the solver's, 0.99)")
    ap.add_argument("--budget", type=float, default=120.0,
                    help="stop growing once a size took longer (s)")
    ap.add_argument("--n", type=int, help=argparse.SUPPRESS)  # one size, in a child process
    ap.add_argument("--out", help="JSON path (default benches/results/particle_speed.json); "
                    "the plot goes beside it, with the suffix .png")
    args = ap.parse_args()

    if args.n is not None:
        print(json.dumps(one_size(args)))
        return
    rec = C.Record("particle_speed", args)
    rows = []
    for n in sorted(args.sizes):
        argv = [sys.executable, __file__, "--n", str(n), "--side", str(args.side),
                "--lift", str(args.lift), "--dt", str(args.dt), "--steps", str(args.steps),
                "--threads", str(args.threads), "--precision", args.precision]
        if args.chebyshev_rho is not None:
            argv += ["--chebyshev-rho", str(args.chebyshev_rho)]
        t = time.perf_counter()
        out = subprocess.run(argv, capture_output=True, text=True)
        took = time.perf_counter() - t
        if out.returncode != 0:
            rec.note(f"n = {n} failed: {out.stderr.strip()[-500:]}")
            break
        row = json.loads(out.stdout.strip().splitlines()[-1])
        row["process_s"] = took
        rows.append(row)
        p = row["phases_ms_median"]
        print(f"{row['particles']:>8} particles: {row['ms_per_step']:8.1f} ms/step "
              f"(CPU {row['cpu_ms_per_step']:.1f} ms, all threads; "
              f"{row['us_per_step_per_particle']:.2f} us/particle), {row['iterations_median']:.0f} "
              f"iterations (median; per iteration {row['ms_per_iteration']:.2f} ms, CPU "
              f"{row['cpu_ms_per_iteration']:.2f} ms, "
              f"{row['cpu_ns_per_iteration_per_particle']:.0f} ns/particle), "
              f"{row['evaluations_median']:.0f} kernel passes, converged "
              f"{row['all_converged']}; " + ", ".join(f"{k} {v:.1f}" for k, v in p.items())
              + f"; {row['peak_rss_growth_kib_per_particle']:.2f} KiB/particle", flush=True)
        if took > args.budget:
            rec.note(f"stopped after n = {n}: {took:.0f} s > budget {args.budget:.0f} s")
            break
    rec.data["results"] = rows
    if len(rows) >= 2:
        n = np.array([r["particles"] for r in rows], float)
        ms = np.array([r["ms_per_step"] for r in rows])
        slope = np.polyfit(np.log(n), np.log(ms), 1)[0]
        rec.data["log_log_slope_ms_vs_particles"] = float(slope)
        rec.note(f"cost ~ particles^{slope:.2f} over {int(n[0])}..{int(n[-1])} particles")
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
            fig, ax = plt.subplots(figsize=(5, 3.6))
            ax.loglog(n, ms, "o-", label="ms per step (median)")
            ax.loglog(n, ms[-1] * n / n[-1], "k--", lw=0.8, label="linear")
            ax.set_xlabel("particles")
            ax.set_ylabel("ms per step (f32, h = 1/30 s)")
            ax.legend()
            fig.tight_layout()
            path = (Path(args.out) if args.out else C.RESULTS / "particle_speed.json")
            path = path.with_suffix(".png")  # beside the JSON, so --out moves both
            fig.savefig(path, dpi=120)
            print(f"wrote {path}")
        except ImportError:
            rec.note("matplotlib missing: no plot")
    rec.write(args.out)


if __name__ == "__main__":
    main()
