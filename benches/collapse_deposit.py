"""The collapse deposit of tests/test_granular.py (issue 39) side by side: peridyn's sand and a
Drucker-Prager continuum (Taichi MLS-MPM, benches/_mpm.py) at equal particle count, in one
process, at the test's spacing and finer: what a deposit test can ask of a continuum.

Scene (the test's): a cylinder of dry sand, radius R = 6 cm, height a R with a = 1, on the
lattice of spacing ``s`` (``--spacings``, m; the test's is 1 cm) with its lowest layer half a
spacing above a plane at z = 0 with Coulomb friction 0.3, density 1600 kg/m^3, released under
gravity 9.81 m/s^2 for ``--duration`` s (0.5, the test's); friction angle phi 20, 30, 40 deg.

- peridyn: main's default sand, ``Granular(friction_angle=phi)``, stepped by the test's
  ``settle`` (dt 1/500 s, 10 iterations, tol 0); on the perfect lattice (the test's column) and
  on the lattice jittered by ``--jitter`` spacings (every site moved by an offset uniform in a
  ball, as the repose test's packing, seeds ``--seeds``; a site pushed below half a spacing is
  raised to it, the plane's margin).
- MPM: the same lattice sites (one particle per site, volume s^3), grid spacing 2 s, St.
  Venant-Kirchhoff in Hencky strain, E = ``--mpm-young`` Pa, nu 0.3, the outer Drucker-Prager
  cone at phi without cohesion (Klar et al. 2016), floor friction 0.3, explicit steps at CFL
  0.4; on the perfect lattice and, with ``--mpm-jitter``, the same jittered packings.

Measured per run, all by the test's definitions (``runout`` and ``slope_angle`` imported from
tests/test_granular.py, so the flank is the SAME fit: rings 1 cm wide, the highest particle
of each, least squares over the rings with tops above 1.5 cm): the runout dR / R (Lube et al.
2004: 1.24 a for a < 1.7); the middle's height (the highest particle within 1.5 cm of the axis
plus half a spacing, over the column's height: Lube et al. find it kept, 1, for a < 1.15);
the flank slope (degrees); wall seconds (MPM's after a warm-up that compiles its kernels).

    python benches/collapse_deposit.py        # both at 1 and 0.5 cm, MPM also at 0.25 cm
    python benches/collapse_deposit.py --spacings 0.01 --seeds 0      # a quick look

Writes benches/results/collapse_deposit.json (``--out``), after every run (a partial run
keeps what it measured). Timings on a shared machine are upper bounds (the record carries the
load average).
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path
from types import SimpleNamespace

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
import _common as C  # noqa: E402
import test_granular as tg  # noqa: E402

import peridyn as pd  # noqa: E402

RADIUS, ASPECT, FLOOR = 0.06, 1.0, 0.3
MIDDLE = 0.015  # the middle's radius (m): 1.5 of the test's spacings


def sites(spacing: float, jitter: float, seed: int) -> np.ndarray:
    """The column's lattice sites (m), as tests/test_granular.py's ``column`` at ``spacing``;
    with ``jitter`` (spacings) each moved by an offset uniform in a ball of that radius
    (``seed``), none below half a spacing."""
    n = int(round(RADIUS / spacing))
    layers = int(round(ASPECT * RADIUS / spacing))
    g = np.arange(-n, n + 1) * spacing
    x, y, z = np.meshgrid(g, g, (np.arange(layers) + 0.5) * spacing, indexing="ij")
    p = np.stack([x, y, z], -1).reshape(-1, 3)
    p = p[np.hypot(p[:, 0], p[:, 1]) <= RADIUS + 1e-9]
    if jitter:
        rng = np.random.default_rng(seed)
        direction = rng.standard_normal(p.shape)
        direction /= np.linalg.norm(direction, axis=1)[:, None]
        p = p + direction * (jitter * spacing * rng.random(len(p)) ** (1.0 / 3.0))[:, None]
        p[:, 2] = np.maximum(p[:, 2], 0.5 * spacing)
    return p


def deposit(positions: np.ndarray, spacing: float) -> dict:
    """The test's measures of a deposit (see the module's docstring)."""
    body = SimpleNamespace(positions=positions)
    r = np.hypot(positions[:, 0], positions[:, 1])
    middle = positions[r < MIDDLE, 2].max() + 0.5 * spacing
    return {"runout": float((tg.runout(body) - RADIUS) / RADIUS),
            "middle_over_height": float(middle / (ASPECT * RADIUS)),
            "slope_deg": float(tg.slope_angle(body))}


def ours(p: np.ndarray, spacing: float, angle: float, a) -> dict:
    body = pd.Particles(p, spacing=spacing, density=tg.RHO, material=tg.sand(angle))
    t = time.perf_counter()
    tg.settle(body, a.duration, threads=a.threads)
    wall = time.perf_counter() - t
    return {"wall_s": wall, **deposit(np.asarray(body.positions), spacing)}


def mpm(p: np.ndarray, spacing: float, angle: float, a) -> dict:
    from _mpm import sand_column

    m = sand_column(p, spacing=spacing, radius=RADIUS, height=ASPECT * RADIUS, density=tg.RHO,
                    young=a.mpm_young, friction_angle=angle, floor_friction=FLOOR,
                    threads=a.threads)
    steps, wall = m.timed(a.duration)
    return {"wall_s": wall, "dt": m.dt, "steps": steps, "grid_cells": list(m.cells),
            **deposit(m.positions(), spacing)}


def summary(runs: list) -> dict:
    """Per (solver, spacing, packing, phi): median, min and max of each measure over seeds."""
    out = {}
    for r in runs:
        if "error" in r:
            continue
        key = f"{r['solver']} s={r['spacing_m']:g} {r['packing']} phi={r['phi_deg']:g}"
        out.setdefault(key, []).append(r)
    return {k: {m: {"median": C.median([r[m] for r in v]), "min": min(r[m] for r in v),
                    "max": max(r[m] for r in v), "n": len(v)}
                for m in ("runout", "middle_over_height", "slope_deg", "wall_s")}
            for k, v in out.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spacings", type=float, nargs="+", default=[0.01, 0.005, 0.0025],
                    help="lattice spacings (m)")
    ap.add_argument("--ours-spacings", type=float, nargs="*", default=[0.01, 0.005],
                    help="the spacings (m) at which peridyn runs too (MPM runs at every one)")
    ap.add_argument("--angles", type=float, nargs="+", default=[20.0, 30.0, 40.0],
                    help="friction angles (degrees)")
    ap.add_argument("--seeds", type=int, nargs="*", default=[0, 1, 2],
                    help="seeds of the jittered packings")
    ap.add_argument("--jitter", type=float, default=0.1, help="jitter radius (spacings)")
    ap.add_argument("--mpm-jitter", action="store_true",
                    help="also run MPM on the jittered packings")
    ap.add_argument("--duration", type=float, default=0.5, help="simulated time (s)")
    ap.add_argument("--mpm-young", type=float, default=3.5e5, help="MPM's Young's modulus (Pa)")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--only", choices=["ours", "mpm"], help="run one solver only")
    ap.add_argument("--out", help="JSON path (default benches/results/collapse_deposit.json)")
    args = ap.parse_args()

    rec = C.Record("collapse_deposit", args)
    rec.data["runs"] = runs = []
    packings = [("lattice", 0)] + [("jitter", seed) for seed in args.seeds]
    for spacing in args.spacings:
        for solver, run in (("ours", ours), ("mpm", mpm)):
            if (args.only and solver != args.only) or (
                    solver == "ours" and not any(np.isclose(spacing, args.ours_spacings))):
                continue
            for packing, seed in packings:
                if solver == "mpm" and packing == "jitter" and not args.mpm_jitter:
                    continue
                p = sites(spacing, args.jitter if packing == "jitter" else 0.0, seed)
                for angle in args.angles:
                    head = {"solver": solver, "spacing_m": spacing, "packing": packing,
                            "seed": seed, "phi_deg": angle, "particles": len(p)}
                    try:
                        r = {**head, **run(p, spacing, angle, args)}
                    except Exception as e:  # a run that fails is recorded, not fatal
                        traceback.print_exc()
                        r = {**head, "error": f"{type(e).__name__}: {e}"}
                    runs.append(r)
                    print(" ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                   for k, v in r.items() if k != "grid_cells"), flush=True)
                    rec.data["summary"] = summary(runs)
                    rec.write(args.out)


if __name__ == "__main__":
    main()
