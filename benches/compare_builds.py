"""Builds of peridyn timed on the same steps of a saved paper-scene run, taking turns.

A change to the Rust core that is meant to make steps cheaper cannot be timed beside the old
code in one process (both are ``peridyn._core``), so this script runs each build in a fresh
process: it continues a ``paper_scenes.py`` run from its saved state (``--state``, the run's
JSON given by ``--run``) for ``--steps`` steps and reports, per step, ms in total and by
contact phase (the solver's own timings), iterations and contact figures. The builds take
turns for ``--rounds`` rounds, in reverse order every other round, so that a drift of the
machine falls on all of them alike. Nothing else should run meanwhile.

The summary gives, per build, the median ms per step, per step with a broad-phase build and
per phase, and the median over the steps of the ratio of its ms to the first build's on the
same step. It also says whether the builds computed the same thing: equal iterations and
contact figures on every step, and the largest difference of the final positions (m) from
the first build's first round (for the first build itself: whether its rounds repeat each
other). A change meant to keep results keeps them there to the bit unless it reorders
floating-point sums.

A build is a wheel (``maturin build --release -o DIR``) or a directory holding an unpacked
``peridyn`` package. Wheels of older commits come from git worktrees that share this
checkout's target directory, so only the crate itself compiles. Cargo gives the crate the
same fingerprint in every checkout and calls it fresh when no source file is newer than
the last build of it, whichever checkout that was: touch the sources before each build, or
the wheel holds the previous build's code (``Finished`` with no ``Compiling peridyn`` line;
touch this checkout's too before building it again):

    git worktree add /tmp/ab/wt_a39010f a39010f
    cd /tmp/ab/wt_a39010f && find src -name '*.rs' -exec touch {} + && \\
        CARGO_TARGET_DIR=/work/main/target maturin build --release -o /tmp/ab/wheels/a39010f

Then, from the repository root:

    python benches/compare_builds.py \\
        --run benches/results/paper_scenes_cloths_over_ball_6x200_chebyshev.json \\
        --state benches/results/paper_scenes_cloths_over_ball_6x200_chebyshev.state.npz \\
        --build a39010f=/tmp/ab/wheels/a39010f --build head=/tmp/ab/wheels/head \\
        --steps 6 --rounds 2 --out benches/results/compare_builds_box_gap.json

The first step of every process builds the pair cache afresh (it is not saved with the state).
Each process loads the whole scene, so memory is that of the run itself: time one at a time.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _common as C  # noqa: E402
from paper_scenes import CONTACT_FIGURES, build  # noqa: E402

#: The contact phases' ms per step (the solver's own timings).
PHASES = tuple(f for f in CONTACT_FIGURES if f.endswith("_ms"))
#: Per-step figures that must agree between builds that compute the same thing.
SAME_FIGURES = ("iterations", "converged") + tuple(f for f in CONTACT_FIGURES
                                                   if f not in PHASES)


def worker(args) -> None:
    """Runs in a build's process: continue the run for ``--steps`` steps, print one JSON line."""
    import peridyn

    earlier = json.loads(Path(args.run).read_text())
    scene = build(argparse.Namespace(**earlier["args"]))
    solver = scene.solver
    peridyn.load_state(args.state, solver)
    first = solver.steps_taken + 1
    rows = []
    for _ in range(args.steps):
        st = solver.step()
        rows.append({"step": solver.steps_taken, "ms": st.timings["total"],
                     "iterations": st.iterations, "converged": bool(st.converged),
                     **{f: st.contact[f] for f in SAME_FIGURES[2:] + PHASES}})
    x = np.concatenate([b.positions for b in scene.bodies.values()])
    np.save(args.positions_out, x)
    print(json.dumps({"module": peridyn.__file__, "first_step": first, "rows": rows}), flush=True)


def run_build(name, where, args, scratch, index):
    positions = scratch / f"positions_{name}_{index}.npy"
    before = os.getloadavg()
    result = C.run_in_build(name, where, [
        Path(__file__).resolve(), "--worker", "--run", args.run, "--state", args.state,
        "--steps", args.steps, "--positions-out", positions])
    result.update(build=name, loadavg_before=list(before), loadavg_after=list(os.getloadavg()))
    return result, np.load(positions)


