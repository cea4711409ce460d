"""Convergence of one implicit Euler step: relative error against iterations and wall time.

Fig. 6 / Fig. 13 of Lu et al. 2023. For one step of a cloth pinned along one edge, taken when the
cloth is stretched most during a short pre-roll, every solver variant starts from the same state
and runs a fixed number of iterations (tol = 0) with ``record_energy=True``. The relative error

    eta_k = (E(y_k) - E(y*)) / (E(y_0) - E(y*))

uses E(y*) from a long f64 run of the same step (``--ref-iters``, >= 500 iterations; if any f64
variant reaches a lower energy, that lower value is used and the JSON says so). Wall time per
iteration comes from separate runs without energy recording: the median over ``--repeats`` of
the step's total time divided by the iteration count. Timed runs are a warm solver's second
step of the same state (the first step's set-up excluded, as in a running simulation;
``--cold`` times the first step instead).

Variants: SISSM (tangent preconditioner, f64 and f32), SISSM + Chebyshev for several rho, the
paper's preconditioner (with and without Chebyshev), inner Jacobi sweeps 1/2/4 (``inner_iters``)
and the descent baseline of Wang & Yang 2016 (``method="descent"``: Jacobi preconditioner from
the diagonal of the energy's Hessian, step length halved on an energy rise, Chebyshev restarted
then; with and without Chebyshev) when the installed build has them; variants the build lacks
are listed in the JSON as skipped. Newton (``method="newton"``, f64 and f32) runs
``--newton-iters`` iterations (each a CG solve) and is one of the references, since on the
stiff cloth the SISSM references do not converge. Besides iterations x mean ms/iteration, the
time to eta 1e-2 / 1e-3 / 1e-4 is measured directly: the step rerun stopped at the first
iteration that reaches it (``ms_to_eta_<thr>_measured``). ``--only`` picks variants by name, ``--references`` the references. f32 runs
of at most ``F32_REEVAL_MAX_ITERS`` iterations get their energies re-evaluated in f64 from their
iterates (the solver's own f32 sums cannot resolve eta below a few percent on the stiff step;
the f32 sums are kept as ``energies_f32_sums``), and Newton runs record ``linear_products``. The descent's wall time includes its Hessian diagonal, which
peridyn computes by central differences of the exact gradient (6 (n+1) kernel evaluations per
vertex): it measures this implementation, not what an analytic diagonal would cost.

Scenes: ``moderate`` (A3, s0 = 2e4 Pa) and ``stiff`` (neo-Hookean s0 = 4.8e7, s1 = 1.2e7 Pa, the
paper's comparison).

Default (a few minutes on 2 shared cores):  python benches/convergence.py
Full size:  python benches/convergence.py --n 120 --iters 500 --ref-iters 5000 --repeats 5
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


def scene_material(name: str):
    if name == "moderate":
        return peridyn.StretchA3(s0=2e4)
    if name == "stiff":
        return peridyn.NeoHookean(s0=4.8e7, s1=1.2e7)
    raise ValueError(name)


def scene_dt(args, scene: str) -> float:
    return args.dt_moderate if scene == "moderate" else args.dt_stiff


def make_cloth(args, scene: str):
    return C.hanging_cloth(args.n, thickness=args.thickness, density=args.density,
                           material=scene_material(scene))


# Long f64 runs of the same step; E(y*) is the lowest energy any of them (or any f64 variant) reaches.
# Newton converges in tens of iterations where SISSM needs thousands: its reference runs
# --newton-ref-iters.
REFERENCES = [("SISSM", {}),
              ("SISSM+Cheb rho=0.999", {"acceleration": "chebyshev", "chebyshev_rho": 0.999}),
              ("newton", {"method": "newton"})]


def iterations(args, kw, reference=False):
    """Iterations a run of variant `kw` takes (Newton: far fewer, each a CG solve)."""
    if kw.get("method") == "newton":
        return args.newton_ref_iters if reference else args.newton_iters
    return args.ref_iters if reference else args.iters


def variants(args):
    rhos = [float(r) for r in args.rhos.split(",")]
    out = [("SISSM", {}), ("SISSM f32", {"precision": "f32"})]
    for r in rhos:
        out.append((f"SISSM+Cheb rho={r:g}", {"acceleration": "chebyshev", "chebyshev_rho": r}))
    out.append(("paper precond", {"preconditioner": "paper"}))
    out.append(("paper precond+Cheb rho=0.9",
                {"preconditioner": "paper", "acceleration": "chebyshev", "chebyshev_rho": 0.9}))
    for k in (1, 2, 4):
        out.append((f"inner Jacobi {k}", {"inner_iters": k}))
    out.append(("descent", {"method": "descent"}))
    for r in rhos:
        out.append((f"descent+Cheb rho={r:g}",
                    {"method": "descent", "acceleration": "chebyshev", "chebyshev_rho": r}))
    for r in rhos:
        out.append((f"SISSM f32+Cheb rho={r:g}",
                    {"precision": "f32", "acceleration": "chebyshev", "chebyshev_rho": r}))
    out.append(("newton", {"method": "newton"}))
    out.append(("newton f32", {"method": "newton", "precision": "f32"}))
    if args.only:
        keep = [w.strip() for w in args.only.split(",")]
        out = [(n, kw) for n, kw in out if n in keep]
    return out


def preroll(args, scene: str, rec: C.Record):
    """Run the scene; return (positions, velocities, step index, max stretch) of the most stretched state."""
    cloth = make_cloth(args, scene)
    solver = peridyn.Solver(dt=scene_dt(args, scene), tol=args.preroll_tol,
                            max_iters=args.preroll_max_iters, threads=args.threads, precision="f64",
                            acceleration="chebyshev", chebyshev_rho=0.99)
    solver.add(cloth)
    best = (cloth.positions, cloth.velocities, 0, 1.0)
    hist = []
    for k in range(args.preroll):
        st = solver.step()
        smax = float(np.max(cloth.stretches()[:, :2]))
        hist.append({"step": k, "iterations": st.iterations, "converged": st.converged,
                     "max_stretch": smax})
        if k >= args.preroll // 4 and smax > best[3]:
            best = (cloth.positions, cloth.velocities, k + 1, smax)
    return best, hist


def one_step(args, scene, state, kw, *, iters, record_energy, warm=False):
    """One step of ``iters`` iterations from ``state`` with a new solver. ``warm``: the solver
    first takes the same step once (discarded; the bodies are reset to ``state``), so the step
    measured is that of a running simulation, without the first step's set-up (the solver's
    data structures, Newton's coarse aggregation and symbolic factorisation)."""
    cloth = make_cloth(args, scene)
    cloth.positions = state[0]
    cloth.velocities = state[1]
    solver = peridyn.Solver(dt=scene_dt(args, scene), tol=0.0, max_iters=iters, threads=args.threads,
                            record_energy=record_energy, **{"precision": "f64", **kw})
    solver.add(cloth)
    if warm:
        solver.step()
        cloth.positions = state[0]
        cloth.velocities = state[1]
    t0 = time.perf_counter()
    st = solver.step()
    wall = (time.perf_counter() - t0) * 1e3
    return st, wall, cloth


