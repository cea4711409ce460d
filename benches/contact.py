"""Cost of a step with contact (Lu et al. 2023, Algorithm 2), split by phase.

Scene: :func:`peridyn.paper_scenes.cloths_over_ball` (1.7 m cloths, s0 = 12000 Pa, kb = 0.1,
xi = 1.5 mm, h = 1e-3 s, gravity g, ball and ground with friction), dropped from 1 mm above the
ball with the layers 1.05 barrier reaches apart, so that contact with the ball and between the
layers starts within the warm-up. The issue's sizes, 14.4K and 40K vertices,
are covered by one layer of 120 x 120 and 200 x 200 and by three layers of 69 x 69 (14.3K)
and 115 x 115 (39.7K). Each case runs in a fresh subprocess, one after another, so its peak
resident memory (``VmHWM`` delta, Rust allocations included) is its own.

Per case: at least ``--warmup`` steps (the fall onto the ball), then on until a step ends with
an active pair between membranes (``StepStats.contact['active_pairs'] > 0``), at most
``--max-warmup`` steps in all, then ``--steps`` timed steps with exactly ``--iters`` global
iterations each (``tol = 0``) unless ``--tol`` is given. Reported as medians over the timed
steps: ms per step and per phase (global, colliders, broad phase, CCD, descent = local step
distances and moves, contact other = the rest of the local step: proximal metric, set-up passes,
realised reaction), global and local (descent) iterations, candidate triangle pairs, live
primitive pairs (those that may come within the barrier's reach) and the cached primitive pairs
they are filtered from, CCD queries, broad-phase builds, repairs, filterings of the live pairs
and the sweeps among them per step, active primitive pairs, clamped vertices, peak memory.
Three layers start one barrier reach apart, so they are in contact after the minimal warm-up;
a single cloth has no contact of its own until it folds as it drapes (after 343-384 steps
from 80 x 80 to 200 x 200 vertices, 475-1020 from 30 x 30 to 60 x 60; 20 x 20 slides off the
ball without folding within 1500), and before that its steps do no CCD and no descent.
``--no-until-contact`` times after exactly ``--warmup`` steps.

Broad-phase cost against vertex count: one layer at ``--bp-sizes``, ms of broad phase per
local step (there is one local step per global iteration), ``--bp-steps`` timed steps each,
reported apart for the steps that built the pair cache and those that did not (a build costs
several filterings, so a median over a few mixed steps says little about either).

Builds side by side (``--build NAME=WHEEL_OR_DIR``, two or more, the first the reference): each
case's landing is simulated once and saved under ``--state-dir`` (by the first build, kept for
later runs); every build then continues it in a fresh process for ``--steps`` steps, the builds
taking turns for ``--rounds`` rounds (in reverse order every other round). Each process reports
the process CPU time per step besides wall time: with ``--threads 1`` that is the work per step,
which a machine shared with other jobs inflates far less than wall time. The summary gives per
case and build the median CPU and wall ms per step, and whether the builds computed the same
thing (contact figures per step, final positions to the bit).

Quick check (minutes):
    python benches/contact.py --sizes 1:30,3:17 --bp-sizes 30 --steps 2 --warmup 12 \\
        --max-warmup 600
Full size (about 10 minutes alone on 2 cores):
    python benches/contact.py
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


def warm_up(solver, warmup: int, until_contact: bool, max_warmup: int) -> tuple[int, int]:
    """Steps ``solver`` at least ``warmup`` times and, with ``until_contact``, on until a step
    ends with an active membrane pair (at most ``max_warmup`` steps in all). Returns the steps
    taken and the active pairs of the last one."""
    taken, active = 0, 0
    limit = max(warmup, max_warmup) if until_contact else warmup
    while taken < limit:
        active = solver.step().contact["active_pairs"]
        taken += 1
        if taken >= warmup and (active > 0 or not until_contact):
            break
    return taken, active


def broad_phase_by_build(rows) -> dict:
    """Broad-phase ms per local step (one per global iteration), median over the timed steps
    that built the pair cache anew (``broad_phase_builds > 0``: every triangle pair within the
    allowance found again) and apart over those that only kept or repaired it and filtered
    its pairs, so that a build in one of a few timed steps cannot pass for the filtering cost.
    Each comes with its step count; its median is None where no timed step falls in it."""
    out = {}
    for name, built in (("without_build", False), ("with_build", True)):
        per = [r["broad_phase"] / max(r["iterations"], 1) for r in rows
               if (r["broad_phase_builds"] > 0) == built]
        out[name] = {"steps": len(per),
                     "ms_per_local_step": float(np.median(per)) if per else None}
    return out


def child(layers: int, n: int, steps: int, warmup: int, until_contact: bool, max_warmup: int,
          iters: int, tol: float, threads, state_dir=None):
    """Runs in the subprocess: prints one JSON line. With ``state_dir``, continues the landing
    saved there for this case, or warms up and saves it there first."""
    import hashlib
    import os

    import peridyn
    from peridyn.paper_scenes import cloths_over_ball

    hwm0 = C.vm_kib("VmHWM")
    scene = cloths_over_ball(layers=layers, n=n, drop=1e-3, layer_gap=1.05, tol=tol,
                             max_iters=iters, threads=threads)
    solver = scene.solver
    state = Path(state_dir) / f"contact_{layers}x{n}.npz" if state_dir else None
    if state is not None and state.exists():
        peridyn.load_state(state, solver)
        warmup_steps, warmup_active = solver.steps_taken, None
    else:
        warmup_steps, warmup_active = warm_up(solver, warmup, until_contact, max_warmup)
        if state is not None:
            state.parent.mkdir(parents=True, exist_ok=True)
            peridyn.save_state(state, solver)
    rows = []
    for _ in range(steps):
        c0, t0 = time.process_time(), time.perf_counter()
        st = solver.step()
        wall = (time.perf_counter() - t0) * 1e3
        t, c = st.timings, st.contact
        rows.append({
            "total": t["total"], "global": t["global"], "colliders": t["colliders"],
            "predict_finish": t["predict"] + t["finish"],
            "broad_phase": c["broad_phase_ms"], "ccd": c["ccd_ms"], "descent": c["descent_ms"],
            # The local step's time outside its broad phase, CCD and descent: the proximal
            # metric, set-up passes and realised reaction (builds without the timer: 0).
            "contact_other": max(t.get("contact", 0.0) - c["broad_phase_ms"] - c["ccd_ms"]
                                 - c["descent_ms"], 0.0),
            "iterations": st.iterations, "local_iterations": c["local_iterations"],
            "candidate_pairs": c["candidate_pairs"], "box_pairs": c["box_pairs"],
            "active_pairs": c["active_pairs"],
            "primitive_pairs": c["primitive_pairs"], "ccd_queries": c["ccd_queries"],
            "broad_phase_builds": c["broad_phase_builds"], "cache_repairs": c["cache_repairs"],
            "cached_pairs": c["cached_pairs"], "live_refreshes": c["live_refreshes"],
            "sweeps": c["sweeps"],
            "clamped": c["clamped"], "residual": st.residual,
            "converged": st.converged, "wall": wall,
            "cpu": (time.process_time() - c0) * 1e3,
        })
    hwm1 = C.vm_kib("VmHWM")
    x = np.concatenate([b.positions for b in scene.bodies.values()])
    ball = scene.ball
    med = {key: float(np.median([r[key] for r in rows]))
           for key in rows[0] if key != "converged"}
    nv = layers * n * n
    print(json.dumps({
        "module": peridyn.__file__,
        "positions_sha256": hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest(),
        "layers": layers, "n": n, "vertices": nv, "threads": solver.threads,
        "warmup_steps": warmup_steps, "active_pairs_after_warmup": warmup_active,
        "median": med, "steps": rows,
        "ms_step_median": med["total"],
        "broad_phase_by_build": broad_phase_by_build(rows),
        "cores_busy": med["cpu"] / med["wall"],
        "peak_bytes_per_vertex": (hwm1 - hwm0) * 1024.0 / nv,
        "VmHWM_kib": [hwm0, hwm1],
        "deepest_in_ball_m": float(-ball.signed_distance(x).min()),
        "lowest_z": float(x[:, 2].min()),
        "loadavg_1": os.getloadavg()[0],
    }), flush=True)


PHASES = ("global", "broad_phase", "ccd", "descent", "contact_other", "colliders",
          "predict_finish")


def plot(data, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2) = plt.subplots(1, 2, figsize=(14, 4.8))
    rows = [r for r in data["cases"] if "median" in r]
    labels = [f"{r['layers']}x{r['n']}^2\n{r['vertices'] / 1000:.1f}K" for r in rows]
    bottom = np.zeros(len(rows))
    for phase in PHASES:
        ms = np.array([r["median"][phase] for r in rows])
        a1.bar(labels, ms, bottom=bottom, label=phase)
        bottom += ms
    a1.set(ylabel="ms per step (median)", title="step with contact, by phase "
           f"({data['args']['iters']} global iterations)")
    a1.legend(fontsize=8)
    bp = sorted([r for r in data["broad_phase"] if "median" in r], key=lambda r: r["vertices"])
    if bp:
        v = np.array([r["vertices"] for r in bp], float)
        for kind, style in (("without_build", "o-"), ("with_build", "s--")):
            steps = "steps without a build" if kind == "without_build" else "steps with a build"
            ms = np.array([r["broad_phase_by_build"][kind]["ms_per_local_step"] or np.nan
                           for r in bp], float)
            a2.loglog(v, ms, style, label=f"broad phase per local step, {steps}")
            if kind == "without_build" and np.isfinite(ms).any():
                last = np.flatnonzero(np.isfinite(ms))[-1]
                a2.loglog(v, ms[last] * v / v[last], "k:", lw=1, label="linear")
        a2.legend(fontsize=8)
    a2.set(xlabel="vertices (one layer)", ylabel="ms", title="broad-phase cost against size")
    a2.grid(True, which="both", alpha=0.3)
    m = data["machine_start"]
    fig.suptitle(f"peridyn contact: cloths over a ball; load {m['loadavg_1_5_15'][0]:.1f} on "
                 f"{m['cpu_count']} CPUs (shared machine: medians)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def child_argv(args, layers: int, n: int, steps: int) -> list:
    """The arguments of a case's subprocess (after the interpreter)."""
    argv = [str(Path(__file__).resolve()), "--child", str(layers), str(n),
            "--steps", str(steps), "--warmup", str(args.warmup), "--max-warmup",
            str(args.max_warmup), "--iters", str(args.iters), "--tol", str(args.tol),
            "--until-contact" if args.until_contact else "--no-until-contact"]
    if args.threads is not None:
        argv += ["--threads", str(args.threads)]
    if args.state_dir:
        argv += ["--state-dir", args.state_dir]
    return argv