def summarize(names, runs, final_positions):
    """Medians per build, ratios to the first build step by step, and agreement."""
    by_step = {name: {} for name in names}
    for run in runs:
        for row in run["rows"]:
            by_step[run["build"]].setdefault(row["step"], []).append(row)
    base = names[0]
    summary = {}
    for name in names:
        rows = [r for per in by_step[name].values() for r in per]
        built = [r["ms"] for r in rows if r["broad_phase_builds"] > 0]
        ratios = [r["ms"] / b["ms"] for step, per in by_step[name].items()
                  for r, b in zip(per, by_step[base][step])]
        summary[name] = {
            "steps_timed": len(rows),
            "ms_per_step_median": float(np.median([r["ms"] for r in rows])),
            "ms_per_step_with_a_build_median": float(np.median(built)) if built else None,
            "steps_with_a_build": len(built),
            **{f"{phase}_median": float(np.median([r[phase] for r in rows])) for phase in PHASES},
            f"ms_ratio_to_{base}_median": float(np.median(ratios)),
            f"ms_ratio_to_{base}_min_max": [float(min(ratios)), float(max(ratios))],
        }
    differing = sorted({
        (step, figure) for name in names[1:] for step, per in by_step[name].items()
        for r, b in zip(per, by_step[base][step]) for figure in SAME_FIGURES
        if r[figure] != b[figure]})
    reference = final_positions[base][0]
    shift = {name: max(float(np.max(np.abs(x - reference))) for x in xs)
             for name, xs in final_positions.items()}
    return summary, {
        "steps_whose_figures_differ_from_first_build": [list(d) for d in differing],
        "largest_final_position_difference_m": shift,
    }


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--run", required=True, help="the paper_scenes.py JSON of the saved run")
    p.add_argument("--state", required=True, help="the run's saved state (.npz)")
    p.add_argument("--build", action="append", default=[], metavar="NAME=WHEEL_OR_DIR",
                   help="a build to time (two or more; the first is the reference)")
    p.add_argument("--steps", type=int, default=6, help="steps per process")
    p.add_argument("--rounds", type=int, default=2, help="turns each build takes")
    p.add_argument("--out", default=None)
    p.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--positions-out", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        return worker(args)
    builds = dict(b.split("=", 1) for b in args.build if "=" in b)
    if len(builds) < 2 or len(builds) != len(args.build):
        p.error("give two or more builds as --build NAME=WHEEL_OR_DIR with distinct names")
    if args.steps < 1 or args.rounds < 1:
        p.error("--steps and --rounds must be >= 1")

    rec = C.Record("compare_builds", args)
    names = list(builds)
    runs, final_positions = [], {name: [] for name in names}
    with tempfile.TemporaryDirectory(prefix="peridyn_builds_") as tmp:
        scratch = Path(tmp)
        where = {name: C.build_dir(build, scratch, name) for name, build in builds.items()}
        digests = {name: C.core_digest(path) for name, path in where.items()}
        same = [name for name in names[1:] if digests[name] in
                [digests[earlier] for earlier in names[:names.index(name)]]]
        if same:
            p.error(f"builds {same} hold the same compiled core as an earlier build (see "
                    "--help on touching the sources before building)")
        rec.data["core_sha256"] = digests
        for r in range(args.rounds):
            for name in (names if r % 2 == 0 else names[::-1]):
                result, x = run_build(name, where[name], args, scratch, r)
                runs.append(result)
                final_positions[name].append(x)
                ms = [row["ms"] for row in result["rows"]]
                print(f"round {r + 1}, {name}: steps {result['first_step']}-"
                      f"{result['rows'][-1]['step']}, ms per step " +
                      " ".join(f"{m:.0f}" for m in ms), flush=True)
    summary, agreement = summarize(names, runs, final_positions)
    rec.data.update({"builds": builds, "runs": runs, "summary": summary,
                     "agreement": agreement})
    for name, s in summary.items():
        print(f"{name}: {s}")
    print(agreement)
    rec.write(args.out)


if __name__ == "__main__":
    main()
