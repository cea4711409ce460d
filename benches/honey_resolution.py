"""Does the dripping honey draw a thread at a finer resolution? (issue 40)

The physical blob of ``tests/test_viscoelastic.py``'s ``honey_under_a_ceiling`` (about 5 x 5 x 6
cm of liquid, 1400 kg/m^3, under a ceiling of two layers of pinned ghost particles, adhesion,
Jacobi global solver, gravity 9.81 m/s^2) sampled with ``n`` particles across (spacing
``0.05 / n`` m, ``round(1.2 n)`` particles tall), for the test's viscoelastic honey (10 Pa s,
G = 500 Pa, yield stress 500 Pa) and a Newtonian one (10 Pa s, G = 0). Each run goes in a fresh
process (its peak resident memory is its own) for ``--time`` seconds (0.4: the test's) at
``--dt`` (5 ms: the test's step; with ``--scale-dt``, ``dt * 5 / n``, the test's Courant
number at every size) and reports:

* ``parts_s``: the first time two consecutive particle depths (sorted) are more than 2.2
  spacings apart (round aa's criterion), None if never;
* ``depth_end``: the lowest particle's depth below the ceiling's lowest layer at the end, in
  spacings and cm;
* ``slabs_filled`` / ``slabs_missing``: of the spacing-tall slabs 1 .. floor(depth) - 1
  between the film and the lowest particle, those holding liquid and the empty ones (the
  strict xfail asks depth > 10 spacings and none missing);
* ``samples``: at every ``--sample`` seconds, the slab profile of the liquid still hanging
  from the film (above the first gap of 2.2 spacings): counts and rms radii per slab, its neck
  (thinnest pair of slabs between film and drop, as a fraction of the n^2 of a full layer),
  the neck's length (slabs holding at most a quarter of a layer: a neck drawn over several
  slabs is a thread) and its narrowest slab's rms radius (a fraction of a full layer's); see
  :func:`attached`;
* ``diverged`` (a ``DivergenceError``, with its step), ``seconds_per_step`` (wall), and
  ``peak_rss_mib`` (the process's ``VmHWM``).

Usage (sizes small to large; a size whose run is predicted to take longer than
``--max-minutes`` (:func:`predicted_seconds`) is only probed, ``--probe-steps`` steps, and is
the last):

    nice python benches/honey_resolution.py --sizes 5 9 13 17 25 33
    nice python benches/honey_resolution.py --sizes 5 9 13 17 25 --scale-dt \
        --out benches/results/honey_resolution_scaled_dt.json
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
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from _common import Record, vm_kib  # noqa: E402
from fluid_scenes import (  # noqa: E402
    PARTING_GAP as GAP, blob_under_a_ceiling, hanging_slabs, neck_slabs, widest_pair)

WIDTH = 0.05  # m, the blob's side (the test's 5 particles of 1 cm)
MATERIALS = {
    "viscoelastic": dict(viscosity=10.0, shear_modulus=500.0, yield_stress=500.0),
    "newtonian": dict(viscosity=10.0),
}


def slab_counts(depth):
    """Particle counts of the spacing-tall slabs 0 .. floor(max depth) (depth in spacings below
    the ceiling's lowest layer; the film, at about 1.0, falls on the edge of slabs 0 and 1): the
    test's slabs."""
    return np.bincount(np.clip(np.floor(depth).astype(int), 0, None))


def attached(depth, radial, layer):
    """The liquid hanging from the film (:func:`fluid_scenes.hanging_slabs`: above the first gap
    of more than ``GAP`` spacings between consecutive depths). ``radial`` is each particle's
    squared in-plane distance from the blob's axis (spacings^2). Returns its slab profile
    (slab 0 the film): counts and rms in-plane radii (spacings); its neck (the thinnest mean
    count of two neighbouring slabs between the film and the drop's lowest widest pair, as a
    fraction of a full layer), the neck's length (:func:`fluid_scenes.neck_slabs`) and the
    narrowest of the neck's slabs' rms radii as a fraction of a full rest layer's."""
    keep, slab = hanging_slabs(depth)
    counts = np.bincount(slab)
    sums = np.bincount(slab, weights=radial[keep], minlength=counts.size)
    radius = np.sqrt(sums / np.maximum(counts, 1))
    full = np.sqrt((layer - 1) / 6.0)  # rms radius of an n x n layer of unit spacing
    out = {"counts": counts.tolist(), "radius": np.round(radius, 3).tolist(), "neck": None,
           "thin_slabs": neck_slabs(counts, layer), "narrowest": None}
    if counts.size > 2:
        widest, pairs = widest_pair(counts)
        filled = np.flatnonzero(counts[1: widest + 2] > 0) + 1
        out.update(neck=float(pairs[: widest + 1].min()) / layer,
                   narrowest=float(radius[filled].min() / full) if filled.size else None)
    return out


class Tracker:
    """The metrics of one run of the blob, fed its liquid's positions as it goes: ``n`` particles
    across at ``spacing`` m, ``top`` the ceiling's lowest layer (m, z up), the blob's axis at
    x = y = ``axis`` (m). :meth:`observe` at every step or frame (``sample``: also record the
    slab profile of :func:`attached`), :meth:`finish` with the last positions. A frame holds a
    thread when the strict xfail's test would pass on it: the lowest particle more than
    ``drip`` spacings down (the test's 10) and every slab between it and the film holding
    liquid (``thread_frames``:
    the first and last such frame, their count, the fewest particles in a slab and the
    deepest lowest particle, in spacings, over them)."""

    def __init__(self, n, spacing, top, axis, drip=10.0):
        self.n, self.spacing, self.top, self.axis, self.drip = n, spacing, top, axis, drip
        self.parts_s = None
        self.samples = []
        self.thread = {"first_s": None, "last_s": None, "frames": 0, "thinnest": None,
                       "deepest": 0.0}

    def depth(self, pos):
        return (self.top - pos[:, 2]) / self.spacing

    def observe(self, t, pos, sample):
        depth = self.depth(pos)
        if self.parts_s is None and np.diff(np.sort(depth)).max() > GAP:
            self.parts_s = round(t, 6)
        between = slab_counts(depth)[1: int(depth.max())]
        if depth.max() > self.drip and between.min() > 0:
            th = self.thread
            th["first_s"] = th["first_s"] if th["first_s"] is not None else round(t, 6)
            th["last_s"] = round(t, 6)
            th["frames"] += 1
            thinnest = int(between.min())
            th["thinnest"] = thinnest if th["thinnest"] is None else min(th["thinnest"], thinnest)
            th["deepest"] = max(th["deepest"], float(depth.max()))
        if sample:
            radial = ((pos[:, 0] - self.axis) ** 2 + (pos[:, 1] - self.axis) ** 2) / self.spacing**2
            self.samples.append({"t": round(t, 6), "depth": float(depth.max()),
                                 **attached(depth, radial, self.n * self.n)})

    def finish(self, pos):
        """The end of the run: the first parting, the depth reached, the slabs filled and missing
        between film and drop and whether that is the strict xfail's thread."""
        depth = self.depth(pos)
        counts = slab_counts(depth)
        between = counts[1: int(depth.max())]
        out = {"parts_s": self.parts_s, "samples": self.samples, "thread_frames": self.thread,
               "depth_end": float(depth.max()),
               "depth_end_cm": float(depth.max()) * self.spacing * 100.0,
               "slabs_filled": int((between > 0).sum()),
               "slabs_missing": int((between == 0).sum())}
        out["thread"] = bool(out["depth_end"] > self.drip and out["slabs_missing"] == 0)
        return out


def run_one(material, n, dt, end, sample, steps_cap, drip=10.0):
    """One run in this process; returns its record."""
    import peridyn as pd

    spacing = WIDTH / n
    tall = int(round(1.2 * n))
    x, ceiling = blob_under_a_ceiling(n, tall, spacing)
    honey = pd.Particles(x, spacing=spacing, density=1400.0,
                         material=pd.ViscoelasticFluid(adhesion=True, **MATERIALS[material]))
    honey.pin(np.flatnonzero(ceiling))
    solver = pd.Solver(dt=dt, gravity=(0, 0, -9.81), global_solver="jacobi")
    solver.add(honey)
    tracker = Tracker(n, spacing, x[ceiling, 2].min(), 0.5 * WIDTH, drip)
    steps = int(round(end / dt))
    if steps_cap:
        steps = min(steps, steps_cap)
    every = max(1, int(round(sample / dt)))
    out = {"material": material, "n": n, "tall": tall, "spacing_m": spacing, "dt": dt,
           "particles": int((~ceiling).sum()), "ghosts": int(ceiling.sum()), "steps": steps,
           "diverged": None}
    wall = 0.0
    done = 0
    for step in range(1, steps + 1):
        t0 = time.perf_counter()
        try:
            solver.step()
        except pd.DivergenceError as err:
            out["diverged"] = {"step": step, "message": str(err)[:300]}
            break
        wall += time.perf_counter() - t0
        done = step
        tracker.observe(step * dt, honey.positions[~ceiling],
                        step % every == 0 or step == steps)
    out["steps_done"] = done
    out["seconds_per_step"] = wall / max(done, 1)
    out.update(tracker.finish(honey.positions[~ceiling]))
    out["peak_rss_mib"] = vm_kib("VmHWM") / 1024.0
    return out


def child(args):
    res = run_one(args.material, args.n, args.dt, args.time, args.sample, args.cap_steps)
    print(json.dumps(res))


def predicted_seconds(took, n, n_next):
    """A run's wall time at ``n_next`` across from one at ``n`` (``took`` s): the particle count
    to the power 1.5 (measured on 17 -> 25 at dt 5 ms, the viscoelastic honey: 3.2 times the
    particles, 5.7-7.3 times the time under load)."""
    return took * (n_next / n) ** 4.5


def parent(args):
    rec = Record("honey_resolution", args)
    rec.data["runs"] = []
    rec.data["probes"] = []
    path = Path(args.out) if args.out else None
    if args.append:
        old = json.loads((path or Path(__file__).parent / "results" /
                          "honey_resolution.json").read_text())
        rec.data["runs"], rec.data["probes"] = old["runs"], old["probes"]
        rec.data["earlier"] = {k: old[k] for k in ("command", "machine_start", "notes")}
    probe = args.probe_only
    for i, n in enumerate(args.sizes):
        longest = 0.0
        for material in args.materials:
            dt = args.dt * 5.0 / n if args.scale_dt else args.dt
            argv = [sys.executable, __file__, "--child", "--material", material, "--n", str(n),
                    "--dt", repr(dt), "--time", str(args.time), "--sample",
                    str(args.sample)]
            if probe:
                argv += ["--cap-steps", str(args.probe_steps)]
            t0 = time.perf_counter()
            try:
                done = subprocess.run(argv, capture_output=True, text=True,
                                      timeout=4.0 * args.max_minutes * 60.0)
            except subprocess.TimeoutExpired:
                rec.note(f"{material} n={n} stopped after {4.0 * args.max_minutes:.0f} min "
                         "(four times --max-minutes)")
                continue
            took = time.perf_counter() - t0
            longest = max(longest, took)
            if done.returncode != 0:
                rec.note(f"{material} n={n} failed: {done.stderr[-2000:]}")
                continue
            res = json.loads(done.stdout.strip().splitlines()[-1])
            res["process_seconds"] = took
            (rec.data["probes"] if probe else rec.data["runs"]).append(res)
            last = res["samples"][-1] if res["samples"] else {}
            print(f"{material:12s} n={n:2d} {'probe ' if probe else ''}parts {res['parts_s']} "
                  f"depth {res.get('depth_end', 0):.1f} sp ({res.get('depth_end_cm', 0):.1f} cm)"
                  f" filled/missing {res['slabs_filled']}/{res['slabs_missing']} neck "
                  f"{last.get('neck')} div {res['diverged'] is not None} "
                  f"{res['seconds_per_step']:.3f} s/step {res['peak_rss_mib']:.0f} MiB "
                  f"({took:.0f} s)", flush=True)
            rec.write(args.out)
        if probe:
            break
        if i + 1 < len(args.sizes):
            guess = predicted_seconds(longest, n, args.sizes[i + 1])
            probe = guess > args.max_minutes * 60.0
            if probe:
                rec.note(f"n={args.sizes[i + 1]} probed ({args.probe_steps} steps): a full run "
                         f"predicted at {guess / 60.0:.0f} min from n={n}'s {longest:.0f} s")
    rec.write(args.out)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[5, 9, 13, 17, 25])
    p.add_argument("--materials", nargs="+", default=list(MATERIALS), choices=list(MATERIALS))
    p.add_argument("--dt", type=float, default=0.005, help="s (the test's 5 ms)")
    p.add_argument("--scale-dt", action="store_true",
                   help="step dt * 5 / n: the test's Courant number at every size")
    p.add_argument("--time", type=float, default=0.4, help="simulated s (the test's 0.4)")
    p.add_argument("--sample", type=float, default=0.01, help="s between slab profiles")
    p.add_argument("--max-minutes", type=float, default=15.0,
                   help="a size whose run is predicted longer than this is probed, the last")
    p.add_argument("--probe-only", action="store_true",
                   help="only probe the first size given")
    p.add_argument("--append", action="store_true",
                   help="add to the runs and probes already in the output JSON")
    p.add_argument("--probe-steps", type=int, default=3, help="steps of a probed size")
    p.add_argument("--out", default=None, help="JSON path (default benches/results/...)")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--material", help=argparse.SUPPRESS)
    p.add_argument("--n", type=int, help=argparse.SUPPRESS)
    p.add_argument("--cap-steps", type=int, default=0, help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        child(args)
    else:
        parent(args)


if __name__ == "__main__":
    main()
