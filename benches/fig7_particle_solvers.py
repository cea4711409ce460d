"""Fig. 7 of He, Wang and Wu 2017: the residual against iterations and against wall time for
the four global solvers of the particle family (direct, jacobi, chebyshev, position), side by
side in one process.

Scene: a block of n x n x n particles (spacing 0.01 m, E 2e5 Pa, nu 0.25, 1000 kg/m^3)
stretched 5 % along x, squashed 5 % along z with a ripple, its first two particles pinned,
released for one step of h = 1/30 s without gravity, in f64. Each solver runs the step with
tol = 0 for ``--iters`` iterations: the residual after each iteration (StepStats.residuals, the
convergence measure max_i |r_i| / m_i, m) is the curve against iterations. For the curve
against wall time the same step is run afresh with max_iters = 1, 2, 4, ... (each a fresh
solver, so the direct solver's factorisation is in every run, as in a real first step) and
its wall time (StepStats.timings['total'], ms; median of ``--repeats``) paired with its last
residual.

Default:  python benches/fig7_particle_solvers.py       (n = 16, 4096 particles)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

import peridyn  # noqa: E402

SOLVERS = ["direct", "jacobi", "chebyshev", "position"]


def step(args, name: str, iters: int):
    n, s = args.n, 0.01
    k, j, i = np.meshgrid(*(np.arange(n),) * 3, indexing="ij")
    x = np.stack([i, j, k], axis=-1).reshape(-1, 3) * s
    body = peridyn.Particles(x, spacing=s, density=1000.0,
                             material=peridyn.Elastic.from_young(2e5, 0.25))
    y = x.copy()
    y[:, 0] *= 1.05
    y[:, 2] = 0.95 * x[:, 2] + 0.002 * np.sin(300 * x[:, 0])
    body.positions = y
    body.pin([0, 1])
    solver = peridyn.Solver(dt=1 / 30, gravity=(0, 0, 0), global_solver=name, tol=0.0,
                            max_iters=iters, threads=args.threads)
    solver.add(body)
    return solver.step()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--n", type=int, default=16, help="particles per side")
    ap.add_argument("--iters", type=int, default=512, help="iterations of the residual curve")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", help="JSON path (default benches/results/fig7_particle_solvers.json)")
    args = ap.parse_args()
    rec = C.Record("fig7_particle_solvers", args)
    results = {}
    for name in SOLVERS:
        stats = step(args, name, args.iters)
        curve = {"residuals": list(stats.residuals), "timed": []}
        m = 1
        while m <= args.iters:
            runs = [step(args, name, m) for _ in range(args.repeats)]
            curve["timed"].append({"iterations": m,
                                   "ms": C.median([r.timings["total"] for r in runs]),
                                   "residual": runs[-1].residual})
            m *= 2
        results[name] = curve
        print(f"{name}: residual {stats.residuals[0]:.2e} -> {stats.residuals[-1]:.2e} m in "
              f"{args.iters} iterations; {curve['timed'][-1]['ms']:.0f} ms for them", flush=True)
    rec.data["particles"] = args.n ** 3
    rec.data["results"] = results
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (a, b) = plt.subplots(1, 2, figsize=(9, 3.6))
        for name, curve in results.items():
            r = curve["residuals"]
            a.semilogy(np.arange(1, len(r) + 1), r, label=name)
            b.loglog([t["ms"] for t in curve["timed"]], [t["residual"] for t in curve["timed"]],
                     "o-", label=name)
        a.set_xlabel("iterations")
        b.set_xlabel("wall time of the step (ms)")
        for ax in (a, b):
            ax.set_ylabel("residual max |r_i| / m_i (m)")
            ax.legend()
        fig.suptitle(f"Fig. 7: {args.n ** 3} particles, h = 1/30 s, f64")
        fig.tight_layout()
        path = C.RESULTS / "fig7_particle_solvers.png"
        fig.savefig(path, dpi=120)
        print(f"wrote {path}")
    except ImportError:
        rec.note("matplotlib missing: no plot")
    rec.write(args.out)


if __name__ == "__main__":
    main()
