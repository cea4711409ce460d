"""``python -m peridyn``: run a scene (by default a cloth draping onto a sphere; with
``--scene torus`` an elastic torus of particles falling onto the ground) and save it.

Writes one PLY per recorded frame (a particle body as a point cloud), ``frames.npz`` with every recorded frame, ``final.png``, a
picture of the last frame, and ``animation.mp4`` of the run (``animation.gif`` where no MP4
encoder is available); with ``--usd`` also ``scene.usd``, the run as one USD stage. Then prints
a summary.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import List, Optional


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text}")
    return value


def _nonnegative_int(text: str) -> int:
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be an integer >= 0, got {text}")
    return value


def _positive_float(text: str) -> float:
    value = float(text)
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


#: The scenes of ``--scene``: the smallest ``--n``, the fields ``--color`` can show, and
#: whether the scene runs on the GPU backend.
SCENES = {
    "cloth": {"min_n": 2, "fields": ("speed", "stretch", "contact", "height"), "gpu": True},
    "torus": {"min_n": 4, "fields": ("speed", "height"), "gpu": False},
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m peridyn",
        description="Simulate a scene: by default a square cloth pinned along one edge swings "
        "down under gravity and drapes onto a sphere; with --scene torus an elastic torus of "
        "particles falls onto the ground. Writes PLY frames, an .npz of all frames, "
        "final.png and animation.mp4 (or .gif) to --out, then prints a summary.",
    )
    parser.add_argument("--scene", choices=tuple(SCENES), default="cloth",
                        help="'cloth' (a membrane, peridyn.scenes.default_scene) or 'torus' (elastic "
                        "particles, peridyn.scenes.elastic_torus_scene) (default: cloth)")
    parser.add_argument("--steps", type=_nonnegative_int, default=None,
                        help="time steps to run (default: 1 s of simulated time)")
    parser.add_argument("--n", type=_positive_int, default=None,
                        help="resolution: cloth vertices per side (default: 120, i.e. 14400 vertices) "
                        "or particles across the torus (default: 16)")
    parser.add_argument("--dt", type=_positive_float, default=None,
                        help="time step in s (default: the scene's, 2e-3 for the cloth, 1/240 for "
                        "the torus)")
    parser.add_argument("--out", type=Path, default=Path("peridyn_out"),
                        help="output directory (default: ./peridyn_out)")
    parser.add_argument("--frame-every", type=_positive_int, default=25,
                        help="write a frame every this many steps (default: 25)")
    parser.add_argument("--threads", type=_positive_int, default=None,
                        help="worker threads of the CPU backend (default: all cores)")
    parser.add_argument("--backend", choices=("cpu", "gpu"), default="cpu",
                        help="'cpu' (Rust threads) or 'gpu' (wgpu compute shaders, f32; "
                        "see peridyn.gpu_info()) (default: cpu)")
    parser.add_argument("--color", choices=("speed", "stretch", "contact", "height", "none"), default="speed",
                        help="colour the animation's body by this per-point field (default: speed; "
                        "the torus has speed and height)")
    parser.add_argument("--no-animation", action="store_true", help="do not write animation.mp4")
    parser.add_argument("--usd", action="store_true",
                        help='also write scene.usd, the run as one USD stage (pip install "peridyn[usd]")')
    parser.add_argument("--no-progress", action="store_true", help="hide the progress bars")
    return parser


def main(argv: Optional[List[str]] = None) -> int:
    args = build_parser().parse_args(argv)
    spec = SCENES[args.scene]
    if args.n is not None and args.n < spec["min_n"]:
        print(f"error: --n must be >= {spec['min_n']} for --scene {args.scene}", file=sys.stderr)
        return 2
    if args.color not in spec["fields"] + ("none",):
        print(f"error: --color {args.color} is not available for --scene {args.scene} "
              f"(choose from {', '.join(spec['fields'] + ('none',))})", file=sys.stderr)
        return 2
    if args.backend == "gpu" and not spec["gpu"]:
        print(f"error: --scene {args.scene} runs on --backend cpu only (particles have no GPU "
              "kernels yet)", file=sys.stderr)
        return 2

    import peridyn
    from peridyn.io import FrameRecorder
    from peridyn.render import render_png
    from peridyn.scenes import default_scene, elastic_torus_scene

    if args.usd:
        try:
            import pxr  # noqa: F401  (checked before a long run, not after)
        except ImportError:
            print('error: --usd needs usd-core: pip install "peridyn[usd]"', file=sys.stderr)
            return 2
    if args.backend == "gpu" and args.threads is not None:
        print("error: --threads applies to --backend cpu only", file=sys.stderr)
        return 2

    kwargs = {"threads": args.threads}
    if args.n is not None:
        kwargs["n"] = args.n
    if args.dt is not None:
        kwargs["dt"] = args.dt
    try:
        if args.scene == "cloth":
            scene = default_scene(backend=args.backend, **kwargs)
        else:
            scene = elastic_torus_scene(**kwargs)
    except RuntimeError as err:  # no GPU adapter: the message says what is missing
        print(f"error: {err}", file=sys.stderr)
        return 2
    steps = scene.steps if args.steps is None else args.steps
    solver = scene.solver
    (body,) = scene.bodies.values()
    is_membrane = hasattr(body, "triangles")
    count, noun = (body.num_vertices, "vertices") if is_membrane else (len(body.positions), "particles")
    points = f"{count} {noun}"

    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    print(f"peridyn {peridyn.__version__}: {scene.description}")
    shape = f"{points}, {body.num_triangles} triangles" if is_membrane else points
    print(f"{shape}, dt = {solver.dt:g} s, {steps} steps, backend {solver.backend}, "
          f"{solver.threads} threads")

    recorder = FrameRecorder(out, fmt="ply", every=args.frame_every)
    recorder.record(solver)  # the initial state is frame 0
    try:
        summary = solver.run(steps, progress=not args.no_progress, callback=recorder)
    except peridyn.DivergenceError as err:
        recorder.close()
        print(f"error: the simulation diverged: {err}", file=sys.stderr)
        return 1
    if solver.steps_taken % args.frame_every != 0:
        recorder.record(solver)  # always keep the last state
    npz = recorder.close()
    png = render_png(out / "final.png", body, colliders=solver.colliders,
                     title=f"t = {solver.time:.3g} s")
    movie = None
    if not args.no_animation:
        from peridyn.animation import animate

        movie = animate(recorder, out / "animation.mp4", field=None if args.color == "none" else args.color,
                        fps=10.0, progress=not args.no_progress)
    usd = None
    if args.usd:
        from peridyn.usd import write_usd

        usd = write_usd(out / "scene.usd", recorder)

    print()
    print(f"{noun:18s} {count}")
    print(f"steps              {summary.steps}")
    print(f"simulated time     {solver.time:.4g} s")
    print(f"ms per step        {summary.ms_per_step_median:.2f} (median), "
          f"{summary.ms_per_step_mean:.2f} (mean)")
    print(f"iterations/step    {summary.mean_iterations:.2f} (mean), {summary.max_iterations} (max)")
    print(f"converged          {100.0 * summary.converged_fraction:.1f} % of steps")
    print(f"wall time          {summary.wall_seconds:.1f} s")
    print(f"output             {out.resolve()}")
    print(f"  frames           {recorder.num_frames} x frame_NNNNN.ply")
    print(f"  all frames       {npz.name}")
    print(f"  picture          {png.name}")
    if movie is not None:
        print(f"  animation        {movie.name}")
    if usd is not None:
        print(f"  USD stage        {usd.name}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
