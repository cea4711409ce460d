"""Do two or more builds of peridyn compute the same, to the bit? Hashes of the state after N steps.

A change that restructures the core and must change no result (issue 37) is checked by
building the commit before and after it and running each build, in a fresh process of its
own (``_common.build_dir``: a wheel is unpacked to a scratch directory, a directory holding
the ``peridyn`` package is used as it is), on two scenes:

- ``default``: the scene of ``python -m peridyn`` (``scenes.default_scene`` with the options
  of ``peridyn.__main__``'s defaults, 120 x 120 vertices, CPU), no files written;
- ``three_layers``: a three-layer contact drop, ``paper_scenes.cloths_over_ball(layers=3,
  n=16, size=0.5, dt=2e-3, drop=2e-3)``: the lowest layer reaches the ball at about step 16,
  the layers are in contact with each other from step 19 on.

Each is stepped ``--steps`` times (50) on ``--threads`` worker threads (1), ``--repeat``
times (2) per build, each time in a fresh process. Per run the script records the SHA-256 of
the positions (float64, C order, each body in the order added, bytes concatenated), the same
of the velocities, and the iterations of every step. It prints a table, writes JSON and exits
1 when any of them differs between builds or between the runs of one build, 0 when all are
equal.

One thread by default, so that builds from before the contact local step's sums were made
independent of the thread count (they varied from run to run on several threads from the
first contact on, by 1e-16 m) compare too; ``--repeat`` shows whether a build repeats
itself, so that a difference between builds is not taken for a change of the code.

Wheels of two commits (see ``compare_builds.py --help`` on building an older commit in a
worktree), then from the repository root:

    python benches/same_results.py --build before=/tmp/ab/wheels/39bf02c \\
        --build after=/tmp/ab/wheels/head --steps 50 --out benches/results/same_results.json

A build is ``NAME=PATH`` or just ``PATH`` (then named by its file name).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402

#: What each scene is, as built by :func:`make_scene`.
SCENES = {
    "default": "python -m peridyn's scene (default_scene with the CLI's defaults)",
    "three_layers": "cloths_over_ball(layers=3, n=16, size=0.5, dt=2e-3, drop=2e-3)",
}
#: The per-scene records that must be equal between builds.
SAME = ("positions_sha256", "velocities_sha256", "iterations")


def make_scene(name: str, threads: int):
    """The scene ``name`` of :data:`SCENES` from the imported build, on ``threads`` threads."""
    if name == "default":
        from peridyn.__main__ import build_parser
        from peridyn.scenes import default_scene

        # As peridyn.__main__.main builds it from its command line.
        cli = build_parser().parse_args(["--threads", str(threads)])
        kwargs = {"n": cli.n, "threads": cli.threads, "backend": cli.backend}
        if cli.dt is not None:
            kwargs["dt"] = cli.dt
        return default_scene(**kwargs)
    from peridyn.paper_scenes import cloths_over_ball

    return cloths_over_ball(layers=3, n=16, size=0.5, dt=2e-3, drop=2e-3, threads=threads)


def sha256_of(arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return h.hexdigest()


def iterations_of(stats) -> int:
    it = stats.iterations
    return int(it() if callable(it) else it)


def in_contact(stats) -> bool | None:
    """Whether the step ended with primitive pairs within the barrier's reach (None where the
    build's stats do not say)."""
    try:
        return stats.contact["active_pairs"] > 0
    except (AttributeError, KeyError, TypeError):
        return None


def worker(args) -> None:
    """Runs in a build's process: step one scene (the one ``--scene``), print one JSON line."""
    import peridyn

    (name,) = args.scene
    scene = make_scene(name, args.threads)
    bodies = list(scene.bodies.values())
    iterations, contact = [], []
    start = time.perf_counter()
    for _ in range(args.steps):
        stats = scene.solver.step()
        iterations.append(iterations_of(stats))
        contact.append(in_contact(stats))
    seconds = time.perf_counter() - start
    print(json.dumps({
        "module": peridyn.__file__,
        "version": getattr(peridyn, "__version__", None),
        "vertices": sum(len(b.positions) for b in bodies),
        "positions_sha256": sha256_of(b.positions for b in bodies),
        "velocities_sha256": sha256_of(b.velocities for b in bodies),
        "iterations": iterations,
        "steps_in_contact": None if None in contact else sum(contact),
        "step_seconds": seconds,
    }), flush=True)


