"""Writing simulation output: single meshes and frame sequences.

Mesh files are written by trimesh (PLY or OBJ); frame sequences also go to one ``.npz`` that
numpy reads back with ``np.load``.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Dict, List, Literal, Optional, Union

import numpy as np
import numpy.typing as npt

__all__ = ["write_mesh", "FrameRecorder", "save_state", "load_state"]

PathLike = Union[str, "os.PathLike[str]"]

_FORMATS = ("ply", "obj")


def write_mesh(path: PathLike, V: npt.ArrayLike, F: npt.ArrayLike) -> Path:
    """Write a triangle mesh to a PLY (binary) or OBJ file, chosen by the file suffix.

    Parameters
    ----------
    path : str or path-like
        Target file, ending in ``.ply`` or ``.obj``. Parent directories must exist.
    V : (N, 3) array_like
        Vertex positions in m.
    F : (M, 3) array_like of int
        Triangles (vertex indices).

    Returns
    -------
    pathlib.Path
        The path written.

    Raises
    ------
    ValueError
        If the suffix is not ``.ply`` or ``.obj``, or ``V`` / ``F`` do not have shape (., 3).
    """
    import trimesh

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in _FORMATS:
        raise ValueError(f"write_mesh: unsupported suffix {path.suffix!r} in {str(path)!r}; use .ply or .obj")
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F)
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"write_mesh: V must have shape (N, 3), got {V.shape}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"write_mesh: F must have shape (M, 3), got {F.shape}")
    mesh = trimesh.Trimesh(vertices=V, faces=F.astype(np.int64), process=False, validate=False)
    mesh.export(str(path), file_type=fmt)
    return path


class FrameRecorder:
    """Record the bodies of a :class:`peridyn.Solver` to mesh files and one ``.npz``.

    Use it as the ``callback`` of :meth:`peridyn.Solver.run` (it records after every
    ``every``-th step), or call :meth:`record` yourself. :meth:`close` writes the ``.npz``;
    the recorder is also a context manager that closes itself.

    Files in ``directory``:

    - ``frame_00000.ply``, ``frame_00001.ply``, ... (one per recorded frame) when the solver
      has one body; ``body0_frame_00000.ply``, ``body1_frame_00000.ply``, ... when it has
      several. Frames are numbered 0, 1, 2, ... in the order recorded.
    - ``frames.npz`` (at :meth:`close`) with ``times`` (F,) in s, ``steps`` (F,) the number of
      steps taken at each frame, and for each body ``b``: ``positions_b`` (F, N_b, 3) in m and
      ``triangles_b`` (M_b, 3).

    Parameters
    ----------
    directory : str or path-like
        Output directory (created if missing).
    fmt : {"ply", "obj", None}
        Mesh file format per frame; ``None`` records only the ``.npz``.
    every : int
        When used as a callback, record after every ``every``-th step (>= 1).
    npz_name : str
        File name of the archive written by :meth:`close`.

    Examples
    --------
    >>> rec = FrameRecorder("out", every=10)            # doctest: +SKIP
    >>> rec.record(solver)                              # the initial state  # doctest: +SKIP
    >>> solver.run(500, callback=rec)                   # doctest: +SKIP
    >>> rec.close()                                     # doctest: +SKIP
    """

    def __init__(
        self,
        directory: PathLike,
        *,
        fmt: Optional[Literal["ply", "obj"]] = "ply",
        every: int = 1,
        npz_name: str = "frames.npz",
    ) -> None:
        if fmt is not None and fmt.lower() not in _FORMATS:
            raise ValueError(f"FrameRecorder: fmt must be 'ply', 'obj' or None, got {fmt!r}")
        if isinstance(every, bool) or int(every) != every or every < 1:
            raise ValueError(f"FrameRecorder: every must be an integer >= 1, got {every!r}")
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.fmt = None if fmt is None else fmt.lower()
        self.every = int(every)
        self.npz_path = self.directory / npz_name
        self.files: List[Path] = []
        self._positions: List[List[np.ndarray]] = []
        self._triangles: List[np.ndarray] = []
        self._times: List[float] = []
        self._steps: List[int] = []
        self._closed = False

    @property
    def num_frames(self) -> int:
        """Number of frames recorded so far."""
        return len(self._times)

    def __call__(self, solver: Any, stats: Any) -> None:
        """Solver callback: record when ``stats.step + 1`` is a multiple of ``every``."""
        if (int(stats.step) + 1) % self.every == 0:
            self.record(solver)

    def record(self, solver: Any) -> int:
        """Record the current state of every body of ``solver`` now.

        Returns
        -------
        int
            Index of the frame just recorded.
        """
        if self._closed:
            raise RuntimeError("FrameRecorder.record: the recorder is closed")
        bodies = list(solver.bodies)
        if not bodies:
            raise ValueError("FrameRecorder.record: the solver has no bodies")
        if not self._triangles:
            self._triangles = [np.asarray(b.triangles, dtype=np.int64) for b in bodies]
            self._positions = [[] for _ in bodies]
        elif len(bodies) != len(self._triangles):
            raise ValueError(
                f"FrameRecorder.record: the solver now has {len(bodies)} bodies, "
                f"the recording started with {len(self._triangles)}"
            )
        frame = self.num_frames
        for b, body in enumerate(bodies):
            V = np.array(body.positions, dtype=np.float64)
            self._positions[b].append(V)
            if self.fmt is not None:
                stem = f"frame_{frame:05d}" if len(bodies) == 1 else f"body{b}_frame_{frame:05d}"
                self.files.append(write_mesh(self.directory / f"{stem}.{self.fmt}", V, self._triangles[b]))
        self._times.append(float(solver.time))
        self._steps.append(int(solver.steps_taken))
        return frame

    def close(self) -> Path:
        """Write the ``.npz`` archive (once) and return its path."""
        if not self._closed:
            arrays = {
                "times": np.asarray(self._times, dtype=np.float64),
                "steps": np.asarray(self._steps, dtype=np.int64),
            }
            for b, tris in enumerate(self._triangles):
                arrays[f"positions_{b}"] = np.stack(self._positions[b])
                arrays[f"triangles_{b}"] = tris
            np.savez_compressed(self.npz_path, **arrays)
            self._closed = True
        return self.npz_path

    def __enter__(self) -> "FrameRecorder":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"FrameRecorder({str(self.directory)!r}, fmt={self.fmt!r}, every={self.every}, "
            f"frames={self.num_frames})"
        )


def save_state(path: PathLike, solver: Any) -> Path:
    """Saves everything that a solver's next steps depend on to a compressed ``.npz`` file.

    That is each body's positions, velocities, pinned vertices and pin targets, each collider's
    motion (the pose its velocity carries on from and a pose set with
    ``Solver.set_collider_pose`` for the next step, if any), the solver's clock and the state
    its contact carries from one step to the next (``Solver.contact_warm_start``).
    :func:`load_state` into a solver set up the same way (same bodies, parameters and colliders)
    then continues the simulation bit for bit.

    Parameters
    ----------
    path : str or os.PathLike
        Destination ``.npz`` file.
    solver : Solver
        The solver to save.

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    arrays: Dict[str, np.ndarray] = {
        "time": np.array(solver.time),
        "steps_taken": np.array(solver.steps_taken),
        "bodies": np.array(len(solver.bodies)),
    }
    for b, body in enumerate(solver.bodies):
        arrays[f"positions_{b}"] = body.positions
        arrays[f"velocities_{b}"] = body.velocities
        arrays[f"pinned_{b}"] = body.pinned
        arrays[f"pin_targets_{b}"] = body.pin_targets
    arrays["colliders"] = np.array(len(solver.colliders))
    for c in range(len(solver.colliders)):
        (base_r, base_t), target = solver.collider_motion(c)
        arrays[f"collider_base_rotation_{c}"] = np.asarray(base_r, dtype=np.float64)
        arrays[f"collider_base_translation_{c}"] = np.asarray(base_t, dtype=np.float64)
        if target is not None:
            arrays[f"collider_target_rotation_{c}"] = np.asarray(target[0], dtype=np.float64)
            arrays[f"collider_target_translation_{c}"] = np.asarray(target[1], dtype=np.float64)
    arrays.update(_solver_state(solver))
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)
    return path