def predicted(args, scene, state):
    """The step's first iterate y_0 = y* = x + h v + h^2 g (pinned vertices stay)."""
    cloth = make_cloth(args, scene)
    h = scene_dt(args, scene)
    g = np.asarray(peridyn.Solver(dt=h).gravity, float)
    y = np.asarray(state[0], float) + h * np.asarray(state[1], float) + h * h * g
    y[cloth.pinned] = np.asarray(state[0], float)[cloth.pinned]
    return y


def energy_f64(args, scene, state, y):
    """E(y) of eq. 2 in f64 (J): sum over free vertices of m |y - y*|^2 / (2 h^2), with
    y* = x + h v + h^2 g from the step's start ``state``, plus the elastic energy at y. The
    solver's own record of an f32 run sums f32 vertex energies, which cannot resolve eta below
    about eps_f32 |E| / (E_0 - E*) (a few percent on the stiff step)."""
    cloth = make_cloth(args, scene)
    h = scene_dt(args, scene)
    g = np.asarray(peridyn.Solver(dt=h).gravity, float)
    x0, v0 = np.asarray(state[0], float), np.asarray(state[1], float)
    free = np.ones(len(x0), bool)
    free[cloth.pinned] = False
    y_star = x0 + h * v0 + h * h * g
    y = np.asarray(y, float)
    cloth.positions = y
    d = y[free] - y_star[free]
    inertia = 0.5 / h**2 * float(np.sum(np.asarray(cloth.masses)[free] * np.sum(d * d, axis=1)))
    return inertia + cloth.elastic_energy()