def named(builds):
    """``{name: path}`` of the ``--build`` values (``NAME=PATH`` or ``PATH``), names unique."""
    out = {}
    for b in builds:
        name, _, path = b.rpartition("=")
        if not name or "/" in name:
            name, path = Path(b).name, b
        unique, k = name, 2
        while unique in out:
            unique, k = f"{name}#{k}", k + 1
        out[unique] = path
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--build", action="append", default=[], metavar="[NAME=]WHEEL_OR_DIR",
                   help="a build (two or more; the first is the reference)")
    p.add_argument("--steps", type=int, default=50, help="steps per scene (default: 50)")
    p.add_argument("--threads", type=int, default=1, help="solver threads (default: 1)")
    p.add_argument("--repeat", type=int, default=2,
                   help="runs of each scene per build, each in a fresh process (default: 2)")
    p.add_argument("--scene", action="append", choices=list(SCENES), default=None,
                   help="a scene to run (default: all)")
    p.add_argument("--out", default=None, help="JSON (default: benches/results/same_results.json)")
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        return worker(args)
    if len(args.build) < 2:
        p.error("give two or more --build")
    if min(args.steps, args.threads, args.repeat) < 1:
        p.error("--steps, --threads and --repeat must be >= 1")
    scenes = args.scene or list(SCENES)
    builds = named(args.build)
    rec = C.Record("same_results", args)
    runs = {scene: {name: [] for name in builds} for scene in scenes}
    with tempfile.TemporaryDirectory(prefix="peridyn_same_") as tmp:
        where = {name: C.build_dir(path, Path(tmp), f"build{i}")
                 for i, (name, path) in enumerate(builds.items())}
        digests = {name: C.core_digest(path) for name, path in where.items()}
        for scene in scenes:
            for _ in range(args.repeat):
                for name in builds:
                    t0 = time.perf_counter()
                    run = C.run_in_build(name, where[name], [
                        Path(__file__).resolve(), "--worker", "--scene", scene,
                        "--steps", args.steps, "--threads", args.threads])
                    run["process_seconds"] = time.perf_counter() - t0
                    runs[scene][name].append(run)

    names = list(builds)
    reference = {scene: runs[scene][names[0]][0] for scene in scenes}
    differ = {scene: {name: sorted({field for run in runs[scene][name]
                                    for field in SAME if run[field] != reference[scene][field]})
                      for name in names} for scene in scenes}
    differ = {scene: {name: fields for name, fields in per.items() if fields}
              for scene, per in differ.items()}
    width = max(len(n) for n in names)
    print(f"{args.steps} steps, {args.threads} thread(s), {args.repeat} run(s) per build; core "
          "SHA-256: " + ", ".join(f"{n} {d[:12]}" for n, d in digests.items()))
    print(f"{'scene':<13} {'build':<{width}} {'run':>3} {'vertices':>8} {'positions sha256':<16} "
          f"{'velocities sha256':<17} {'iterations':>10} {'contact':>7} {'s':>5}")
    for scene in scenes:
        for name in names:
            for k, r in enumerate(runs[scene][name]):
                contact = "?" if r["steps_in_contact"] is None else r["steps_in_contact"]
                print(f"{scene:<13} {name:<{width}} {k + 1:>3} {r['vertices']:>8} "
                      f"{r['positions_sha256'][:16]:<16} {r['velocities_sha256'][:16]:<17} "
                      f"{sum(r['iterations']):>10} {contact:>7} {r['process_seconds']:>5.1f}")
        print(f"{scene}: " + ("; ".join(
            (f"{name} differs from {names[0]} run 1" if name != names[0] else
             f"{name}'s runs differ from each other") + " in " + ", ".join(fields)
            for name, fields in differ[scene].items()) or "the same in every run of every build"))
    rec.data.update({"builds": builds, "core_sha256": digests, "scenes": {
        s: SCENES[s] for s in scenes}, "runs": runs, "differ": differ,
        "same": not any(differ.values())})
    rec.write(args.out)
    print("DIFFERENT" if any(differ.values()) else "SAME")
    return 1 if any(differ.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
