"""Shared helpers for the Python benchmarks in benches/: machine record, scenes, JSON output,
builds run in fresh processes.

Every benchmark records, next to its numbers, what the machine was doing (``os.getloadavg()``
before and after, CPU count and affinity), which peridyn it measured (version, git commit,
whether the work tree was dirty) and the exact command that produced the file.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import os
import platform
import shlex
import subprocess
import sys
import time
import zipfile
from pathlib import Path
from typing import Any, Dict, Optional

import numpy as np

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benches" / "results"


def git_info() -> Dict[str, Any]:
    def run(*args: str) -> Optional[str]:
        try:
            return subprocess.run(
                ["git", "-C", str(REPO), *args], capture_output=True, text=True, timeout=20
            ).stdout.strip()
        except Exception:  # pragma: no cover - git missing
            return None

    status = run("status", "--porcelain", "--", "src", "python", "Cargo.toml", "pyproject.toml")
    return {"commit": run("rev-parse", "HEAD"), "core_sources_dirty": bool(status)}


def command_line() -> str:
    """The exact command, as run from the repository root."""
    script = Path(sys.argv[0]).resolve()
    try:
        script_s = str(script.relative_to(REPO))
    except ValueError:
        script_s = str(script)
    return " ".join(["python", shlex.quote(script_s), *map(shlex.quote, sys.argv[1:])])


def machine(extra: Optional[Dict[str, Any]] = None) -> Dict[str, Any]:
    try:
        import peridyn
    except ImportError:  # a parent that runs builds in their own processes (build_dir)
        peridyn = None

    info = {
        "utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "loadavg_1_5_15": list(os.getloadavg()),
        "cpu_count": os.cpu_count(),
        "cpu_affinity": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None,
        "cpu_model": _cpu_model(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "numpy": np.__version__,
        "peridyn_version": getattr(peridyn, "__version__", None),
        "peridyn_module": getattr(peridyn, "__file__", None),
        "git": git_info(),
    }
    if extra:
        info.update(extra)
    return info


def vm_kib(field: str) -> int:
    """A ``/proc/self/status`` memory figure of this process (e.g. ``"VmHWM"``, the peak resident
    size) in KiB, or -1 where the file does not exist."""
    try:
        text = Path("/proc/self/status").read_text()
    except OSError:
        return -1
    for line in text.splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return -1


def _cpu_model() -> Optional[str]:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


class Record:
    """Collects the run's metadata; ``write`` adds the load at the end and saves JSON."""

    def __init__(self, name: str, args: Any):
        self.name = name
        self.t0 = time.perf_counter()
        self.data: Dict[str, Any] = {
            "benchmark": name,
            "command": command_line(),
            "args": vars(args) if args is not None else {},
            "machine_start": machine(),
            "notes": [],
        }

    def note(self, text: str) -> None:
        print("note:", text, flush=True)
        self.data["notes"].append(text)

    def write(self, out: Optional[str] = None) -> Path:
        self.data["machine_end"] = {
            "utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
            "loadavg_1_5_15": list(os.getloadavg()),
        }
        self.data["wall_seconds"] = time.perf_counter() - self.t0
        path = Path(out) if out else RESULTS / f"{self.name}.json"
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(_jsonable(self.data), indent=1, allow_nan=True) + "\n")
        print(f"wrote {path}", flush=True)
        return path


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating,)):
        return float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, float) and not np.isfinite(x):
        return None if np.isnan(x) else ("inf" if x > 0 else "-inf")
    return x


def build_dir(build: str, scratch: Path, name: str) -> Path:
    """A directory to put first on ``PYTHONPATH`` for ``build`` (a wheel, a directory holding
    one wheel, or a directory holding the ``peridyn`` package); a wheel is unpacked into
    ``scratch / name``."""
    path = Path(build)
    if path.is_dir() and not (path / "peridyn").is_dir():
        wheels = sorted(path.glob("peridyn-*.whl"))
        if len(wheels) != 1:
            raise SystemExit(f"--build {name}={build}: expected one peridyn wheel there, "
                             f"found {len(wheels)}")
        path = wheels[0]
    if path.is_dir():
        return path
    if path.suffix != ".whl" or not path.is_file():
        raise SystemExit(f"--build {name}={build}: not a wheel or a directory")
    target = scratch / name
    with zipfile.ZipFile(path) as wheel:
        wheel.extractall(target)
    return target


def core_digest(where: Path) -> str:
    """The SHA-256 of the build's compiled core (``peridyn/_core*.so`` or ``.pyd``)."""
    cores = sorted((where / "peridyn").glob("_core*.so")) + sorted(
        (where / "peridyn").glob("_core*.pyd"))
    if len(cores) != 1:
        raise SystemExit(f"{where}: expected one compiled core in peridyn/, found {len(cores)}")
    return hashlib.sha256(cores[0].read_bytes()).hexdigest()


