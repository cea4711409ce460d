"""The dam break of benches/dam_break.py in pySPlisHSPlasH's DFSPH (Bender and Koschier 2015,
divergence-free SPH), the peer of peridyn's fluids. Run by ``dam_break.py --peers`` in a
subprocess (SPlisHSPlasH holds one global simulation per process, and its import may need
``LD_PRELOAD=libGLdispatch.so.0`` on a machine without a display):

    python benches/_dfsph_dam_break.py NA A OUT.json

Scene: a water column ``a`` wide and deep and ``2a`` high (z up) against the left wall of a tank
``8a`` long and ``a`` deep, sampled on SPlisHSPlasH's regular grid of particle radius
``a / (2 na)`` (spacing ``a / na``, as peridyn's lattice), water (1000 kg/m^3; SPlisHSPlasH's
default standard viscosity at 0.01, its usual setting), DFSPH with its default tolerances
(density error 0.01 %, divergence error 0.1 %), a fixed time step of 1 ms (CFL number about
0.1 at the front's 2 m/s; its CFL control chose 0.1 ms here), the walls a box mesh with
boundary particles (Akinci et al. 2012) 2r beyond the tank's faces (see ``scene``). Writes
the particle count, the fronts ``Z = (max x + r) / a`` at Martin and Moyce's ``T`` (the first
step at or beyond each), the wall seconds per simulated second (from the first step: setup
and boundary sampling excluded) and the steps taken.
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

G = 9.81
BOUNDARY = 0  # boundary particles (Akinci et al. 2012)
TIME_STEP = 0.001  # s
GAP = 2.0  # the box's boundary particles lie GAP particle radii beyond the tank's faces
MARTIN_MOYCE = [(0.832, 1.217), (1.997, 2.292), (3.345, 4.134), (5.091, 6.98)]


def box_obj(path: Path) -> None:
    """The unit cube [-0.5, 0.5]^3 as 12 outward-facing triangles."""
    v = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    faces = [(1, 2, 4), (1, 4, 3), (5, 7, 8), (5, 8, 6), (1, 5, 6), (1, 6, 2),
             (3, 4, 8), (3, 8, 7), (1, 3, 7), (1, 7, 5), (2, 6, 8), (2, 8, 4)]
    lines = [f"v {x} {y} {z}" for x, y, z in v] + [f"f {a} {b} {c}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def scene(na: int, a: float, folder: Path) -> Path:
    r = a / (2 * na)
    box_obj(folder / "box.obj")
    length, depth, height = 8 * a, a, 4 * a
    description = {
        "Configuration": {
            "particleRadius": r, "simulationMethod": 4, "gravitation": [0, 0, -G],
            "timeStepSize": TIME_STEP, "cflMethod": 0,
            "enableDivergenceSolver": True,
            "boundaryHandlingMethod": BOUNDARY, "enablePartioExport": False,
            "enableVTKExport": False,
        },
        "Materials": [{"id": "Fluid", "density0": 1000.0}],
        "RigidBodies": [{
            "geometryFile": str(folder / "box.obj"),
            # The boundary particles lie 2r beyond the tank's faces, 1.5 spacings from the
            # first fluid particles' centres: at 1 spacing (1r beyond) their density share
            # burst the column at rest apart in its first step (median speed 2.2 m/s).
            "translation": [length / 2, depth / 2, height / 2],
            "scale": [length + 2 * GAP * r, depth + 2 * GAP * r, height + 2 * GAP * r],
            "isDynamic": False,
            "isWall": True,
            "mapInvert": True, "mapThickness": 0.0,
            "mapResolution": [80, 10, 40], "samplingMode": 1,
        }],
        # SPlisHSPlasH's regular sampling puts floor(extent / 2r) - 1 particles across a
        # block: the block reaches r beyond the column so that it holds na x na x 2 na.
        "FluidBlocks": [{"denseMode": 0, "start": [-r, -r, -r],
                         "end": [a + r, depth + r, 2 * a + r]}],
    }
    path = folder / "dam_break.json"
    path.write_text(json.dumps(description, indent=1))
    return path


def main() -> None:
    na, a, out = int(sys.argv[1]), float(sys.argv[2]), Path(sys.argv[3])
    import pysplishsplash as sph

    folder = Path(tempfile.mkdtemp(prefix="dfsph_dam_break_"))
    c = math.sqrt(2 * G / a)
    r = a / (2 * na)
    base = sph.Exec.SimulatorBase()
    base.init(useGui=False, sceneFile=str(scene(na, a, folder)), useCache=False,
              outputDir=str(folder), initialPause=False)
    run = {"fronts": [], "steps": 0, "first": None}

    def after_step():
        """SPlisHSPlasH's time-step callback: the clock of the first step, and the front at
        the first step at or beyond each of Martin and Moyce's times."""
        run["steps"] += 1
        if run["first"] is None:
            run["first"] = time.perf_counter()
        t = sph.TimeManager.getCurrent().getTime()
        if len(run["fronts"]) < len(MARTIN_MOYCE) and t >= MARTIN_MOYCE[len(run["fronts"])][0] / c:
            fluid = sph.Simulation.getCurrent().getFluidModel(0)
            n = fluid.getNumActiveParticles0()
            x = np.array([fluid.getPosition(i) for i in range(n)], dtype=float)
            T, Z = MARTIN_MOYCE[len(run["fronts"])]
            front = float((x[:, 0].max() + r) / a)
            run["fronts"].append({"T": T, "T_reached": t * c, "Z_martin_moyce": Z,
                                  "Z": front, "error": front / Z - 1.0})
            run["particles"] = n
            run["t"] = t
            run["x_range"] = [x.min(0).tolist(), x.max(0).tolist()]

    base.setValueFloat(base.STOP_AT, MARTIN_MOYCE[-1][0] / c + TIME_STEP)
    base.setTimeStepCB(after_step)
    base.run()
    wall = time.perf_counter() - run["first"]
    out.write_text(json.dumps({
        "method": "pySPlisHSPlasH DFSPH", "na": na, "particles": run["particles"],
        "time_step_s": TIME_STEP,
        "steps": run["steps"], "extent_at_end_m": run["x_range"], "simulated_s": run["t"],
        "wall_s": wall,
        "wall_seconds_per_simulated_second": wall / run["t"], "fronts": run["fronts"],
    }, indent=1))
    os._exit(0)  # SPlisHSPlasH's teardown segfaults after a run without GUI (2.19.0)


if __name__ == "__main__":
    main()
