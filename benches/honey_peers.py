"""Does a reference method draw the honey thread in the strict xfail's scene? (issue 40)

The physical blob of ``tests/test_viscoelastic.py``'s ``honey_under_a_ceiling`` (5 x 5 x 6 cm,
1400 kg/m^3, gravity 9.81 m/s^2, 0.4 s) held at its top, sampled with ``n`` particles across
(spacing ``0.05 / n`` m, ``round(1.2 n)`` tall, the particles of ``blob_under_a_ceiling``), in
three methods side by side:

* ``peridyn``: main's model as ``benches/honey_resolution.py`` runs it (pinned two-layer ghost
  ceiling, adhesion, Jacobi global solver, dt 5 ms), in this process;
* ``mpm``: Taichi MLS-MPM on the CPU (``benches/_mpm.py``), in this process, with the liquid's
  particles at the same lattice sites (volume spacing^3), a grid of ``dx`` = 2 spacings (8
  particles a cell) and/or 1 spacing (1 a cell), the top held by sticky grid nodes (every node
  at or above the liquid's top face, z = 0, has zero velocity: the ghosts' counterpart, holding
  in tension); ``"viscous"`` (the Newtonian liquid: two-sided weakly compressible pressure,
  speed of sound ``--sound-speed``, bulk modulus ``1400 c^2``, plus 10 Pa s) and ``"honey"``
  (the same plus G = 500 Pa and a von Mises yield stress of 500 Pa, as the test's honey);
* ``sph``: pySPlisHSPlasH's DFSPH with Weiler 2018 viscosity at 10 Pa s, Newtonian only
  (SPlisHSPlasH has no elastoplastic liquid), in a subprocess per run
  (``benches/_dfsph_honey.py``: its holds, ``ghosts`` and ``lid`` with or without Akinci 2013
  adhesion).

Every method's liquid positions go to :class:`honey_resolution.Tracker` (depth below the ghosts'
lowest layer, z = 0.5 spacings: the film at 1): ``parts_s`` (first gap of more than 2.2
spacings), the depth at the end, the filled / missing slabs between film and drop (the test
asks depth > 10 spacings and none missing), ``thread_frames`` (the frames on which the test
would pass, its 10 spacings taken as 10 cm at every size: first, last, the fewest particles in a
slab), the slab profiles of the hanging
liquid every 0.01 s (neck, rms radii); and the wall seconds per simulated second. peridyn's
frames are its 5 ms steps, MPM's and SPH's every ``--frame`` s (2.5 ms).

    nice python benches/honey_peers.py                      # n = 5 9 13 17, about 15 min
    nice python benches/honey_peers.py --sizes 5 --methods mpm
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from _common import Record  # noqa: E402
from fluid_scenes import blob_under_a_ceiling  # noqa: E402
from honey_resolution import WIDTH, Tracker, run_one  # noqa: E402

DENSITY = 1400.0  # kg/m^3
VISCOSITY = 10.0  # Pa s
SHEAR_MODULUS = 500.0  # Pa
YIELD_STRESS = 500.0  # Pa, uniaxial von Mises
DEPTH = 0.95  # m of grid below the blob's top face (the drop falls about 0.8 m in 0.4 s)
SIDE = 0.025  # m of grid beside the blob on every side
DRIP = 0.1  # m: a frame holds a thread with its lowest particle this far down (the test's 10 cm)
MPM_MATERIAL = {"newtonian": "viscous", "viscoelastic": "honey"}
GL_DISPATCH = "/usr/lib/x86_64-linux-gnu/libGLdispatch.so.0"


def mpm_run(material, n, per_dx, sound_speed, end, frame, sample):
    """One MLS-MPM run of the blob at ``n`` across on a grid of ``per_dx`` spacings; its record."""
    from _mpm import Mpm

    spacing = WIDTH / n
    x, ceiling = blob_under_a_ceiling(n, int(round(1.2 * n)), spacing)
    dx = per_dx * spacing
    side = math.ceil(SIDE / dx) * dx
    low = (-side, -side, -math.ceil(DEPTH / dx) * dx)
    high = (WIDTH + side, WIDTH + side, 2 * dx)
    extra = {"shear_modulus": SHEAR_MODULUS, "yield_stress": YIELD_STRESS} \
        if material == "viscoelastic" else {}
    mpm = Mpm(x[~ceiling], volume=spacing**3, density=DENSITY, dx=dx, low=low, high=high,
              material=MPM_MATERIAL[material], sound_speed=sound_speed, viscosity=VISCOSITY,
              ceiling=0.0, **extra)
    mpm.warm_up()
    tracker = Tracker(n, spacing, 0.5 * spacing, 0.5 * WIDTH, drip=DRIP / spacing)
    every = max(1, int(round(sample / frame)))
    t, steps, frames, wall = 0.0, 0, 0, 0.0
    j_low, j_high = 1.0, 1.0
    while t < end - 1e-9:
        t0 = time.perf_counter()
        done = mpm.advance(min(frame, end - t))
        wall += time.perf_counter() - t0
        steps += done
        t += done * mpm.dt
        frames += 1
        pos = mpm.positions()
        if not np.isfinite(pos).all():
            break
        J = mpm.J.to_numpy()
        j_low, j_high = min(j_low, float(J.min())), max(j_high, float(J.max()))
        tracker.observe(t, pos, frames % every == 0)
    out = {"method": "Taichi MLS-MPM", "material": material, "mpm_material": MPM_MATERIAL[material],
           "n": n, "spacing_m": spacing, "dx_spacings": per_dx, "dx_m": dx,
           "particles_per_cell": per_dx**3, "particles": int((~ceiling).sum()),
           "grid_nodes": int(np.prod(mpm.cells)), "sound_speed_m_s": sound_speed,
           "bulk_modulus_pa": DENSITY * sound_speed**2, "dt_s": mpm.dt, "steps": steps,
           "simulated_s": t, "finite": bool(np.isfinite(pos).all()),
           "volume_ratio_range": [j_low, j_high], "volume_ratio_mean_end": float(J.mean()),
           "wall_s": wall, "wall_per_simulated_s": wall / max(t, 1e-12)}
    out.update(tracker.finish(pos))
    return out


def peridyn_run(material, n, end, sample):
    res = run_one(material, n, 0.005, end, sample, 0, drip=DRIP * n / WIDTH)
    res["method"] = "peridyn (main)"
    res["wall_per_simulated_s"] = res["seconds_per_step"] / res["dt"]
    return res


def sph_run(n, hold, adhesion, end, frame, minutes):
    """One DFSPH run in its own process (SPlisHSPlasH's one global simulation); its record."""
    out = Path(tempfile.mkdtemp(prefix="honey_peers_")) / "sph.json"
    # OpenMP's busy waiting costs SPlisHSPlasH tens of times its time on a loaded machine.
    env = dict(os.environ, LD_PRELOAD=GL_DISPATCH, OMP_WAIT_POLICY="PASSIVE")
    argv = [sys.executable, str(Path(__file__).with_name("_dfsph_honey.py")), str(n), hold,
            repr(adhesion), repr(end), repr(frame), str(out)]
    try:
        done = subprocess.run(argv, capture_output=True, text=True, env=env,
                              timeout=minutes * 60.0)
    except subprocess.TimeoutExpired:
        return {"method": "pySPlisHSPlasH DFSPH + Weiler 2018", "n": n, "hold": hold,
                "adhesion": adhesion, "error": f"stopped after {minutes} min"}
    if not out.exists():
        return {"method": "pySPlisHSPlasH DFSPH + Weiler 2018", "n": n, "hold": hold,
                "adhesion": adhesion, "error": done.stdout[-1000:] + done.stderr[-1000:]}
    res = json.loads(out.read_text())
    res["material"] = "newtonian"
    return res


def summary(res):
    th = res.get("thread_frames") or {}
    ends = {k: res.get(k) for k in ("parts_s", "depth_end", "slabs_filled", "slabs_missing")}
    label = res["method"].split()[0]
    if "dx_spacings" in res:
        label += f" dx={res['dx_spacings']}"
    label += f" {res.get('hold', '')}"
    if res.get("adhesion"):
        label += f"+adh {res['adhesion']}"
    return (f"{label:28s} {res.get('material', ''):12s} n={res['n']:2d} parts {ends['parts_s']} "
            f"depth {ends['depth_end'] or 0:.1f} filled/missing {ends['slabs_filled']}/"
            f"{ends['slabs_missing']} thread {th.get('first_s')}-{th.get('last_s')} "
            f"thinnest {th.get('thinnest')} {res.get('wall_per_simulated_s', 0):.0f} s/s")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[5, 9, 13, 17])
    p.add_argument("--methods", nargs="+", default=["peridyn", "mpm", "sph"],
                   choices=["peridyn", "mpm", "sph"])
    p.add_argument("--materials", nargs="+", default=["newtonian", "viscoelastic"],
                   choices=["newtonian", "viscoelastic"])
    p.add_argument("--mpm-dx", type=int, nargs="+", default=[2, 1],
                   help="MPM grid spacing in particle spacings")
    p.add_argument("--sound-speed", type=float, default=20.0,
                   help="m/s, MPM's weakly compressible liquid (bulk modulus 1400 c^2)")
    p.add_argument("--sph-holds", nargs="+", default=["ghosts:0", "lid:0", "lid:100"],
                   help="DFSPH holds HOLD:ADHESION (benches/_dfsph_honey.py)")
    p.add_argument("--sph-sizes", type=int, nargs="+", default=[5, 9, 13],
                   help="sizes DFSPH runs at (of --sizes)")
    p.add_argument("--sph-minutes", type=float, default=10.0, help="a DFSPH run's time limit")
    p.add_argument("--time", type=float, default=0.4, help="simulated s (the test's 0.4)")
    p.add_argument("--frame", type=float, default=0.0025, help="s between MPM / SPH frames")
    p.add_argument("--sample", type=float, default=0.01, help="s between slab profiles")
    p.add_argument("--out", default=None, help="JSON path (default benches/results/...)")
    args = p.parse_args()
    rec = Record("honey_peers", args)
    rec.data["runs"] = []

    def keep(res):
        rec.data["runs"].append(res)
        print(summary(res), flush=True)
        rec.write(args.out)

    for n in args.sizes:
        for material in args.materials:
            if "peridyn" in args.methods:
                keep(peridyn_run(material, n, args.time, args.sample))
            if "mpm" in args.methods:
                for per_dx in args.mpm_dx:
                    keep(mpm_run(material, n, per_dx, args.sound_speed, args.time, args.frame,
                                 args.sample))
            if "sph" in args.methods and material == "newtonian" and n in args.sph_sizes:
                for spec in args.sph_holds:
                    hold, adhesion = spec.split(":")
                    keep(sph_run(n, hold, float(adhesion), args.time, args.frame,
                                 args.sph_minutes))
    rec.write(args.out)


if __name__ == "__main__":
    main()
