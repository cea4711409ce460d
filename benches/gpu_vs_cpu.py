"""Milliseconds per time step of the GPU backend beside the CPU backend, in the same run.

A 120 x 120 cloth (14 400 vertices, 1-ring, bending and hourglass) pinned along one edge
swings onto a sphere and a turned box with friction (every vertex tests both colliders in
every iteration). Every step runs exactly ``--iters`` global iterations (tol = 0), so both
backends do the same work; the first ``--warmup`` steps are not timed. For each backend the
median over ``--repeats`` fresh runs of the median ms per step is reported, with the bytes the
GPU kernels load and store per iteration and the effective bandwidth that implies.

On Mesa's lavapipe the "GPU" is the CPU driver: the JSON records the adapter name and device
type so the figure is not mistaken for a GPU's.

    python benches/gpu_vs_cpu.py --steps 5 --out benches/results/gpu_vs_cpu.json
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time

import numpy as np

import peridyn


def scene(n: int, backend: str, precision: str, iters: int):
    v, f = peridyn.grid(n, n, size=(1.0, 1.0), diagonal="alternate")
    cloth = peridyn.Membrane(v, f, thickness=1e-3, density=300.0,
                             material=peridyn.StretchA3(s0=2e4), bending=1e-4, hourglass=0.5)
    cloth.pin(np.flatnonzero(np.isclose(v[:, 1], 1.0)))
    kw = dict(dt=2e-3, tol=0.0, max_iters=iters, acceleration="chebyshev")
    solver = peridyn.Solver(backend=backend, precision=precision, **kw)
    solver.add(cloth)
    solver.add_collider(peridyn.Sphere(center=(0.5, 0.45, -0.3), radius=0.25))
    c, s = np.cos(0.3), np.sin(0.3)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    solver.add_collider(peridyn.Box(center=(0.5, 0.2, -0.45), half_extents=(0.3, 0.1, 0.1),
                                    rotation=turn, friction=0.5))
    return solver, cloth


def ms_per_step(n, backend, precision, iters, steps, warmup):
    solver, _ = scene(n, backend, precision, iters)
    for _ in range(warmup):
        solver.step()
    times = []
    for _ in range(steps):
        t = time.perf_counter()
        solver.step()
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times), solver


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=120, help="vertices per side")
    p.add_argument("--iters", type=int, default=20, help="global iterations per step")
    p.add_argument("--steps", type=int, default=5, help="timed steps per run")
    p.add_argument("--warmup", type=int, default=1, help="untimed steps per run")
    p.add_argument("--repeats", type=int, default=3, help="runs per backend (median)")
    p.add_argument("--out", default="benches/results/gpu_vs_cpu.json")
    a = p.parse_args()

    info = peridyn.gpu_info()
    results = {}
    runs_to_do = [("cpu_f32", "cpu", "f32"), ("cpu_f64", "cpu", "f64"), ("gpu_f32", "gpu", "f32")]
    if info["f64"]:
        runs_to_do.append(("gpu_f64", "gpu", "f64"))
    for label, backend, precision in runs_to_do:
        runs = []
        for _ in range(a.repeats):
            ms, solver = ms_per_step(a.n, backend, precision, a.iters, a.steps, a.warmup)
            runs.append(ms)
        entry = {
            "ms_per_step_median": statistics.median(runs),
            "ms_per_step_runs": runs,
            # the step's fixed costs (upload, initial guess, read-back) shared out
            "ms_per_iteration": statistics.median(runs) / a.iters,
            "threads": solver.threads,
        }
        if backend == "gpu":
            entry["bytes_per_iteration"] = solver.bytes_per_iteration
            entry["effective_GB_per_s"] = (
                solver.bytes_per_iteration / (entry["ms_per_iteration"] * 1e-3) / 1e9)
        results[label] = entry
        print(f"{label}: {statistics.median(runs):.1f} ms/step ({runs})", flush=True)
    gpu = results["gpu_f32"]
    out = {
        "benchmark": "gpu_vs_cpu",
        "scene": (f"{a.n}x{a.n} cloth, 1-ring, bending + hourglass, pinned edge, sphere and "
                  "box (friction 0.5) colliders"),
        "vertices": a.n * a.n,
        "iterations_per_step": a.iters,
        "timed_steps_per_run": a.steps,
        "warmup_steps": a.warmup,
        "repeats": a.repeats,
        "adapter": info,
        "note": ("device_type 'Cpu' means a software driver (lavapipe): this measures the "
                 "driver on the CPU, not a GPU"),
        "machine": {"cpus": os.cpu_count(), "platform": platform.platform()},
        "peridyn": peridyn.__version__,
        "results": results,
        "gpu_over_cpu_f32": gpu["ms_per_step_median"] / results["cpu_f32"]["ms_per_step_median"],
    }
    os.makedirs(os.path.dirname(a.out) or ".", exist_ok=True)
    with open(a.out, "w") as fh:
        json.dump(out, fh, indent=2)
    print(json.dumps({k: out[k] for k in ("adapter", "gpu_over_cpu_f32")}, indent=2))


if __name__ == "__main__":
    main()