#: Per-step contact figures that builds computing the same thing agree on.
SAME_FIGURES = ("iterations", "local_iterations", "primitive_pairs", "cached_pairs",
                "candidate_pairs", "ccd_queries", "broad_phase_builds", "cache_repairs",
                "live_refreshes", "sweeps", "active_pairs", "clamped", "residual")


def compare_builds(args, sizes, rec) -> None:
    """Times the builds ``args.build`` on each case's saved landing, taking turns (see the
    module doc), into ``rec.data["builds"]``."""
    import tempfile

    builds = dict(b.split("=", 1) for b in args.build)
    names = list(builds)
    runs = {f"{layers}x{n}": {name: [] for name in names} for layers, n in sizes}
    with tempfile.TemporaryDirectory(prefix="peridyn_contact_builds_") as tmp:
        where = {name: C.build_dir(b, Path(tmp), name) for name, b in builds.items()}
        # The first build saves each landing once; every timed run then starts from it.
        for layers, n in sizes:
            C.run_in_build(names[0], where[names[0]], child_argv(args, layers, n, 1))
        for r in range(args.rounds):
            for name in (names if r % 2 == 0 else names[::-1]):
                for layers, n in sizes:
                    case = C.run_in_build(name, where[name],
                                          child_argv(args, layers, n, args.steps))
                    runs[f"{layers}x{n}"][name].append(case)
                    m = case["median"]
                    print(f"round {r + 1}, {name}, {layers} x {n}^2: cpu {m['cpu']:.1f} ms/step, "
                          f"wall {m['wall']:.1f} (broad {m['broad_phase']:.1f}, descent "
                          f"{m['descent']:.1f}, contact other {m['contact_other']:.1f}, "
                          f"colliders {m['colliders']:.1f}), "
                          f"load {case['loadavg_1']:.1f}", flush=True)
    summary = {}
    for key, per in runs.items():
        base = per[names[0]][0]
        summary[key] = {}
        for name in names:
            cases = per[name]
            rows = [row for c in cases for row in c["steps"]]
            same_figures = all(
                [row[f] for row in c["steps"] for f in SAME_FIGURES]
                == [row[f] for row in base["steps"] for f in SAME_FIGURES] for c in cases)
            summary[key][name] = {
                "cpu_ms_per_step_median_per_round": [c["median"]["cpu"] for c in cases],
                "cpu_ms_per_step_median": C.median([row["cpu"] for row in rows]),
                "wall_ms_per_step_median": C.median([row["wall"] for row in rows]),
                **{f"{phase}_ms_median": C.median([row[phase] for row in rows])
                   for phase in PHASES},
                "same_figures_as_first_build": same_figures,
                "same_positions_as_first_build": all(
                    c["positions_sha256"] == base["positions_sha256"] for c in cases),
            }
            print(f"{key} {name}: {summary[key][name]}", flush=True)
    rec.data["builds"] = {"builds": builds, "summary": summary, "runs": runs}


