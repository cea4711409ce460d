"""The hanging honey blob of benches/honey_peers.py in pySPlisHSPlasH's DFSPH (Bender and
Koschier 2015) with Weiler et al. 2018's implicit viscosity, the SPH peer of peridyn's honey. Run
by ``honey_peers.py`` in a subprocess (SPlisHSPlasH holds one global simulation per process, and
its import needs ``LD_PRELOAD=libGLdispatch.so.0`` on a machine without a display):

    python benches/_dfsph_honey.py N HOLD ADHESION END FRAME OUT.json

Scene: the blob of ``tests/fluid_scenes.py``'s ``blob_under_a_ceiling`` (``N`` particles across
5 cm, ``round(1.2 N)`` tall, spacing ``0.05 / N`` m, cell-centred, the liquid's top face at
z = 0), 1400 kg/m^3, gravity 9.81 m/s^2, sampled by SPlisHSPlasH's regular fluid blocks
(particle radius half the spacing), Weiler 2018 viscosity of kinematic ``10 / 1400`` m^2/s
(10 Pa s; its CG to a relative error of 0.01, at most 500 iterations), DFSPH with its divergence
solver, CFL-controlled steps (factor 0.5, at most 2.5 ms), no floor or walls. ``HOLD``:

* ``ghosts``: the ceiling of ``blob_under_a_ceiling`` (two layers one spacing wider on every
  side, at z = 0.5 and 1.5 spacings) sampled as particles of the same fluid and held still by
  SPlisHSPlasH's ``AnimatedByEmitter`` particle state (the time integration and the pressure
  solve skip them; they enter every neighbour's density and viscosity with zero velocity): the
  counterpart of peridyn's pinned ghosts;
* ``lid``: a static box above the blob (its face at z = 0.5 spacings, where the ghosts' lowest
  layer would be), Akinci et al. 2012 boundary particles, with Weiler 2018's boundary viscosity
  at the liquid's (``viscosityBoundary`` 10 / 1400 m^2/s): a lid that holds by friction only,
  unless ``ADHESION`` > 0: then Akinci et al. 2013's surface tension (its cohesion coefficient
  at SPlisHSPlasH's default 0.05) with their adhesion to the boundary of coefficient
  ``ADHESION`` (``surfaceTensionBoundary``; its kernel reaches from half the support, 2 particle
  radii, to the support, 4 radii, so it pulls the liquid's second and third layers).

Every ``FRAME`` seconds of simulated time (the first step at or beyond each) the liquid's
positions go to :class:`honey_resolution.Tracker` (the depth below the ghosts' lowest layer,
z = 0.5 spacings); the output holds the tracker's record, the wall seconds per simulated second
(from the first step) and the steps taken.
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _dfsph_dam_break import box_obj  # noqa: E402
from honey_resolution import WIDTH, Tracker  # noqa: E402
from honey_peers import DRIP  # noqa: E402

G = 9.81
DENSITY = 1400.0
KINEMATIC = 10.0 / DENSITY  # m^2/s, 10 Pa s
SAMPLE = 0.01  # s between slab profiles


def scene(n: int, hold: str, adhesion: float, folder: Path) -> Path:
    s = WIDTH / n
    r = s / 2
    tall = int(round(1.2 * n))
    # SPlisHSPlasH's regular sampling puts floor(extent / 2r) - 1 particles across a block, the
    # first at start + 2r: a block reaching r beyond the lattice's outer faces holds it exactly.
    blocks = [{"denseMode": 0, "start": [-r, -r, -tall * s - r], "end": [WIDTH + r, WIDTH + r, r]}]
    bodies = []
    if hold == "ghosts":
        blocks.append({"denseMode": 0, "start": [-s - r, -s - r, -r],
                       "end": [WIDTH + s + r, WIDTH + s + r, 2 * s + r]})
    else:
        box_obj(folder / "box.obj")
        thick = 4 * s
        bodies.append({
            "geometryFile": str(folder / "box.obj"),
            "translation": [WIDTH / 2, WIDTH / 2, r + thick / 2],
            "scale": [WIDTH + 8 * s, WIDTH + 8 * s, thick],
            "isDynamic": False, "isWall": False, "mapInvert": False, "mapThickness": 0.0,
            "mapResolution": [20, 20, 20], "samplingMode": 1,
        })
    description = {
        "Configuration": {
            "particleRadius": r, "simulationMethod": 4, "gravitation": [0, 0, -G],
            "timeStepSize": 0.001, "cflMethod": 1, "cflFactor": 0.5,
            "cflMaxTimeStepSize": 0.0025, "enableDivergenceSolver": True,
            "boundaryHandlingMethod": 0, "enableZSort": False, "enablePartioExport": False,
            "enableVTKExport": False,
        },
        "Materials": [{
            "id": "Fluid", "density0": DENSITY, "viscosityMethod": 6,
            "Weiler et al. 2018": {"viscosity": KINEMATIC, "viscosityBoundary": KINEMATIC,
                                   "viscoMaxIter": 500, "viscoMaxError": 0.01},
            "surfaceTensionMethod": 2 if adhesion > 0 else 0,
            "Akinci et al. 2013": {"surfaceTension": 0.05, "surfaceTensionBoundary": adhesion},
        }],
        "RigidBodies": bodies,
        "FluidBlocks": [dict(b, id="Fluid") for b in blocks],
    }
    path = folder / "honey.json"
    path.write_text(json.dumps(description, indent=1))
    return path


def main() -> None:
    n, hold, adhesion = int(sys.argv[1]), sys.argv[2], float(sys.argv[3])
    end, frame, out = float(sys.argv[4]), float(sys.argv[5]), Path(sys.argv[6])
    import pysplishsplash as sph

    folder = Path(tempfile.mkdtemp(prefix="dfsph_honey_"))
    s = WIDTH / n
    base = sph.Exec.SimulatorBase()
    base.init(useGui=False, sceneFile=str(scene(n, hold, adhesion, folder)), useCache=False,
              outputDir=str(folder), initialPause=False)
    base.initSimulation()
    fluid = sph.Simulation.getCurrent().getFluidModel(0)
    count = fluid.numActiveParticles()
    x0 = np.array(fluid.getFieldBuffer("position"), copy=True, dtype=float)[:count]
    ghost = x0[:, 2] > 0.0
    for i in np.flatnonzero(ghost):
        fluid.setParticleState(int(i), sph.ParticleState.AnimatedByEmitter)
        fluid.setVelocity(int(i), np.zeros(3))
    liquid = np.flatnonzero(~ghost)
    visc = fluid.getViscosityBase()
    read_back = {"viscosity": visc.getValueFloat(visc.VISCOSITY_COEFFICIENT),
                 "viscosityBoundary": visc.getValueFloat(visc.VISCOSITY_COEFFICIENT_BOUNDARY)}
    tracker = Tracker(n, s, 0.5 * s, 0.5 * WIDTH, drip=DRIP / s)
    run = {"steps": 0, "first": None, "next": frame, "dt_min": 1.0, "dt_max": 0.0}
    every = max(1, int(round(SAMPLE / frame)))

    def after_step():
        """SPlisHSPlasH's time-step callback: the clock of the first step, and a frame to the
        tracker at the first step at or beyond each frame time."""
        run["steps"] += 1
        if run["first"] is None:
            run["first"] = time.perf_counter()
        tm = sph.TimeManager.getCurrent()
        t, h = tm.getTime(), tm.getTimeStepSize()
        run["dt_min"], run["dt_max"] = min(run["dt_min"], h), max(run["dt_max"], h)
        if t >= run["next"] - 1e-9:
            k = int(round(run["next"] / frame))
            pos = np.array(fluid.getFieldBuffer("position"), copy=True, dtype=float)[liquid]
            tracker.observe(t, pos, k % every == 0)
            run["next"] += frame
            run["t"] = t
            run["pos"] = pos

    base.setValueFloat(base.STOP_AT, end)
    base.setTimeStepCB(after_step)
    base.runSimulation()
    wall = time.perf_counter() - run["first"]
    now = np.array(fluid.getFieldBuffer("position"), copy=True, dtype=float)[:count]
    ghost_moved = np.abs(now[ghost] - x0[ghost]).max() if ghost.any() else 0.0
    res = {"method": "pySPlisHSPlasH DFSPH + Weiler 2018", "hold": hold, "adhesion": adhesion,
           "n": n, "spacing_m": s, "particles": int(liquid.size), "ghosts": int(ghost.sum()),
           "ghost_max_move_m": float(ghost_moved), "viscosity_read_back": read_back,
           "steps": run["steps"],
           "dt_range_s": [run["dt_min"], run["dt_max"]], "simulated_s": run["t"],
           "wall_s": wall, "wall_per_simulated_s": wall / run["t"]}
    res.update(tracker.finish(run["pos"]))
    out.write_text(json.dumps(res))
    os._exit(0)  # SPlisHSPlasH's teardown segfaults after a run without GUI (2.19.0)


if __name__ == "__main__":
    main()
