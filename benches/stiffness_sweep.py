"""Iterations to reach tol against stiffness and time step, and the stability matrix at the extremes.

Part 1 (sweep): a small cloth (n x n, 1 m, pinned along one edge, gravity, A3 material with
bending D = 2 s0 t^3 / 12), set swinging about its pinned edge (free edge at ``--swing`` m/s)
so that every step moves it by more than tol whatever h, takes ``--steps`` steps for every s0 in 50 .. 5e7 Pa and
h in 1e-4 .. 1/30 s, with tol = ``--tol`` m and at most ``--max-iters`` iterations; recorded per
(s0, h): the iterations of every step (median and max) and whether each step converged. Run for
plain SISSM and SISSM + Chebyshev (``--accel-rho``).

Part 2 (stability matrix, issue 4 item 6): s0 x h x thickness x scenario on a small mesh with the
default solver settings (tol = 1e-4 m, max_iters = 100). Scenarios:
  hang     the cloth pinned along one edge, from rest;
  impact   the free cloth at 15 m/s towards a floor 5 cm below;
  crumple  every vertex moved to a random position (+-0.3 m) at rest, pinned where it starts;
  line     the whole sheet flattened onto a line (y = 0, z = 0) at rest, pinned where it starts;
  sliver   pinned, rest mesh with near-degenerate triangles (every other column moved to 1e-3 of
           a cell from its neighbour).
Each case passes when no position is NaN or infinite unless the solver raised DivergenceError
(which is saying so), the total energy (kinetic + elastic + gravitational) stays below
``E(0) + 5 %`` (+1 uJ) at every step (pins are set where the vertices start, so nothing else
adds energy: implicit Euler only dissipates), and
every step's ``converged`` flag equals ``residual < tol`` (it says when it has not
converged).

Default (about a minute):  python benches/stiffness_sweep.py
Full size:                 python benches/stiffness_sweep.py --n 40 --steps 20 --max-iters 3000 --matrix-n 16 --matrix-steps 30
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

S0S = [50.0, 5e2, 5e3, 5e4, 5e5, 5e6, 5e7]
HS = [1e-4, 1e-3, 1e-2, 1.0 / 30.0]
G = 9.81


def bent_cloth(n, s0, t, density=300.0, V=None, F=None):
    if V is None:
        V, F = peridyn.grid(n, n, size=(1.0, 1.0), diagonal="alternate")
    cloth = peridyn.Membrane(V, F, thickness=t, density=density, material=peridyn.StretchA3(s0=s0),
                             bending=peridyn.plate_bending_stiffness(2 * s0, 0.0, t))
    return cloth, V


def sweep(args, kw):
    rows = []
    for s0 in S0S:
        for h in HS:
            cloth, V = bent_cloth(args.n, s0, args.thickness)
            cloth.pin(np.flatnonzero(np.isclose(V[:, 1], 1.0)))
            # Swinging about the pinned edge (rigid rotation, free edge moving down at --swing m/s):
            # every step moves the cloth by more than tol, whatever h, so the count means something.
            vel = np.zeros_like(V)
            vel[:, 2] = args.swing * (V[:, 1] - 1.0)
            cloth.velocities = vel
            solver = peridyn.Solver(dt=h, tol=args.tol, max_iters=args.max_iters, threads=args.threads, **kw)
            solver.add(cloth)
            its, conv, err = [], [], []
            failed = None
            t0 = time.perf_counter()
            for _ in range(args.steps):
                try:
                    st = solver.step()
                except Exception as e:  # DivergenceError
                    failed = f"{type(e).__name__}: {e}"
                    break
                its.append(st.iterations)
                conv.append(bool(st.converged))
                err.append(st.residual)
            rows.append({"s0": s0, "h": h, "iterations": its, "converged": conv, "residuals": err,
                         "median_iterations": C.median(its), "max_iterations": max(its) if its else None,
                         "converged_fraction": float(np.mean(conv)) if conv else 0.0,
                         "failed": failed, "wall_s": time.perf_counter() - t0,
                         "finite": bool(np.all(np.isfinite(cloth.positions)))})
            print(f"  s0={s0:8.3g} h={h:8.3g}: iterations median {rows[-1]['median_iterations']:6.1f} "
                  f"max {rows[-1]['max_iterations']}, converged {100*rows[-1]['converged_fraction']:5.1f} %"
                  + (f"  {failed}" if failed else ""), flush=True)
    return rows


def total_energy(cloth):
    z = cloth.positions[:, 2]
    return cloth.kinetic_energy() + cloth.elastic_energy() + G * float(np.dot(cloth.masses, z))


def matrix_case(args, s0, h, t, scenario, rng):
    n = args.matrix_n
    V, F = peridyn.grid(n, n, size=(1.0, 1.0), diagonal="alternate")
    if scenario == "sliver":
        V = V.copy()
        cell = 1.0 / (n - 1)
        odd = (np.round(V[:, 0] / cell).astype(int) % 2 == 1) & (V[:, 0] < 1.0 - 1e-9)
        V[odd, 0] -= cell * (1.0 - 1e-3)
    cloth, _ = bent_cloth(n, s0, t, V=V, F=F)
    solver = peridyn.Solver(dt=h, threads=args.threads)  # default tol and max_iters
    P = V.copy()
    if scenario == "impact":
        cloth.velocities = np.tile([0.0, 0.0, -15.0], (len(V), 1))
        solver.add_collider(peridyn.Plane(point=(0.0, 0.0, -0.05), normal=(0.0, 0.0, 1.0)))
    elif scenario == "crumple":
        P = V + rng.uniform(-0.3, 0.3, size=V.shape)
    elif scenario == "line":
        P[:, 1] = 0.0
    cloth.positions = P
    if scenario != "impact":
        # Pinned where they start (crumpled or flattened too): no pin moves, so nothing but the
        # solver can add energy.
        pins = np.flatnonzero(np.isclose(V[:, 1], 1.0))
        cloth.pin(pins, P[pins])
    solver.add(cloth)
    energies = [total_energy(cloth)]
    steps, raised, silent_nan, flags_ok = [], None, False, True
    for _ in range(args.matrix_steps):
        try:
            st = solver.step()
        except Exception as e:
            raised = f"{type(e).__name__}: {e}"
            break
        pos = cloth.positions
        if not np.all(np.isfinite(pos)):
            silent_nan = True
            break
        energies.append(total_energy(cloth))
        ok = bool(st.converged) == bool(st.residual < solver.tol)
        flags_ok &= ok
        steps.append({"iterations": st.iterations, "converged": bool(st.converged),
                      "residual": st.residual})
    e = np.asarray(energies)
    if len(e) >= 2 and np.all(np.isfinite(e)):
        ref = e[0]
        bound = ref + 0.05 * abs(ref) + 1e-6
        bounded = bool(np.all(e[1:] <= bound))
        growth = float((e[1:].max() - ref) / max(abs(ref), 1e-12))
    else:
        bounded = len(e) >= 1 and bool(np.all(np.isfinite(e))) and raised is not None
        growth = None
    passed = (not silent_nan) and bounded and flags_ok
    conv = [s["converged"] for s in steps]
    return {"s0": s0, "h": h, "thickness": t, "scenario": scenario, "steps_taken": len(steps),
            "raised": raised, "silent_nan": silent_nan, "energy_bounded": bounded,
            "energy_growth_rel": growth, "energy_first_last": [float(e[0]), float(e[-1])],
            "converged_flags_consistent": flags_ok,
            "converged_fraction": float(np.mean(conv)) if conv else 0.0,
            "max_iterations": max((s["iterations"] for s in steps), default=None),
            "max_residual": max((s["residual"] for s in steps), default=None),
            "pass": bool(passed)}


def plot(data, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    variants = list(data["sweep"])
    fig, axes = plt.subplots(1, len(variants) + 1, figsize=(6 * (len(variants) + 1), 5.2), squeeze=False)
    axes = axes[0]
    for ax, name in zip(axes, variants):
        rows = data["sweep"][name]
        M = np.full((len(S0S), len(HS)), np.nan)
        for r in rows:
            M[S0S.index(r["s0"]), HS.index(r["h"])] = r["median_iterations"]
        im = ax.imshow(np.log10(np.maximum(M, 1)), origin="lower", cmap="viridis", aspect="auto")
        for r in rows:
            i, j = S0S.index(r["s0"]), HS.index(r["h"])
            txt = f"{r['median_iterations']:.0f}\n{100 * r['converged_fraction']:.0f}%"
            ax.text(j, i, txt, ha="center", va="center", fontsize=7,
                    color="w" if r["converged_fraction"] < 1 else "k",
                    bbox=None if r["converged_fraction"] == 1 else dict(fc="red", alpha=0.6, lw=0))
        ax.set_xticks(range(len(HS)), [f"{h:.3g}" for h in HS])
        ax.set_yticks(range(len(S0S)), [f"{s:.0e}" for s in S0S])
        ax.set(xlabel="time step h (s)", ylabel="s0 (Pa)",
               title=f"{name}: median iterations to tol\n(and % of steps converged; red: not all)")
        fig.colorbar(im, ax=ax, label="log10 median iterations")
    ax = axes[-1]
    cases = data["matrix"]["cases"]
    scen = data["matrix"]["scenarios"]
    ths = data["matrix"]["thicknesses"]
    s0m, hm = data["matrix"]["s0"], data["matrix"]["h"]
    M = np.zeros((len(scen) * len(ths), len(s0m) * len(hm)))
    for c in cases:
        i = scen.index(c["scenario"]) * len(ths) + ths.index(c["thickness"])
        j = s0m.index(c["s0"]) * len(hm) + hm.index(c["h"])
        M[i, j] = 2 if not c["pass"] else (1 if c["converged_fraction"] == 1 else 0.5)
    from matplotlib.colors import ListedColormap

    ax.imshow(M, cmap=ListedColormap(["#f2c14e", "#f2c14e", "#7bc96f", "#d9534f"]), vmin=0, vmax=2,
              aspect="auto", origin="upper")
    ax.set_yticks(range(M.shape[0]), [f"{s} t={t:g}" for s in scen for t in ths], fontsize=7)
    ax.set_xticks(range(M.shape[1]), [f"{s:.0e}\nh={h:.2g}" for s in s0m for h in hm], fontsize=6)
    ax.set_title(f"stability matrix: {data['matrix']['passed']}/{len(cases)} pass\n"
                 "green: pass, all steps converged\nyellow: pass, some steps flagged not converged\n"
                 "red: fail (NaN, energy growth or a wrong flag)", fontsize=8)
    m = data["machine_start"]
    fig.suptitle(f"peridyn stiffness / time-step sweep ({data['args']['n']}x{data['args']['n']}, tol "
                 f"{data['args']['tol']:g} m) and stability matrix ({data['args']['matrix_n']}x"
                 f"{data['args']['matrix_n']}); load {m['loadavg_1_5_15'][0]:.1f}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=16, help="sweep cloth: vertices per side")
    p.add_argument("--thickness", type=float, default=1e-3)
    p.add_argument("--steps", type=int, default=8)
    p.add_argument("--tol", type=float, default=1e-5)
    p.add_argument("--max-iters", type=int, default=1000)
    p.add_argument("--swing", type=float, default=3.0, help="initial speed of the free edge (m/s)")
    p.add_argument("--accel-rho", type=float, default=0.99)
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--matrix-n", type=int, default=10)
    p.add_argument("--matrix-steps", type=int, default=10)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--skip-sweep", action="store_true")
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)

    rec = C.Record("stiffness_sweep", args)
    rec.data["sweep"] = {}
    if not args.skip_sweep:
        for name, kw in (("SISSM", {}), (f"SISSM+Cheb rho={args.accel_rho:g}",
                                          {"acceleration": "chebyshev", "chebyshev_rho": args.accel_rho})):
            print(f"== sweep: {name}", flush=True)
            rec.data["sweep"][name] = sweep(args, kw)

    print("== stability matrix", flush=True)
    rng = np.random.default_rng(args.seed)
    s0m, hm, ths = [50.0, 2e4, 5e7], [1e-4, 1e-2, 1.0 / 30.0], [1e-4, 1e-3, 1e-2]
    scen = ["hang", "impact", "crumple", "line", "sliver"]
    cases = []
    for sc in scen:
        for t in ths:
            for s0 in s0m:
                for h in hm:
                    c = matrix_case(args, s0, h, t, sc, rng)
                    cases.append(c)
                    if not c["pass"] or c["raised"]:
                        print(f"  {sc:8s} t={t:g} s0={s0:g} h={h:.3g}: pass={c['pass']} raised={c['raised']} "
                              f"nan={c['silent_nan']} bounded={c['energy_bounded']} "
                              f"growth={c['energy_growth_rel']} flags_ok={c['converged_flags_consistent']}",
                              flush=True)
    passed = sum(c["pass"] for c in cases)
    rec.data["matrix"] = {"s0": s0m, "h": hm, "thicknesses": ths, "scenarios": scen,
                          "solver": "defaults (tol=1e-4 m, max_iters=100)", "cases": cases,
                          "passed": passed,
                          "all_converged": sum(c["pass"] and c["converged_fraction"] == 1 for c in cases),
                          "raised_divergence": sum(bool(c["raised"]) for c in cases),
                          "silent_nan": sum(c["silent_nan"] for c in cases)}
    print(f"stability matrix: {passed}/{len(cases)} pass; "
          f"{rec.data['matrix']['all_converged']} with every step converged; "
          f"{rec.data['matrix']['raised_divergence']} raised DivergenceError; "
          f"{rec.data['matrix']['silent_nan']} silent NaN", flush=True)
    path = rec.write(args.out)
    plot(rec.data, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