# f32 runs of at most this many iterations get their energies re-evaluated in f64 from the
# iterates (one rerun per iteration count).
F32_REEVAL_MAX_ITERS = 40


def run_scene(args, scene: str, rec: C.Record):
    print(f"== scene {scene}: pre-roll {args.preroll} steps", flush=True)
    state, hist = preroll(args, scene, rec)
    out = {"material": repr(scene_material(scene)), "dt": scene_dt(args, scene), "preroll": hist, "state_step": state[2],
           "state_max_stretch": state[3]}
    print(f"   most stretched state after step {state[2]} (max stretch {state[3]:.4f})", flush=True)

    out["references"] = {}
    e_refs = []
    for rname, rkw in REFERENCES:
        if not C.solver_supports(**rkw) or (args.references and rname not in args.references.split(",")):
            continue
        n_ref = iterations(args, rkw, reference=True)
        print(f"   reference: f64 {rname}, {n_ref} iterations", flush=True)
        ref, ref_wall, _ = one_step(args, scene, state, rkw, iters=n_ref, record_energy=True)
        e_ref = np.asarray(ref.energies, float)
        e_refs.append((float(np.min(e_ref)), rname))
        out["references"][rname] = {
            "kwargs": rkw, "iterations": ref.iterations, "E_final": float(e_ref[-1]),
            "E_min": float(np.min(e_ref)), "E0": float(e_ref[0]),
            "residual": ref.residual, "last_move": ref.last_move, "wall_ms": ref_wall,
            "dE_over_last_100": float(e_ref[-101] - e_ref[-1]) if len(e_ref) > 101 else None}
        print(f"      E_final {e_ref[-1]:.10g} J, residual {ref.residual:.2e} m", flush=True)

    runs = {}
    for name, kw in variants(args):
        if not C.solver_supports(**kw):
            runs[name] = {"kwargs": kw, "skipped": "this peridyn build's Solver does not accept "
                          + ", ".join(f"{k}={v!r}" for k, v in kw.items())}
            print(f"   {name:28s} skipped (not in this build)", flush=True)
            continue
        try:
            st, _, cloth = one_step(args, scene, state, kw, iters=iterations(args, kw),
                                    record_energy=True)
        except Exception as e:  # DivergenceError or a rejected combination
            runs[name] = {"kwargs": kw, "failed": f"{type(e).__name__}: {e}"}
            print(f"   {name:28s} failed: {e}", flush=True)
            continue
        runs[name] = {
            "kwargs": kw,
            "energies": np.asarray(st.energies, float),
            "moves": np.asarray(st.moves, float),
            "iterations": st.iterations,
            "residual": st.residual,
            "converged_flag": st.converged,
            "ms_step_all": [], "ms_global_all": [],
            "linear_products": getattr(st, "linear_products", None),
        }
        if kw.get("precision", "f64") == "f64":
            # The f64 re-evaluation below agrees with the solver's own energy (a check of it).
            e64 = energy_f64(args, scene, state, cloth.positions)
            runs[name]["energy_f64_check_rel"] = abs(e64 - st.energies[-1]) / abs(st.energies[-1])
        elif st.iterations <= F32_REEVAL_MAX_ITERS:
            e = [energy_f64(args, scene, state, one_step(args, scene, state, kw, iters=k,
                                                         record_energy=False)[2].positions)
                 for k in range(1, st.iterations + 1)]
            runs[name]["energies_f32_sums"] = runs[name]["energies"]
            e0 = energy_f64(args, scene, state, predicted(args, scene, state))
            runs[name]["energies"] = np.asarray([e0] + e, float)
        print(f"   {name:28s} {st.iterations} it, residual {st.residual:.2e}", flush=True)

    # Timing: rounds over all variants (interleaved, so a burst of load on the shared machine
    # hits every variant alike), without energy recording; medians over the rounds.
    for rnd in range(args.repeats):
        for name, kw in variants(args):
            r = runs.get(name, {})
            if "energies" not in r:
                continue
            s2, _w, _ = one_step(args, scene, state, kw, iters=iterations(args, kw), record_energy=False,
                                 warm=args.warm)
            r["ms_step_all"].append(s2.timings["total"])
            r["ms_global_all"].append(s2.timings["global"])
            if kw.get("method") == "newton" and hasattr(s2, "newton"):
                r.setdefault("newton_phases_all", []).append(dict(s2.newton))
    # E(y*): the reference's final energy, or a lower one if an f64 variant found it.
    e_star, src = min(e_refs)
    lowest = min(((float(np.min(r["energies"])), n) for n, r in runs.items()
                  if "energies" in r and r["kwargs"].get("precision", "f64") == "f64"
                  and len(r["energies"])), default=(np.inf, None))
    out["E_star_source"] = f"reference {src}"
    if lowest[0] < e_star:
        out["E_star_source"] = f"lower energy reached by '{lowest[1]}' (references not fully converged)"
        out["E_star_reference_minus_lowest"] = e_star - lowest[0]
        e_star = lowest[0]
    out["E_star"] = e_star
    # The floor of any f32 solver on this step: eta of the best f64 iterate with its positions
    # rounded to f32 (an f32 solver stores positions so), evaluated in f64.
    best = min(((float(np.min(r["energies"])), n) for n, r in runs.items() if "energies" in r
                and r["kwargs"].get("precision", "f64") == "f64" and len(r["energies"])),
               default=(None, None))[1]
    if best is not None:
        kw = runs[best]["kwargs"]
        _s, _w, c = one_step(args, scene, state, kw, iters=iterations(args, kw), record_energy=False)
        y = np.asarray(c.positions, float)
        e0 = energy_f64(args, scene, state, predicted(args, scene, state))
        e_round = energy_f64(args, scene, state, y.astype(np.float32).astype(float))
        out["f32_rounding_floor_eta"] = (e_round - e_star) / (e0 - e_star)
        out["f32_rounding_floor_of"] = best
        print(f"   eta of '{best}' rounded to f32: {out['f32_rounding_floor_eta']:.2e}", flush=True)
    # Time to a given accuracy, measured: the same step stopped at the first iteration whose
    # eta reaches the threshold (tol = 0, max_iters = that iteration), median over the rounds.
    # (For Newton the cost per iteration varies with its CG solves, so iterations times a mean
    # cost per iteration would not do.)
    etas = eta_of(runs, out)
    for rnd in range(args.repeats):
        for name, kw in variants(args):
            r = runs.get(name, {})
            for thr in TIMED_ETAS:
                hit = np.flatnonzero(etas.get(name, np.array([])) <= thr)
                if len(hit) == 0 or hit[0] == 0:
                    continue
                s3, _w, _ = one_step(args, scene, state, kw, iters=int(hit[0]), record_energy=False,
                                     warm=args.warm)
                r.setdefault(f"ms_to_eta_{thr:g}_all", []).append(s3.timings["total"])
                if kw.get("method") == "newton" and hasattr(s3, "newton"):
                    r.setdefault(f"newton_phases_to_eta_{thr:g}_all", []).append(dict(s3.newton))
    for name, r in runs.items():
        for thr in TIMED_ETAS:
            if f"ms_to_eta_{thr:g}_all" in r:
                r[f"ms_to_eta_{thr:g}_measured"] = C.median(r[f"ms_to_eta_{thr:g}_all"])
        if "energies" in r:
            r["ms_step_median"] = C.median(r["ms_step_all"])
            r["ms_global_median"] = C.median(r["ms_global_all"])
            r["ms_per_iteration"] = r["ms_step_median"] / max(r["iterations"], 1)
            print(f"   {name:28s} {r['ms_step_median']:8.1f} ms / {r['iterations']} it (median of "
                  f"{len(r['ms_step_all'])})", flush=True)

    for n, r in runs.items():
        if "energies" not in r:
            continue
        e = r["energies"]
        denom = e[0] - e_star
        eta = (e - e_star) / denom if denom > 0 else np.full_like(e, np.nan)
        r["eta"] = eta
        r["eta_final"] = float(eta[-1])
        r["roundoff_floor_eta"] = float(np.finfo(np.float64 if r["kwargs"].get("precision", "f64") == "f64"
                                                  else np.float32).eps * abs(e_star) / denom) if denom > 0 else None
        for thr in (1e-1, 1e-2, 1e-3, 1e-4):
            hit = np.flatnonzero(eta <= thr)
            r[f"iters_to_eta_{thr:g}"] = int(hit[0]) if len(hit) else None
            r[f"ms_to_eta_{thr:g}"] = float(hit[0] * r["ms_per_iteration"]) if len(hit) else None
    # Variants whose iterates coincide (same energy history to round-off): their curves overlap
    # in the plot.
    groups, seen = [], set()
    names = [n for n, r in runs.items() if "energies" in r]
    for i, a in enumerate(names):
        if a in seen:
            continue
        g = [a]
        for b in names[i + 1:]:
            ea, eb = runs[a]["energies"], runs[b]["energies"]
            if b not in seen and len(ea) == len(eb) and np.allclose(ea, eb, rtol=1e-13, atol=0):
                g.append(b)
                seen.add(b)
        if len(g) > 1:
            groups.append(g)
    out["identical_iterates"] = groups
    out["runs"] = runs
    return out


