"""What `Solver(tol=)` means for a passive scene: energy drift, sag and cost against tol and h.

`tol` (m) bounds each step's distance from the exact implicit Euler solution (a step stops
when `max_i |r_i| / m_i < tol`). Implicit Euler solved exactly only dissipates, so the total
energy (kinetic + gravitational + elastic) of a passive scene never rises. A step stopped at
`tol` may: its velocity carries an error up to `tol / h`. When `tol` exceeds the motion the
forces cause within one step (about `g h^2`), the first iterate already passes the test and the
step is barely solved at all.

Scene: an n x n cloth (1 m, `StretchA3(s0)`, 1 mm, 200 kg/m^3, light bending) pinned along one
edge, released flat from rest under gravity, run for `--duration` s at each h and tol (up to
`--max-iters` iterations a step). Recorded per (h, tol): the energy at the end against the
start, the largest rise of the energy above its running minimum (0 for a solve that only
dissipates), the share of steps that raise it, iterations per step, ms per step (median), and
the free corner's height at the end against the tightest tol's.

Default (a few minutes):  python benches/tolerance_energy.py
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

G = 9.81


def hanging_cloth(n, s0):
    V, F = peridyn.grid(n, n, size=(1.0, 1.0))
    cloth = peridyn.Membrane(V, F, thickness=1e-3, density=200.0, material=peridyn.StretchA3(s0=s0),
                             bending=1e-8)
    cloth.pin(np.flatnonzero(np.isclose(V[:, 1], 1.0)))
    corner = int(np.flatnonzero(np.isclose(V[:, 0], 0.0) & np.isclose(V[:, 1], 0.0))[0])
    return cloth, corner


def run(args, h, tol):
    cloth, corner = hanging_cloth(args.n, args.s0)
    solver = peridyn.Solver(dt=h, tol=tol, max_iters=args.max_iters, gravity=(0.0, 0.0, -G),
                            threads=args.threads)
    solver.add(cloth)
    mass = cloth.masses

    def energy():
        return cloth.kinetic_energy() + G * float(mass @ cloth.positions[:, 2]) + cloth.elastic_energy()

    energies, iterations, ms, converged = [energy()], [], [], []
    for _ in range(int(round(args.duration / h))):
        t = time.perf_counter()
        stats = solver.step()
        ms.append(1e3 * (time.perf_counter() - t))
        iterations.append(stats.iterations)
        converged.append(bool(stats.converged))
        energies.append(energy())
    E = np.array(energies)
    rise = E - np.minimum.accumulate(E)
    return {
        "h": h, "tol": tol, "tol_over_g_h2": tol / (G * h * h),
        "steps": len(iterations),
        "energy_change_J": float(E[-1] - E[0]),
        "largest_rise_J": float(rise.max()),
        "steps_raising_energy_percent": float(100.0 * np.mean(np.diff(E) > 1e-12 * max(1.0, abs(E[0])))),
        "iterations_mean": float(np.mean(iterations)),
        "iterations_max": int(np.max(iterations)),
        "converged_percent": float(100.0 * np.mean(converged)),
        "ms_per_step_median": float(np.median(ms)),
        "corner_z_m": float(cloth.positions[corner, 2]),
    }


def plot(rows, hs, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(16, 4.8))
    for h in hs:
        rs = [r for r in rows if r["h"] == h]
        tols = [r["tol"] for r in rs]
        label = f"h = {h:g} s"
        axes[0].loglog([r["tol_over_g_h2"] for r in rs], [max(r["largest_rise_J"], 1e-12) for r in rs], "o-",
                       label=label)
        axes[1].semilogx(tols, [r["energy_change_J"] for r in rs], "o-", label=label)
        axes[2].loglog(tols, [r["iterations_mean"] for r in rs], "o-", label=label)
    axes[0].set(xlabel="tol / (g h^2)", ylabel="largest energy rise above its running minimum (J)",
                title="energy gained by stopping at tol (1e-12: none)")
    axes[1].set(xlabel="tol (m)", ylabel="energy at the end - at the start (J)",
                title="energy dissipated over the run")
    axes[2].set(xlabel="tol (m)", ylabel="iterations per step (mean)", title="cost")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=30, help="vertices per side (default 30)")
    p.add_argument("--s0", type=float, default=1.2e4, help="StretchA3 stiffness (Pa)")
    p.add_argument("--duration", type=float, default=1.5, help="simulated time per run (s)")
    p.add_argument("--hs", default="1e-3,4e-3,0.0333333", help="time steps (s), comma-separated")
    p.add_argument("--tols", default="1e-3,1e-4,1e-5,1e-6,1e-7", help="tolerances (m), comma-separated")
    p.add_argument("--max-iters", type=int, default=1000)
    p.add_argument("--threads", type=int, default=2)
    p.add_argument("--out", default=None, help="JSON path (default benches/results/tolerance_energy.json)")
    args = p.parse_args()
    hs = [float(x) for x in args.hs.split(",")]
    tols = sorted((float(x) for x in args.tols.split(",")), reverse=True)

    rec = C.Record("tolerance_energy", args)
    rows = []
    for h in hs:
        for tol in tols:
            r = run(args, h, tol)
            rows.append(r)
            print(f"h {h:<9g} tol {tol:<7g} (tol / g h^2 = {r['tol_over_g_h2']:8.3g}): energy change "
                  f"{r['energy_change_J']:+.4f} J, largest rise {r['largest_rise_J']:.2e} J, "
                  f"{r['steps_raising_energy_percent']:4.0f} % of steps raise it, "
                  f"{r['iterations_mean']:6.1f} it/step, {r['ms_per_step_median']:6.2f} ms/step, "
                  f"corner z {r['corner_z_m']:+.4f} m", flush=True)
    for h in hs:  # the corner's height against the tightest tolerance's, per h
        rs = [r for r in rows if r["h"] == h]
        ref = min(rs, key=lambda r: r["tol"])["corner_z_m"]
        for r in rs:
            r["corner_z_vs_tightest_m"] = r["corner_z_m"] - ref
    rec.data["rows"] = rows
    path = rec.write(args.out)
    plot(rows, hs, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
