"""A contact scene of Lu et al. 2023 (Table 1) at full size, checked as it runs.

Runs one of :mod:`peridyn.paper_scenes` (``cloths_over_ball`` with ``--layers``,
``antependium``, ``shooting_shell``) or of :mod:`peridyn.avatar_scenes` (``skirt``, ``dress``:
Fig. 12, whose ms per step on the paper's GPU go into the JSON beside ours) for ``--steps`` steps and every ``--check-every`` steps
checks the promises of the contact local step with :mod:`peridyn.checks`: no two non-adjacent
triangles intersect (exact test, ipctk), the smallest distance between non-adjacent primitives
(looked for up to ``4 xi``; the local step keeps it above ``eps xi``), and how deep the deepest
vertex is inside a collider. Per step it records ms (the solver's own timing), iterations,
the convergence measure after each iteration (``residuals``, m), the contact figures
(candidate and box triangle pairs, live and active primitive pairs, CCD queries, broad-phase
builds and repairs, clamped vertices, ms by phase), the lowest and highest vertex and how
many vertices touch a collider (within ``2 xi`` of its surface).

The JSON (and a PNG of the smallest distance and ms per step against the step) is rewritten
at every check, so a run stopped early (``--time-limit``, or killed) keeps what it measured.

A full-size run can take longer than one sitting: with ``--state PATH`` the solver's state
(``peridyn.save_state``) is written to PATH at every check, and a later run with the same
arguments and ``--state PATH`` continues from it, appending to the JSON of ``--out`` (one entry
per sitting in its ``segments``: command, commit, machine, steps and wall time). It refuses to
continue with other settings (only ``--steps``, ``--check-every``, ``--time-limit``, ``--out``,
``--state`` and ``--threads`` may change). The pair cache is not saved: a resumed run builds
it afresh at its first step.

Full size, one layer over the ball (40K vertices):
    python benches/paper_scenes.py --scene cloths_over_ball --layers 1 --steps 400 --check-every 20
Quick check (a minute):
    python benches/paper_scenes.py --n 30 --steps 40 --check-every 10 --out /tmp/ps.json
The six layers' landing at the paper's mesh spacing (8.6 mm) on a cloth 0.4 times the size,
dropped from 0.4 m so that it lands at speed (38K vertices, 20 minutes on two cores; as at full
size from step 437 on, 11 of its steps 383-400 run to 20 iterations without converging; see
docs/performance.md):
    python benches/paper_scenes.py --layers 6 --n 80 --size 0.68 --drop 0.4 --steps 420 \
        --check-every 20 --max-iters 20
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

#: Fig. 12 of the paper: average ms per step of its garments on an RTX A4000 (1/22 s and 1/8 s).
PAPER_MS_PER_STEP = {"skirt": 1e3 / 22, "dress": 1e3 / 8}

CONTACT_FIGURES = ("candidate_pairs", "box_pairs", "primitive_pairs", "active_pairs",
                   "ccd_queries", "broad_phase_builds", "cache_repairs", "live_refreshes",
                   "clamped", "local_iterations", "broad_phase_ms", "ccd_ms", "descent_ms")


def build(args):
    """The scene of the parsed arguments (``args`` of this script, or a run JSON's ``args``)."""
    from peridyn import paper_scenes

    common = dict(tol=args.tol, max_iters=args.max_iters, threads=args.threads)
    if args.chebyshev_rho is not None:
        common["solver_options"] = dict(acceleration="chebyshev", chebyshev_rho=args.chebyshev_rho)
    if args.kb is not None:
        common["bending" if args.scene == "antependium" else "kb"] = args.kb
    if args.scene == "cloths_over_ball":
        shape = {key: value for key, value in (("size", args.size), ("drop", args.drop))
                 if value is not None}
        scene = paper_scenes.cloths_over_ball(layers=args.layers, n=args.n, **shape, **common)
    elif args.scene == "antependium":
        scene = paper_scenes.antependium(n=args.n, **common)
    elif args.scene == "shooting_shell":
        scene = paper_scenes.shooting_shell(n=args.n, **common)
    else:
        from peridyn import avatar_scenes

        scene = getattr(avatar_scenes, args.scene)(**common)
    if args.proximal is not None:
        scene.solver.contact = scene.solver.contact.replace(proximal=args.proximal)
    return scene


def check(scene, step):
    """The geometric checks at the current positions."""
    from peridyn import checks

    t0 = time.perf_counter()
    contact = scene.solver.contact
    x, tris, _ = checks.mesh_of(scene.bodies.values())
    crossing = checks.intersecting_pairs(x, tris)
    pad = 4.0 * contact.thickness
    gap = checks.min_separation(x, tris, pad)
    deepest = checks.deepest_inside(scene.solver, list(scene.colliders.values()), x)
    return {
        "step": step,
        "intersecting_pairs": len(crossing),
        "first_intersecting": [list(map(int, p)) for p in crossing[:5]],
        "min_distance_m": gap,
        "min_distance_searched_up_to_m": pad,
        "eps_xi_m": contact.eps * contact.thickness,
        "deepest_inside_collider_m": deepest,
        "check_seconds": time.perf_counter() - t0,
    }


def plot(data, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(13, 4.5))
    checks = data["checks"]
    if checks:
        s = [c["step"] for c in checks]
        a1.plot(s, [c["min_distance_m"] * 1e3 for c in checks], "o-", label="min distance")
        a1.axhline(checks[0]["eps_xi_m"] * 1e3, color="r", ls=":", label="eps xi")
        bad = [c["step"] for c in checks if c["intersecting_pairs"]]
        if bad:
            a1.plot(bad, [0.0] * len(bad), "rx", ms=10, label="intersection")
        a1.legend(fontsize=8)
    a1.set(xlabel="step", ylabel="mm", title="smallest distance between non-adjacent primitives")
    rows = data["steps"]
    if rows:
        a2.plot([r["step"] for r in rows], [r["ms"] for r in rows], lw=0.8)
    a2.set(xlabel="step", ylabel="ms per step", title="cost per step")
    m = data["machine_start"]
    fig.suptitle(f"{data['scene']}: {data['vertices']} vertices; load "
                 f"{m['loadavg_1_5_15'][0]:.1f} on {m['cpu_count']} CPUs", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)


#: Arguments that may differ between the sittings of one run: they change where a run ends,
#: how long a sitting lasts, how often it checks, where it writes and how many threads it uses,
#: not the simulation.
PER_SITTING_ARGS = ("steps", "check_every", "time_limit", "out", "state", "threads")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scene", default="cloths_over_ball",
                   choices=["cloths_over_ball", "antependium", "shooting_shell", "skirt", "dress"])
    p.add_argument("--layers", type=int, default=1, help="cloths_over_ball: 1, 3 or 6")
    p.add_argument("--n", type=int, default=None,
                   help="vertices per side (default: the paper's 200; shell: target 120; "
                        "not for the garments, which have the paper's vertex counts)")
    p.add_argument("--size", type=float, default=None,
                   help="cloths_over_ball: side of each cloth in m (default: the paper's 1.7)")
    p.add_argument("--drop", type=float, default=None,
                   help="cloths_over_ball: height of the lowest cloth above the ball in m "
                        "(default: the scene's 5 mm)")
    p.add_argument("--kb", type=float, default=None,
                   help="bending factor kb (default: the scene's; the paper's antependium: "
                        "0, 0.003, 0.03, 0.3)")
    p.add_argument("--steps", type=int, default=400)
    p.add_argument("--check-every", type=int, default=20)
    p.add_argument("--proximal", choices=["jacobi", "identity"], default=None,
                   help="metric of the local step's proximal term (default: Contact's, jacobi; "
                        "identity is the paper's eq. 47)")
    p.add_argument("--tol", type=float, default=1e-4)
    p.add_argument("--max-iters", type=int, default=100)
    p.add_argument("--chebyshev-rho", type=float, default=None,
                   help="Chebyshev acceleration with this spectral-radius estimate (default: none)")
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--time-limit", type=float, default=None,
                   help="stop after this many wall seconds (the JSON keeps what ran)")
    p.add_argument("--out", default=None)
    p.add_argument("--state", default=None,
                   help="save the state here at every check, and resume from it if it exists")
    args = p.parse_args(argv)
    garment = args.scene in PAPER_MS_PER_STEP
    if garment and args.n is not None:
        p.error("--n is not an option of the garments (they have the paper's vertex counts)")
    if args.n is None and not garment:
        args.n = 120 if args.scene == "shooting_shell" else 200
    if args.scene != "cloths_over_ball" and (args.size, args.drop) != (None, None):
        p.error("--size and --drop are options of cloths_over_ball")
    if args.check_every < 1 or args.steps < 1:
        p.error("--steps and --check-every must be >= 1")

    rec = C.Record("paper_scenes", args)
    hwm0 = C.vm_kib("VmHWM")
    scene = build(args)
    solver, contact = scene.solver, scene.solver.contact
    bodies = list(scene.bodies.values())
    colliders = list(scene.colliders.values())
    nv = sum(b.num_vertices for b in bodies)
    size = (f"_{args.layers}x{args.n}" if args.scene == "cloths_over_ball"
            else "" if garment else f"_{args.n}")
    name = args.scene + size + ("" if args.kb is None else f"_kb{args.kb:g}")
    name += "".join(f"_{key}{value:g}" for key, value in (("size", args.size), ("drop", args.drop))
                    if value is not None)
    out = Path(args.out) if args.out else C.RESULTS / f"paper_scenes_{name}.json"
    state = Path(args.state) if args.state else None
    first = 1
    segments = []
    if state is not None and state.exists():
        import peridyn

        earlier = json.loads(out.read_text())
        if earlier["vertices"] != nv or earlier["scene"] != scene.description:
            p.error(f"--state {state}: {out} is of another scene")
        changed = {key: (earlier["args"].get(key), value) for key, value in vars(args).items()
                   if key not in PER_SITTING_ARGS and earlier["args"].get(key) != value}
        if changed:
            p.error(f"--state {state}: {out} ran with other settings; a run continues with the "
                    "settings it began with: " + ", ".join(
                        f"--{key.replace('_', '-')} was {was}, now {now}"
                        for key, (was, now) in changed.items()))
        peridyn.load_state(state, solver)
        first = solver.steps_taken + 1
        segments = earlier.get("segments") or [{
            key: earlier.get(key) for key in ("command", "machine_start", "machine_end",
                                              "wall_seconds")}]
        rec.data.update({key: earlier[key] for key in ("steps", "checks")})
        rec.data["steps"] = [r for r in rec.data["steps"] if r["step"] < first]
        rec.data["checks"] = [c for c in rec.data["checks"] if c["step"] < first]
        print(f"resumed from {state} at step {first - 1}", flush=True)
    else:
        rec.data.update({"steps": [], "checks": [check(scene, 0)]})
        print(f"{scene.description}: {nv} vertices; step 0: {rec.data['checks'][0]}", flush=True)
    rec.data.update({
        "scene": scene.description, "vertices": nv, "dt": solver.dt,
        "paper_ms_per_step": PAPER_MS_PER_STEP.get(args.scene),
        "contact": {"thickness": contact.thickness, "d_hat": contact.d_hat, "eps": contact.eps,
                    "proximal": contact.proximal},
    })
    start = time.perf_counter()
    stopped = None
    for k in range(first, args.steps + 1):
        st = solver.step()
        x = np.concatenate([b.positions for b in bodies])
        near = np.zeros(len(x), bool)
        for i, c in enumerate(colliders):
            rotation, translation = solver.collider_pose(i)
            near |= c.signed_distance((x - translation) @ rotation) < 2 * contact.thickness
        row = {"step": k, "time_s": st.time, "ms": st.timings["total"],
               "iterations": st.iterations, "converged": bool(st.converged),
               "residuals": [float(e) for e in st.residuals],
               "lowest_z": float(x[:, 2].min()), "highest_z": float(x[:, 2].max()),
               "touching_collider": int(near.sum()),
               **{f: st.contact[f] for f in CONTACT_FIGURES}}
        rec.data["steps"].append(row)
        over = args.time_limit is not None and time.perf_counter() - start > args.time_limit
        if k % args.check_every == 0 or k == args.steps or over:
            c = check(scene, k)
            rec.data["checks"].append(c)
            print(f"step {k}: {row['ms']:.0f} ms, {row['iterations']} it, "
                  f"{row['candidate_pairs']} candidates ({row['box_pairs']} boxes), "
                  f"{row['active_pairs']} active, {row['touching_collider']} touching, "
                  f"z in [{row['lowest_z']:.3f}, {row['highest_z']:.3f}]; "
                  f"{c['intersecting_pairs']} intersecting, min distance "
                  f"{c['min_distance_m'] * 1e3:.3f} mm, deepest in a collider "
                  f"{c['deepest_inside_collider_m'] * 1e3:.3f} mm", flush=True)
            ms = [r["ms"] for r in rec.data["steps"]]
            peak = (C.vm_kib("VmHWM") - hwm0) * 1024.0 / nv
            rec.data["segments"] = segments + [{
                "command": rec.data["command"], "machine_start": rec.data["machine_start"],
                "first_step": first, "last_step": k, "peak_bytes_per_vertex": peak,
                "wall_seconds": time.perf_counter() - rec.t0,
            }]
            rec.data["summary"] = {
                "steps_run": k, "simulated_s": st.time,
                "ms_per_step_median": float(np.median(ms)),
                "intersections_seen": sum(c["intersecting_pairs"] for c in rec.data["checks"]),
                "min_distance_m": min(c["min_distance_m"] for c in rec.data["checks"]),
                "deepest_inside_collider_m": max(c["deepest_inside_collider_m"]
                                                 for c in rec.data["checks"]),
                "peak_bytes_per_vertex": max(s.get("peak_bytes_per_vertex") or 0.0
                                             for s in rec.data["segments"]),
                "stopped_early": over and k < args.steps,
            }
            rec.write(str(out))
            if state is not None:
                import peridyn

                partial = state.with_name(state.name + ".partial.npz")
                peridyn.save_state(partial, solver)
                partial.replace(state)
            plot(rec.data, out.with_suffix(".png"))
        if over:
            stopped = k
            break
    if stopped is not None and stopped < args.steps:
        rec.note(f"stopped by --time-limit after {stopped} of {args.steps} steps")
        rec.write(str(out))


if __name__ == "__main__":
    main()