# Accuracies whose time is measured directly (the target is 1e-3).
TIMED_ETAS = (1e-2, 1e-3, 1e-4)


def eta_of(runs, out):
    """eta_k per run from its recorded energies and out["E_star"]."""
    e_star, etas = out["E_star"], {}
    for n, r in runs.items():
        if "energies" in r:
            e = r["energies"]
            denom = e[0] - e_star
            etas[n] = (e - e_star) / denom if denom > 0 else np.full_like(e, np.nan)
    return etas


def plot(data, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    scenes = list(data["scenes"])
    cmap = plt.get_cmap("tab20")
    fig, axes = plt.subplots(len(scenes), 3, figsize=(17, 5 * len(scenes)), squeeze=False)
    for row, scene in enumerate(scenes):
        sd = data["scenes"][scene]
        for i, (name, r) in enumerate(sd["runs"].items()):
            if "eta" not in r:
                continue
            col = cmap(i % 20)
            eta = np.clip(np.asarray(r["eta"], float), 1e-12, None)
            k = np.arange(len(eta))
            ls = "--" if "descent" in name else (":" if "paper" in name else "-")
            axes[row, 0].semilogy(k, eta, ls, label=name, color=col)
            axes[row, 1].semilogy(k * r["ms_per_iteration"], eta, ls, label=name, color=col)
            measured = [(r[f"ms_to_eta_{t:g}_measured"], t) for t in TIMED_ETAS
                        if f"ms_to_eta_{t:g}_measured" in r]
            if measured:
                axes[row, 1].plot([m for m, _ in measured], [t for _, t in measured], "o", color=col,
                                  markersize=4)
            moves = np.asarray(r["moves"], float)
            axes[row, 2].semilogy(np.arange(1, len(moves) + 1), np.clip(moves, 1e-16, None), ls, label=name, color=col)
        axes[row, 0].set(xlabel="iteration k", ylabel="eta_k = (E_k - E*) / (E_0 - E*)",
                         title=f"{scene}: relative energy error vs iterations")
        axes[row, 1].set(xlabel="wall time (ms; lines: iterations x mean ms/iteration, dots: measured "
                         "time to 1e-2/1e-3/1e-4)", ylabel="eta_k",
                         title=f"{scene}: relative energy error vs wall time")
        axes[row, 2].set(xlabel="iteration k", ylabel="largest vertex move (m)",
                         title=f"{scene}: largest move per iteration")
        for ax in axes[row]:
            ax.grid(True, which="both", alpha=0.3)
        axes[row, 0].legend(fontsize=7)
    a = data["args"]
    fig.suptitle(f"peridyn convergence of one step: {a['n']}x{a['n']} cloth, h={a['dt_moderate']:g} s (moderate), "
                 f"{a['dt_stiff']:g} s (stiff), "
                 f"threads={a['threads']}, load {data['machine_start']['loadavg_1_5_15'][0]:.1f} "
                 f"on {data['machine_start']['cpu_count']} CPUs", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def fmt(x):
    return "None" if x is None else f"{x:.1f}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=40, help="vertices per side (default 40)")
    p.add_argument("--dt-moderate", type=float, default=1e-2, help="time step of the moderate scene (s)")
    p.add_argument("--dt-stiff", type=float, default=1e-3, help="time step of the stiff scene (s); at 1e-2 "
                   "plain SISSM does not converge in 3000 iterations on 40x40")
    p.add_argument("--thickness", type=float, default=1e-3)
    p.add_argument("--density", type=float, default=300.0)
    p.add_argument("--preroll", type=int, default=20, help="pre-roll steps; the most stretched state "
                   "after the first quarter of them is the benchmark step's start")
    p.add_argument("--preroll-tol", type=float, default=1e-5)
    p.add_argument("--preroll-max-iters", type=int, default=300)
    p.add_argument("--iters", type=int, default=300, help="iterations per variant")
    p.add_argument("--ref-iters", type=int, default=2000, help="iterations of the f64 reference (>= 500)")
    p.add_argument("--newton-iters", type=int, default=30, help="iterations of the Newton variants")
    p.add_argument("--newton-ref-iters", type=int, default=60, help="iterations of the Newton reference")
    p.add_argument("--repeats", type=int, default=5, help="timing repeats (median)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--cold", dest="warm", action="store_false", help="time a new solver's first step "
                   "(set-up included) instead of its second step of the same state")
    p.add_argument("--rhos", default="0.9,0.95,0.99,0.999")
    p.add_argument("--scenes", default="moderate,stiff")
    p.add_argument("--references", default=None, help="comma-separated reference names to run "
                   "(default: all of " + ", ".join(n for n, _ in REFERENCES) + ")")
    p.add_argument("--only", default=None, help="comma-separated variant names to run (default: all)")
    p.add_argument("--out", default=None, help="JSON path (default benches/results/convergence.json)")
    args = p.parse_args(argv)
    if args.ref_iters < 500:
        p.error("--ref-iters must be >= 500")

    rec = C.Record("convergence", args)
    rec.data["features"] = {"method": C.solver_supports(method="sissm"),
                            "inner_iters": C.solver_supports(inner_iters=1)}
    rec.data["scenes"] = {}
    rec.note("descent wall times include the finite-difference Hessian diagonal (6 (n+1) kernel "
             "evaluations per vertex and iteration); compare descent against SISSM in iterations")
    for scene in args.scenes.split(","):
        rec.data["scenes"][scene] = run_scene(args, scene, rec)
    path = rec.write(args.out)
    plot(rec.data, path.with_suffix(".png"))
    for scene, sd in rec.data["scenes"].items():
        print(f"\n{scene}: E* from {sd['E_star_source']}")
        print(f"  {'variant':30s} {'ms/it':>7s} {'eta_final':>10s} {'it->1e-2':>9s} {'ms->1e-2':>9s} "
              f"{'it->1e-3':>9s} {'ms->1e-3':>9s} {'it->1e-4':>9s}")
        for n, r in sd["runs"].items():
            if "eta" in r:
                print(f"  {n:30s} {r['ms_per_iteration']:7.3f} {r['eta_final']:10.2e} "
                      f"{str(r['iters_to_eta_0.01']):>9s} {('%.1f' % r['ms_to_eta_0.01']) if r['ms_to_eta_0.01'] is not None else 'None':>9s} "
                      f"{str(r['iters_to_eta_0.001']):>9s} {fmt(r.get('ms_to_eta_0.001_measured')):>9s} "
                      f"{str(r['iters_to_eta_0.0001']):>9s}")
            else:
                print(f"  {n:30s} {r.get('skipped') or r.get('failed')}")


if __name__ == "__main__":
    main()