def run_in_build(name: str, where: Path, argv: list) -> Dict[str, Any]:
    """Runs ``python ARGV`` in a fresh process that imports peridyn from ``where`` (first on
    ``PYTHONPATH``, see :func:`build_dir`) and returns the JSON object of its last line of
    output, which must give ``"module"``: the ``peridyn.__file__`` it imported (checked to lie
    in ``where``)."""
    env = dict(os.environ, PYTHONPATH=str(where))
    done = subprocess.run([sys.executable, *map(str, argv)], env=env, capture_output=True,
                          text=True)
    if done.returncode != 0:
        raise SystemExit(f"build {name} failed:\n{done.stderr[-4000:]}")
    result = json.loads(done.stdout.strip().splitlines()[-1])
    if not Path(result["module"]).resolve().is_relative_to(Path(where).resolve()):
        raise SystemExit(f"build {name} imported peridyn from {result['module']}, not {where}")
    return result


def solver_supports(**kwargs: Any) -> bool:
    """True when this build's Solver accepts the keyword arguments (e.g. method=, inner_iters=)."""
    import peridyn

    try:
        peridyn.Solver(dt=1e-3, **kwargs)
        return True
    except TypeError:
        return False
    except ValueError:
        return False


def hanging_cloth(
    n: int,
    *,
    size: float = 1.0,
    thickness: float = 1e-3,
    density: float = 300.0,
    material: Any = None,
    bending: Optional[float] = None,
    diagonal: str = "alternate",
):
    """An n x n cloth in z = 0, pinned along the edge y = size (the paper's comparison scene)."""
    import peridyn

    V, F = peridyn.grid(n, n, size=(size, size), diagonal=diagonal)
    if material is None:
        material = peridyn.StretchA3(s0=2e4)
    if bending is None:
        E = getattr(material, "youngs_modulus", 4e4)
        bending = peridyn.plate_bending_stiffness(E, 0.0, thickness)
    cloth = peridyn.Membrane(
        V, F, thickness=thickness, density=density, material=material, bending=bending
    )
    cloth.pin(np.flatnonzero(np.isclose(V[:, 1], size)))
    return cloth


def median(xs) -> float:
    xs = [x for x in xs if x is not None]
    return float(np.median(xs)) if xs else float("nan")


def layers_over_ball(contact_changes: Dict[str, Any], tol: float, args: Any, layers: int = 2) -> dict:
    """``layers`` stacked layers of 0.5 m dropped over the ball
    (``paper_scenes.cloths_over_ball(layers, n=args.n, size=0.5)``), with the contact parameters
    ``contact_changes`` changed, for ``args.steps`` steps at ``tol`` (m) and ``args.max_iters``:
    the iterations per step (median and largest), the steps that ran to the cap, ms per step
    (median), the local step's iterations per step (median), and at the end the smallest distance
    between non-adjacent primitives (m; the local step keeps it above ``eps xi``) and the count of
    intersecting triangle pairs."""
    from peridyn import checks, paper_scenes

    scene = paper_scenes.cloths_over_ball(layers=layers, n=args.n, size=0.5, tol=tol,
                                          max_iters=args.max_iters, threads=args.threads)
    c = scene.solver.contact.replace(**contact_changes)
    scene.solver.contact = c
    iterations, ms, local = [], [], []
    start = time.perf_counter()
    for _ in range(args.steps):
        stats = scene.solver.step()
        iterations.append(stats.iterations)
        ms.append(stats.timings["total"])
        local.append(stats.contact["local_iterations"])
    wall = time.perf_counter() - start
    x, tris, _ = checks.mesh_of(scene.bodies.values())
    return {
        **contact_changes,
        "tol_m": tol,
        "wall_s": wall,
        "iterations_median": median(iterations),
        "iterations_max": max(iterations),
        "steps_at_max_iters": sum(i >= args.max_iters for i in iterations),
        "ms_per_step_median": median(ms),
        "local_iterations_median": median(local),
        "min_distance_m": checks.min_separation(x, tris, 2 * (c.thickness + c.d_hat)),
        "intersecting_pairs": len(checks.intersecting_pairs(x, tris)),
        "eps_xi_m": c.eps * c.thickness,
    }


def layers_summary(r: dict) -> str:
    """One line of a :func:`layers_over_ball` result."""
    return (f"{r['iterations_median']:.0f} iterations median ({r['iterations_max']} at most, "
            f"{r['steps_at_max_iters']} steps at the cap), {r['local_iterations_median']:.0f} "
            f"local, {r['ms_per_step_median']:.1f} ms per step, {r['wall_s']:.1f} s, min distance "
            f"{r['min_distance_m'] * 1e3:.3f} mm, {r['intersecting_pairs']} intersecting")