def run_case(args, layers: int, n: int, steps: int):
    cmd = [sys.executable, *child_argv(args, layers, n, steps)]
    r = subprocess.run(cmd, capture_output=True, text=True)
    lines = [line for line in r.stdout.splitlines() if line.startswith("{")]
    if r.returncode != 0 or not lines:
        case = {"layers": layers, "n": n, "failed": (r.stderr or r.stdout)[-2000:]}
        print(f"{layers} x {n}^2: FAILED\n{case['failed']}", flush=True)
        return case
    case = json.loads(lines[-1])
    m = case["median"]
    if args.until_contact and case["active_pairs_after_warmup"] == 0:
        print(f"{layers} x {n}^2: no membrane contact within {args.max_warmup} warm-up steps; "
              "its timed steps may do no CCD and no descent", flush=True)
    print(f"{layers} x {n:3d}^2 = {case['vertices']:6d} v, after {case['warmup_steps']} "
          f"warm-up steps: {m['total']:8.1f} ms/step "
          f"(global {m['global']:.1f}, broad {m['broad_phase']:.1f}, CCD {m['ccd']:.1f}, "
          f"descent {m['descent']:.1f}, contact other {m['contact_other']:.1f}, "
          f"colliders {m['colliders']:.1f}), {m['iterations']:.0f} it, {m['local_iterations']:.0f} local it, "
          f"{m['candidate_pairs']:.0f} candidates ({m['box_pairs']:.0f} boxes), "
          f"{m['primitive_pairs']:.0f} live primitive "
          f"pairs of {m['cached_pairs']:.0f} cached, {m['ccd_queries']:.0f} CCD queries, "
          f"{m['broad_phase_builds']:.0f} builds, {m['sweeps']:.0f} sweeps in "
          f"{m['live_refreshes']:.0f} filterings, "
          f"{m['active_pairs']:.0f} active, "
          f"peak {case['peak_bytes_per_vertex']:.0f} B/v, load {case['loadavg_1']:.1f}",
          flush=True)
    split = []
    for kind, b in case["broad_phase_by_build"].items():
        ms = "-" if b["ms_per_local_step"] is None else f"{b['ms_per_local_step']:.1f}"
        split.append(f"{ms} ms {kind.replace('_', ' ')} ({b['steps']} steps)")
    print("    broad phase per local step: " + ", ".join(split), flush=True)
    return case


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="1:120,1:200,3:69,3:115",
                   help="LAYERS:N cases, comma-separated (N vertices per side per layer)")
    p.add_argument("--bp-sizes", default="40,80,120,160,200",
                   help="one-layer sizes for the broad-phase sweep")
    p.add_argument("--steps", type=int, default=5, help="timed steps per case (median)")
    p.add_argument("--bp-steps", type=int, default=8, help="timed steps per broad-phase case")
    p.add_argument("--warmup", type=int, default=20, help="least steps before timing (the fall)")
    p.add_argument("--until-contact", action=argparse.BooleanOptionalAction, default=True,
                   help="warm up on until a step ends with an active membrane pair")
    p.add_argument("--max-warmup", type=int, default=1500,
                   help="most steps before timing with --until-contact")
    p.add_argument("--iters", type=int, default=10, help="global iterations per step")
    p.add_argument("--tol", type=float, default=0.0, help="0: exactly --iters iterations")
    p.add_argument("--threads", type=int, default=None)
    p.add_argument("--state-dir", default=None,
                   help="continue each case's landing saved here (saved first if missing)")
    p.add_argument("--build", action="append", default=[], metavar="NAME=WHEEL_OR_DIR",
                   help="time builds side by side on the saved landings (two or more, the "
                        "first the reference; needs --state-dir)")
    p.add_argument("--rounds", type=int, default=2, help="turns each build takes with --build")
    p.add_argument("--out", default=None)
    p.add_argument("--child", nargs=2, metavar=("LAYERS", "N"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        child(int(args.child[0]), int(args.child[1]), args.steps, args.warmup,
              args.until_contact, args.max_warmup, args.iters, args.tol, args.threads,
              args.state_dir)
        return

    sizes = [tuple(int(v) for v in s.split(":")) for s in args.sizes.split(",")]
    if args.build:
        if len(args.build) < 2 or not all("=" in b for b in args.build) or not args.state_dir:
            p.error("give two or more --build NAME=WHEEL_OR_DIR and --state-dir")
        rec = C.Record("contact_builds", args)
        compare_builds(args, sizes, rec)
        rec.write(args.out)
        return

    rec = C.Record("contact", args)
    rec.data["cases"] = [run_case(args, layers, n, args.steps) for layers, n in sizes]
    rec.data["broad_phase"] = [run_case(args, 1, int(n), args.bp_steps)
                               for n in args.bp_sizes.split(",")]
    ok = [c for c in rec.data["cases"] if "median" in c]
    rec.data["headline"] = {
        f"{c['layers']}x{c['n']}^2 ({c['vertices']} v)": {
            "ms_per_step": c["ms_step_median"],
            "warmup_steps": c["warmup_steps"],
            "ms_by_phase": {k: c["median"][k] for k in PHASES},
            "iterations": c["median"]["iterations"],
            "local_iterations": c["median"]["local_iterations"],
            "active_pairs": c["median"]["active_pairs"],
            "peak_bytes_per_vertex": c["peak_bytes_per_vertex"],
        }
        for c in ok
    }
    rec.note("Medians over the timed steps of each case; a loaded machine (see loadavg) "
             "inflates every figure.")
    path = rec.write(args.out)
    plot(rec.data, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