def _solver_state(solver: Any, data: Any = None) -> Dict[str, np.ndarray]:
    """The solver's own state that its next steps depend on, as ``.npz`` entries (``data``
    None), or restores it from ``data`` (a file without it: none, as in a fresh solver);
    raises ``ValueError`` on a bad entry."""
    if data is None:
        return {"contact_warm_start": np.asarray(solver.contact_warm_start(), dtype=np.float64)}
    warm = data["contact_warm_start"] if "contact_warm_start" in data else np.zeros((0, 3))
    solver.set_contact_warm_start(warm)
    return {}


def load_state(path: PathLike, solver: Any) -> None:
    """Restores a state written by :func:`save_state` into ``solver`` (same bodies and
    colliders, in order).

    Raises
    ------
    ValueError
        If the file holds a different number of bodies or colliders, or a body's vertex count
        differs.
    """
    with np.load(Path(path)) as data:
        bodies = solver.bodies
        if int(data["bodies"]) != len(bodies):
            raise ValueError(
                f"load_state: {path} holds {int(data['bodies'])} bodies, the solver has {len(bodies)}"
            )
        for b, body in enumerate(bodies):
            positions = data[f"positions_{b}"]
            if positions.shape != (body.num_vertices, 3):
                raise ValueError(
                    f"load_state: body {b} has {body.num_vertices} vertices, "
                    f"the file has {positions.shape[0]}"
                )
        # files written before collider motion was saved hold no "colliders"
        colliders = int(data["colliders"]) if "colliders" in data else 0
        if "colliders" in data and colliders != len(solver.colliders):
            raise ValueError(
                f"load_state: {path} holds {colliders} colliders, the solver has {len(solver.colliders)}"
            )
        _solver_state(solver, data)
        for b, body in enumerate(bodies):
            body.positions = data[f"positions_{b}"]
            body.velocities = data[f"velocities_{b}"]
            body.unpin()
            pinned = data[f"pinned_{b}"]
            if len(pinned):
                body.pin(pinned, data[f"pin_targets_{b}"])
        for c in range(colliders):
            target = {}
            if f"collider_target_rotation_{c}" in data:
                target = dict(target_rotation=data[f"collider_target_rotation_{c}"],
                              target_translation=data[f"collider_target_translation_{c}"])
            solver.set_collider_motion(c, base_rotation=data[f"collider_base_rotation_{c}"],
                                       base_translation=data[f"collider_base_translation_{c}"], **target)
        solver.set_clock(float(data["time"]), int(data["steps_taken"]))
