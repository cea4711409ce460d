"""Cost of a step against vertex count: ms per step and peak memory per vertex.

A square cloth of n x n vertices (1 m, pinned along one edge, gravity, A3 s0 = 2e4 Pa, 1 mm,
h = 1e-3 s), exactly 10 iterations per step (tol = 0), no contact, for f32 and f64 and 1 and 2
threads. Each (n, precision, threads) runs in a fresh subprocess, one after another, so that
the peak resident memory (``VmHWM`` of /proc/self/status, which sees the Rust allocations that
tracemalloc cannot) belongs to that case alone: memory per vertex is
``(VmHWM after the steps - VmHWM before the membrane is built) / n^2``; the mesh arrays built in
numpy before the baseline are not counted. ms per step is the median over ``--steps`` timed steps
after ``--warmup`` steps of the step's own ``timings['total']``; the wall-clock median of the
``step()`` call is recorded too, and the process CPU time per step over the wall time
(``cores_busy``: below the thread count when other work on the machine takes the cores).

Default (about a minute):      python benches/scaling.py
Full size (1.6K .. 160K):      python benches/scaling.py --sizes 40,80,120,200,283,400 --steps 15
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


def child(n: int, precision: str, threads: int, steps: int, warmup: int, iters: int, dt: float):
    """Runs in the subprocess: prints one JSON line."""
    import os

    import peridyn

    V, F = peridyn.grid(n, n, size=(1.0, 1.0), diagonal="alternate")
    pins = np.flatnonzero(np.isclose(V[:, 1], 1.0))
    hwm0, rss0 = C.vm_kib("VmHWM"), C.vm_kib("VmRSS")
    cloth = peridyn.Membrane(V, F, thickness=1e-3, density=300.0,
                             material=peridyn.StretchA3(s0=2e4),
                             bending=peridyn.plate_bending_stiffness(4e4, 0.0, 1e-3))
    cloth.pin(pins)
    solver = peridyn.Solver(dt=dt, tol=0.0, max_iters=iters, threads=threads, precision=precision)
    solver.add(cloth)
    hwm_built = C.vm_kib("VmHWM")
    totals, walls, globals_, its, cpus = [], [], [], [], []
    for k in range(warmup + steps):
        c0, t0 = time.process_time(), time.perf_counter()
        st = solver.step()
        w = (time.perf_counter() - t0) * 1e3
        if k >= warmup:
            cpus.append((time.process_time() - c0) * 1e3)
            totals.append(st.timings["total"])
            globals_.append(st.timings["global"])
            walls.append(w)
            its.append(st.iterations)
    hwm1, rss1 = C.vm_kib("VmHWM"), C.vm_kib("VmRSS")
    nv = n * n
    print(json.dumps({
        "n": n, "vertices": nv, "precision": precision, "threads": threads,
        "iterations": its, "ms_step_median": float(np.median(totals)),
        "ms_step_all": totals, "ms_global_median": float(np.median(globals_)),
        "ms_wall_median": float(np.median(walls)),
        "cpu_ms_step_median": float(np.median(cpus)),
        "cores_busy": float(np.median(cpus) / np.median(walls)),
        "us_per_vertex": float(np.median(totals)) * 1e3 / nv,
        "peak_bytes_per_vertex": (hwm1 - hwm0) * 1024.0 / nv,
        "peak_bytes_per_vertex_after_build": (hwm_built - hwm0) * 1024.0 / nv,
        "rss_bytes_per_vertex": (rss1 - rss0) * 1024.0 / nv,
        "VmHWM_kib": [hwm0, hwm_built, hwm1],
        "lowest_z": float(cloth.positions[:, 2].min()),
        "loadavg_1": os.getloadavg()[0],
    }), flush=True)


def plot(data, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [r for r in data["cases"] if "ms_step_median" in r]
    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(16, 4.8))
    for prec in ("f32", "f64"):
        for th in sorted({r["threads"] for r in rows}):
            rr = sorted([r for r in rows if r["precision"] == prec and r["threads"] == th],
                        key=lambda r: r["vertices"])
            if not rr:
                continue
            x = [r["vertices"] for r in rr]
            lab = f"{prec}, {th} thread{'s' if th > 1 else ''}"
            ls = "-" if prec == "f32" else "--"
            a1.loglog(x, [r["ms_step_median"] for r in rr], ls, marker="o", label=lab)
            a2.semilogx(x, [r["us_per_vertex"] for r in rr], ls, marker="o", label=lab)
            a3.semilogx(x, [r["peak_bytes_per_vertex"] for r in rr], ls, marker="o", label=lab)
    if rows:
        xs = np.array(sorted({r["vertices"] for r in rows}), float)
        a1.loglog(xs, 10.0 * xs / 14400, "k:", lw=1, label="target: 10 ms at 14.4K, linear")
        a3.axhline(1024, color="k", ls=":", lw=1, label="target: 1 KiB / vertex")
    if rows:
        from matplotlib.ticker import NullFormatter

        for a in (a1, a2, a3):
            a.set_xticks(xs, [f"{v / 1000:.3g}K" for v in xs])
            a.xaxis.set_minor_formatter(NullFormatter())
    a1.set(xlabel="vertices", ylabel="ms per step (median, 10 iterations)", title="time per step")
    a2.set(xlabel="vertices", ylabel="microseconds per vertex per step", title="time per vertex")
    a3.set(xlabel="vertices", ylabel="peak memory (bytes / vertex)", title="peak memory (VmHWM delta)")
    for a in (a1, a2, a3):
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=8)
    m = data["machine_start"]
    fig.suptitle(f"peridyn scaling: h=1e-3, 10 iterations, no contact; load {m['loadavg_1_5_15'][0]:.1f} "
                 f"on {m['cpu_count']} CPUs (shared machine: medians)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sizes", default="40,80,120,200", help="vertices per side, comma-separated")
    p.add_argument("--precisions", default="f32,f64")
    p.add_argument("--threads", default="1,2")
    p.add_argument("--steps", type=int, default=7, help="timed steps per case (median)")
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument("--iters", type=int, default=10)
    p.add_argument("--dt", type=float, default=1e-3)
    p.add_argument("--out", default=None)
    p.add_argument("--child", nargs=3, metavar=("N", "PRECISION", "THREADS"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        n, prec, th = args.child
        child(int(n), prec, int(th), args.steps, args.warmup, args.iters, args.dt)
        return

    rec = C.Record("scaling", args)
    cases = []
    for n in [int(s) for s in args.sizes.split(",")]:
        for prec in args.precisions.split(","):
            for th in [int(t) for t in args.threads.split(",")]:
                cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(n), prec, str(th),
                       "--steps", str(args.steps), "--warmup", str(args.warmup),
                       "--iters", str(args.iters), "--dt", str(args.dt)]
                r = subprocess.run(cmd, capture_output=True, text=True)
                lines = [l for l in r.stdout.splitlines() if l.startswith("{")]
                if r.returncode != 0 or not lines:
                    case = {"n": n, "precision": prec, "threads": th,
                            "failed": (r.stderr or r.stdout)[-2000:]}
                    print(f"{n:4d}^2 {prec} t{th}: FAILED\n{case['failed']}", flush=True)
                else:
                    case = json.loads(lines[-1])
                    print(f"{n:4d}^2 = {n*n:6d} v  {prec} t{th}: {case['ms_step_median']:8.2f} ms/step "
                          f"({case['us_per_vertex']:.3f} us/v, CPU/wall {case['cores_busy']:.2f}), peak {case['peak_bytes_per_vertex']:7.0f} B/v, "
                          f"load {case['loadavg_1']:.1f}", flush=True)
                cases.append(case)
    rec.data["cases"] = cases
    ok = [c for c in cases if "ms_step_median" in c]
    target = [c for c in ok if c["n"] == 120 and c["precision"] == "f32"]
    rec.data["headline"] = {
        "ms_per_step_120x120_f32": {str(c["threads"]): c["ms_step_median"] for c in target},
        "target": "<= 10 ms per step at 120x120 f32, 10 iterations, h=1e-3 (issue 4); "
                  "<= 1 KiB per vertex; linear in vertex count",
        "max_peak_bytes_per_vertex": max((c["peak_bytes_per_vertex"] for c in ok if c["vertices"] >= 14400),
                                         default=None),
    }
    # Linearity: us per vertex at the largest size over that at the smallest >= 14.4K.
    for prec in ("f32", "f64"):
        for th in {c["threads"] for c in ok}:
            rr = sorted([c for c in ok if c["precision"] == prec and c["threads"] == th],
                        key=lambda c: c["vertices"])
            if len(rr) >= 2:
                rec.data["headline"][f"us_per_vertex_ratio_largest_over_smallest_{prec}_t{th}"] = (
                    rr[-1]["us_per_vertex"] / rr[0]["us_per_vertex"])
    path = rec.write(args.out)
    plot(rec.data, path.with_suffix(".png"))


if __name__ == "__main__":
    main()
