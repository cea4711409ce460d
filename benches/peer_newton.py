"""Peer comparison, side by side in one process: peridyn against NVIDIA Newton's cloth solvers on CPU.

The same scene for every solver: a 1 m square cloth of n x n vertices (default 120 x 120,
14.4K vertices) in z = 0, pinned along the edge y = 1 m, gravity -9.81 m/s^2 along z, h = 1e-3 s,
10 iterations per step, no contact, no damping. All solvers are built first, then step in turn,
``--block`` consecutive steps each (every solver takes its block of steps before any takes the
next block, so drifts of a shared machine's speed hit all alike, while each solver runs as a
user runs it, step after step; with ``--block 1`` every peridyn step starts with caches that a
Newton step of hundreds of milliseconds has just filled: 7.16 against 7.05 ms per step for
peridyn f32 on 2 threads in two runs one after the other at commit 7cd05e7, so the order
hardly matters here, while this VM's speed drifts by half between runs, for every solver
alike): ``--warmup`` untimed steps (JIT compilation, first touch), then
``--steps`` timed steps; ms per step is the median wall-clock time of one step
(``wp.synchronize()`` included for Newton). The sag is the
lowest z of the cloth after all the steps (m, negative: below the pinned edge).

Material, made comparable (small-strain, per unit area of the sheet):
- peridyn: A3, s0 (Pa) x thickness t: 2D shear modulus mu = s0 t (N/m), Poisson 0;
  bending D = 2 s0 t^3 / 12; density rho, mass rho t per m^2 (lumped by area).
- Newton VBD: neo-Hookean triangles tri_ke = mu, tri_ka = 0 (Lame lambda 0), edge_ke = D.
- Newton Style3D: tri_aniso_ke = (mu, mu, mu), edge_aniso_ke = (D, D, D).
- Newton XPBD: its solver has no triangle FEM constraint; springs on the mesh edges and across
  each edge pair (``add_springs=True``) with spring_ke = mu (approximately the same 2D modulus),
  edge_ke = D. Its stiffness is therefore only roughly comparable. Newton's XPBD accumulates
  the constraint corrections Jacobi-style, and at this stiffness, mass and step it diverges
  (recorded as such); "XPBD-soft" runs it with springs softened by --xpbd-soft-factor so that
  it is stable: same cost per step, a sag that is not comparable.
  Newton's particle masses are uniform: rho t (1 m^2) / n^2 each.

Default (a few minutes):    python benches/peer_newton.py
Longer run (sag at 0.5 s):  python benches/peer_newton.py --steps 500
Install Newton:             pip install newton   (brings warp-lang; runs on CPU without CUDA)
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


class PeridynRunner:
    def __init__(self, args, precision, threads):
        self.cloth = C.hanging_cloth(args.n, thickness=args.thickness, density=args.density,
                                     material=peridyn.StretchA3(s0=args.s0),
                                     bending=peridyn.plate_bending_stiffness(2 * args.s0, 0.0, args.thickness))
        self.solver = peridyn.Solver(dt=args.dt, tol=0.0, max_iters=args.iters, threads=threads,
                                     precision=precision)
        self.solver.add(self.cloth)
        self.name = f"peridyn SISSM {precision}"
        self.threads, self.iters = threads, args.iters
        self.walls, self.totals, self.cpus = [], [], []

    def step(self, timed):
        c0, t0 = time.process_time(), time.perf_counter()
        st = self.solver.step()
        w = (time.perf_counter() - t0) * 1e3
        if timed:
            self.walls.append(w)
            self.cpus.append((time.process_time() - c0) * 1e3)
            self.totals.append(st.timings["total"])

    def result(self):
        z = self.cloth.positions[:, 2]
        return {"solver": self.name, "threads": self.threads, "iterations": self.iters,
                "ms_step_median": C.median(self.walls), "ms_step_all": self.walls,
                "cpu_ms_step_median": C.median(self.cpus),
                "cores_busy": C.median(self.cpus) / C.median(self.walls),
                "ms_step_median_core_timer": C.median(self.totals), "sag_m": float(z.min()),
                "finite": bool(np.all(np.isfinite(self.cloth.positions))),
                "vertices": self.cloth.num_vertices}


def newton_versions():
    import newton
    import warp as wp

    return {"newton": getattr(newton, "__version__", None), "warp": getattr(wp, "__version__", None)}


def build_newton(args, kind):
    import warp as wp

    import newton
    from newton.solvers import style3d

    wp.config.quiet = True
    n = args.n
    mu = args.s0 * args.thickness
    D = 2 * args.s0 * args.thickness**3 / 12.0
    mass = args.density * args.thickness * 1.0 / (n * n)
    builder = newton.ModelBuilder(up_axis=newton.Axis.Z)
    common = dict(pos=wp.vec3(0.0, 0.0, 0.0), rot=wp.quat_identity(), vel=wp.vec3(0.0, 0.0, 0.0),
                  dim_x=n - 1, dim_y=n - 1, cell_x=1.0 / (n - 1), cell_y=1.0 / (n - 1), mass=mass,
                  fix_top=True, tri_kd=0.0, edge_kd=0.0, particle_radius=0.25 / (n - 1))
    mapping = {}
    if kind == "Style3D":
        newton.solvers.SolverStyle3D.register_custom_attributes(builder)
        style3d.add_cloth_grid(builder, **common, tri_aniso_ke=wp.vec3(mu, mu, mu),
                               edge_aniso_ke=wp.vec3(D, D, D))
        mapping = {"tri_aniso_ke": [mu, mu, mu], "edge_aniso_ke": [D, D, D]}
    elif kind.startswith("XPBD"):
        ke = mu if kind == "XPBD" else mu * args.xpbd_soft_factor
        builder.add_cloth_grid(**common, tri_ke=mu, tri_ka=0.0, edge_ke=D, add_springs=True,
                               spring_ke=ke, spring_kd=0.0)
        mapping = {"spring_ke": ke, "edge_ke": D, "note": "XPBD solves springs and bending only"
                   + ("" if kind == "XPBD" else f"; springs softened by {args.xpbd_soft_factor:g} "
                      "to keep newton's Jacobi XPBD stable: its timing is valid, its sag is not comparable")}
    elif kind == "VBD":
        builder.add_cloth_grid(**common, tri_ke=mu, tri_ka=0.0, edge_ke=D)
        builder.color(include_bending=True)
        mapping = {"tri_ke": mu, "tri_ka": 0.0, "edge_ke": D}
    model = builder.finalize(device="cpu")
    model.set_gravity((0.0, 0.0, -9.81))
    if kind == "Style3D":
        solver = newton.solvers.SolverStyle3D(
            model=model, config=newton.solvers.SolverStyle3D.Config(iterations=args.iters))
    elif kind.startswith("XPBD"):
        solver = newton.solvers.SolverXPBD(model=model, iterations=args.iters)
    else:
        solver = newton.solvers.SolverVBD(model=model, iterations=args.iters)
    # Style3D asserts on its contacts argument; no collider shapes exist, so this is empty.
    contacts = newton.CollisionPipeline(model).contacts() if kind == "Style3D" else None
    return NewtonRunner(args, kind, model, solver, contacts, mapping)


class NewtonRunner:
    def __init__(self, args, kind, model, solver, contacts, mapping):
        import warp as wp

        self.wp, self.args, self.kind, self.model = wp, args, kind, model
        self.solver, self.contacts, self.mapping = solver, contacts, mapping
        self.s0, self.s1, self.control = model.state(), model.state(), model.control()
        self.name = f"newton {kind}"
        self.walls, self.cpus = [], []

    def step(self, timed):
        c0, t0 = time.process_time(), time.perf_counter()
        self.s0.clear_forces()
        self.solver.step(self.s0, self.s1, self.control, self.contacts, self.args.dt)
        self.wp.synchronize()
        w = (time.perf_counter() - t0) * 1e3
        self.s0, self.s1 = self.s1, self.s0
        if timed:
            self.walls.append(w)
            self.cpus.append((time.process_time() - c0) * 1e3)

    def result(self):
        q = self.s0.particle_q.numpy()
        top = np.isclose(self.model.particle_q.numpy()[:, 1], 1.0)
        finite = bool(np.all(np.isfinite(q)))
        return {"solver": self.name, "iterations": self.args.iters,
                "diverged": (not finite) or float(q[:, 2].min()) < -10.0,
                "ms_step_median": C.median(self.walls), "ms_step_all": self.walls,
                "cpu_ms_step_median": C.median(self.cpus),
                "cores_busy": C.median(self.cpus) / C.median(self.walls),
                "sag_m": float(q[:, 2].min()), "finite": finite,
                "vertices": int(self.model.particle_count),
                "pinned_max_move_m": float(np.abs(q[top, 2]).max()) if top.any() else None,
                "stiffness_mapping": self.mapping, "warp_device": "cpu"}


def plot(data, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in data["results"] if "ms_step_median" in r]
    labels = [r["solver"] + (f" t{r['threads']}" if "threads" in r else "") for r in rows]
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.8))
    colors = ["tab:blue" if l.startswith("peridyn") else "tab:orange" for l in labels]
    a1.barh(labels, [r["ms_step_median"] for r in rows], color=colors)
    a1.set_xscale("log")
    a1.set(xlabel="ms per step (median, log scale)",
           title=f"{data['args']['n']}x{data['args']['n']} cloth, h={data['args']['dt']:g} s, "
                 f"{data['args']['iters']} iterations")
    for i, r in enumerate(rows):
        a1.text(r["ms_step_median"], i, f" {r['ms_step_median']:.1f}", va="center", fontsize=8)
    sag = [0.0 if r.get("diverged") else -1e3 * r["sag_m"] for r in rows]
    a2.barh(labels, sag, color=colors)
    for i, r in enumerate(rows):
        a2.text(sag[i], i, " diverged" if r.get("diverged") else f" {sag[i]:.2f}", va="center", fontsize=8)
    a2.set(xlabel="sag: depth of the lowest point (mm)",
           title=f"after {data['args']['warmup'] + data['args']['steps']} steps "
                 f"({(data['args']['warmup'] + data['args']['steps']) * data['args']['dt']:g} s)")
    for a in (a1, a2):
        a.grid(True, axis="x", alpha=0.3)
    m = data["machine_start"]
    fig.suptitle(f"peridyn vs newton (CPU) side by side; load {m['loadavg_1_5_15'][0]:.1f} on "
                 f"{m['cpu_count']} CPUs", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--n", type=int, default=120)
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--iters", type=int, default=10)
    p.add_argument("--steps", type=int, default=60, help="timed steps per solver")
    p.add_argument("--warmup", type=int, default=5, help="untimed steps first (JIT, first touch)")
    p.add_argument("--block", type=int, default=10,
                   help="consecutive steps each solver takes before the next solver's turn")
    p.add_argument("--s0", type=float, default=1e6, help="peridyn A3 s0 (Pa); mu = s0 * thickness")
    p.add_argument("--thickness", type=float, default=1e-3)
    p.add_argument("--density", type=float, default=300.0)
    p.add_argument("--threads", default="1,2", help="peridyn thread counts")
    p.add_argument("--newton-solvers", default="VBD,XPBD,XPBD-soft,Style3D",
                   help="XPBD-soft: XPBD with springs softened by --xpbd-soft-factor (stable)")
    p.add_argument("--xpbd-soft-factor", type=float, default=1e-3)
    p.add_argument("--out", default=None)
    args = p.parse_args(argv)
    if args.block < 1:
        p.error("--block must be >= 1")

    rec = C.Record("peer_newton", args)
    rec.data["scene"] = {"mu_N_per_m": args.s0 * args.thickness,
                         "bending_D_Nm": 2 * args.s0 * args.thickness**3 / 12.0,
                         "mass_kg": args.density * args.thickness, "simulated_s":
                         (args.warmup + args.steps) * args.dt}
    results = []
    try:
        import warp as wp

        wp.config.quiet = True
        wp.init()
        rec.data["newton_versions"] = newton_versions()
        newton_ok = True
    except Exception as e:
        newton_ok = False
        why = f"newton/warp not importable: {type(e).__name__}: {e}"
        rec.note(why + " (install with: pip install newton)")
        rec.data["newton_unavailable"] = why
    runners, results = [], []
    for prec in ("f32", "f64"):
        for th in [int(t) for t in args.threads.split(",")]:
            runners.append(PeridynRunner(args, prec, th))
    if newton_ok:
        for kind in args.newton_solvers.split(","):
            try:
                t0 = time.perf_counter()
                runners.append(build_newton(args, kind))
                print(f"newton {kind}: built in {time.perf_counter() - t0:.1f} s", flush=True)
            except Exception as e:
                results.append({"solver": f"newton {kind}", "failed": f"{type(e).__name__}: {e}",
                                "traceback": traceback.format_exc()[-3000:]})
                print(f"newton {kind}: FAILED to build: {e}", flush=True)
    # Side by side: every solver takes its block of steps before any takes the next block, so
    # drifts of the shared machine's speed spread over all of them. Warm-up steps (JIT, first
    # touch) are not timed.
    failed = set()
    total = args.warmup + args.steps
    for first in range(0, total, args.block):
        for i, r in enumerate(runners):
            for k in range(first, min(first + args.block, total)):
                if i in failed:
                    break
                try:
                    r.step(timed=k >= args.warmup)
                except Exception as e:
                    failed.add(i)
                    results.append({"solver": r.name,
                                    "failed": f"{type(e).__name__}: {e} (at step {k})",
                                    "traceback": traceback.format_exc()[-3000:]})
                    print(f"{r.name}: FAILED at step {k}: {e}", flush=True)
    for i, r in enumerate(runners):
        if i in failed:
            continue
        res = r.result()
        results.append(res)
        print(f"{res['solver']:24s} {('t' + str(res['threads'])) if 'threads' in res else '  '}: "
              f"{res['ms_step_median']:9.2f} ms/step (CPU/wall {res['cores_busy']:.2f}), "
              f"sag {res['sag_m']*1e3:10.2f} mm", flush=True)
    rec.data["results"] = results
    ok = {r["solver"] + (f" t{r['threads']}" if "threads" in r else ""): r["ms_step_median"]
          for r in results if "ms_step_median" in r}
    best_f32 = min((v for k, v in ok.items() if k.startswith("peridyn SISSM f32")), default=None)
    ratios = {}
    for k, v in ok.items():
        if k.startswith("newton") and best_f32:
            ratios[f"{k} / peridyn f32 (best thread count)"] = v / best_f32
    rec.data["headline"] = {"ms_per_step": ok, "speedup_of_peridyn_f32": ratios,
                            "targets": "issue 4: peridyn f32 <= 10 ms/step; >= 20x faster than "
                                       "Style3D, >= 7x faster than XPBD at 10 iterations"}
    for k, v in ratios.items():
        print(f"  {k}: {v:.1f}x")
    path = rec.write(args.out)
    plot(rec.data, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
