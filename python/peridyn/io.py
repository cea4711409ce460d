"""Writing simulation output: single meshes and frame sequences.

Mesh files are written by trimesh (PLY or OBJ); frame sequences also go to one ``.npz`` that
numpy reads back with ``np.load``.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any, Dict, List, Literal, Optional, Union

import numpy as np
import numpy.typing as npt

__all__ = ["write_mesh", "FrameRecorder"]

PathLike = Union[str, "os.PathLike[str]"]

_FORMATS = ("ply", "obj")


def __getattr__(name: str) -> Any:
    """``save_state``, ``load_state`` and ``STATE_FORMAT_VERSION`` lived here before
    :mod:`peridyn.state`; they are found there (imported late: it imports this module)."""
    if name in ("save_state", "load_state", "STATE_FORMAT_VERSION"):
        from . import state

        return getattr(state, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


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
        If the suffix is not ``.ply`` or ``.obj``, ``V`` / ``F`` do not have shape (., 3),
        ``V`` holds anything but finite real numbers (for PLY, which stores float32: within
        float32's range), or ``F`` anything but whole vertex indices in ``[0, N)`` (the
        message names the first offending value).
    """
    import trimesh

    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    if fmt not in _FORMATS:
        raise ValueError(f"write_mesh: unsupported suffix {path.suffix!r} in {str(path)!r}; use .ply or .obj")
    V = _mesh_vertices(V, "write_mesh: V")
    F = _mesh_triangles(F, len(V), "write_mesh: F")
    if fmt == "ply":  # trimesh writes float32 coordinates
        beyond = (np.abs(V) > np.finfo(np.float32).max).any(axis=1)
        if beyond.any():
            i = int(np.flatnonzero(beyond)[0])
            raise ValueError(
                f"write_mesh: V: vertex {i} is {V[i].tolist()}, beyond the float32 range of a PLY "
                "file (it would be written as inf)"
            )
    mesh = trimesh.Trimesh(vertices=V, faces=F, process=False, validate=False)
    mesh.export(str(path), file_type=fmt)
    return path


def _mesh_vertices(V: npt.ArrayLike, name: str) -> np.ndarray:
    """``V`` as an (N, 3) float64 array of finite real numbers, or a ``ValueError``."""
    V = np.asarray(V)
    if V.dtype.kind not in "fiu":
        raise ValueError(f"{name} must hold real numbers, got dtype {V.dtype}")
    if V.ndim != 2 or V.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {V.shape}")
    V = V.astype(np.float64)
    bad = ~np.isfinite(V).all(axis=1)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"{name}: vertex {i} is not finite: {V[i].tolist()}")
    return V


def _mesh_triangles(F: npt.ArrayLike, n: int, name: str) -> np.ndarray:
    """``F`` as an (M, 3) int64 array of vertex indices in [0, n), or a ``ValueError``: whole
    numbers only (integer dtypes, or floats with integral values)."""
    F = np.asarray(F)
    if F.dtype.kind not in "fiu":
        raise ValueError(f"{name} must hold integer vertex indices, got dtype {F.dtype}")
    if F.ndim != 2 or F.shape[1] != 3:
        raise ValueError(f"{name} must have shape (M, 3), got {F.shape}")
    if F.dtype.kind == "f":
        fractional = ~(np.isfinite(F) & (F == np.floor(F)))
        if fractional.any():
            t = int(np.flatnonzero(fractional.any(axis=1))[0])
            raise ValueError(f"{name}: triangle {t} holds {F[t].tolist()}, not whole vertex indices")
    out = (F < 0) | (F >= n)
    if out.any():
        t = int(np.flatnonzero(out.any(axis=1))[0])
        raise ValueError(
            f"{name}: triangle {t} holds {F[t].tolist()}, vertex indices must be in [0, {n})"
        )
    return F.astype(np.int64)


class FrameRecorder:
    """Record the bodies of a :class:`peridyn.Solver` to mesh files and one ``.npz``.

    Use it as the ``callback`` of :meth:`peridyn.Solver.run` (it records after every
    ``every``-th step), or call :meth:`record` yourself. :meth:`close` writes the ``.npz``;
    the recorder is also a context manager that closes itself.

    Files in ``directory``:

    - ``frame_00000.ply``, ``frame_00001.ply``, ... (one per recorded frame) when the solver
      has one body; ``body0_frame_00000.ply``, ``body1_frame_00000.ply``, ... when it has
      several. Frames are numbered 0, 1, 2, ... in the order recorded. A particle set is
      written as a point cloud (vertices without faces).
    - with ``surfaces=True``, also ``frame_00000_surface.ply`` (or
      ``body1_frame_00000_surface.ply``, ...) for each particle set: its surface as a closed
      triangle mesh (:func:`peridyn.particle_surface` with its defaults), for fluids.
    - ``frames.npz`` (at :meth:`close`) with ``times`` (F,) in s, ``steps`` (F,) the number of
      steps taken at each frame, and for each body ``b``: ``positions_b`` (F, N_b, 3) in m,
      ``triangles_b`` (M_b, 3) (a membrane; none for a particle set), ``velocities_b``
      (F, N_b, 3) in m/s and ``stretch_b`` (F, N_b), the largest in-plane principal stretch
      (when the body has them); ``collider_rotations`` (F, C, 3, 3) and
      ``collider_translations`` (F, C, 3) in m, each collider's pose
      (``Solver.collider_pose``). :func:`peridyn.load_recording` reads it back.

    Parameters
    ----------
    directory : str or path-like
        Output directory (created if missing).
    fmt : {"ply", "obj", None}
        Mesh file format per frame; ``None`` records only the ``.npz``.
    every : int
        When used as a callback, record after every ``every``-th step (>= 1).
    surfaces : bool
        Also write each particle set's surface mesh per frame (needs ``fmt``; costs a grid of
        about ``(extent / (spacing / 2))^3`` cells per body and frame).
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
        surfaces: bool = False,
        npz_name: str = "frames.npz",
    ) -> None:
        if fmt is not None and fmt.lower() not in _FORMATS:
            raise ValueError(f"FrameRecorder: fmt must be 'ply', 'obj' or None, got {fmt!r}")
        if isinstance(every, bool) or int(every) != every or every < 1:
            raise ValueError(f"FrameRecorder: every must be an integer >= 1, got {every!r}")
        if not isinstance(surfaces, (bool, np.bool_)):
            raise ValueError(f"FrameRecorder: surfaces must be True or False, got {surfaces!r}")
        if surfaces and fmt is None:
            raise ValueError("FrameRecorder: surfaces=True writes mesh files: give fmt 'ply' or 'obj'")
        self.directory = Path(directory)
        self.directory.mkdir(parents=True, exist_ok=True)
        self.fmt = None if fmt is None else fmt.lower()
        self.every = int(every)
        self.surfaces = bool(surfaces)
        self.npz_path = self.directory / npz_name
        self.files: List[Path] = []
        self._frames: List[Any] = []  # peridyn.recording.Frame, one per recorded frame
        self._colliders: List[Any] = []
        self._closed = False

    @property
    def num_frames(self) -> int:
        """Number of frames recorded so far."""
        return len(self._frames)

    def __call__(self, solver: Any, stats: Any) -> None:
        """Solver callback: record when ``stats.step + 1`` is a multiple of ``every``."""
        if (int(stats.step) + 1) % self.every == 0:
            self.record(solver)

    def record(self, solver: Any) -> int:
        """Record the current state of every body of ``solver`` now (and its colliders' poses).

        A body is anything with ``positions``; one with ``triangles`` is written as a mesh file,
        one without (a particle set) as a point cloud (a mesh file without faces).

        Returns
        -------
        int
            Index of the frame just recorded.
        """
        from .recording import capture

        if self._closed:
            raise RuntimeError("FrameRecorder.record: the recorder is closed")
        if not list(solver.bodies):
            raise ValueError("FrameRecorder.record: the solver has no bodies")
        frame_state = capture(solver)
        positions, triangles = frame_state.positions, frame_state.triangles
        if self._frames:
            # Every frame goes into one array per body in the .npz: check before recording.
            first = self._frames[0]
            if len(positions) != len(first.positions):
                raise ValueError(
                    f"FrameRecorder.record: the solver now has {len(positions)} bodies, "
                    f"the recording started with {len(first.positions)}"
                )
            for b, (V, tris) in enumerate(zip(positions, triangles)):
                n = len(first.positions[b])
                if len(V) != n:
                    raise ValueError(
                        f"FrameRecorder.record: body {b} now has {len(V)} vertices, "
                        f"the recording started with {n}"
                    )
                same = (tris is None) == (first.triangles[b] is None) and (
                    tris is None or np.array_equal(tris, first.triangles[b]))
                if not same:
                    raise ValueError(
                        f"FrameRecorder.record: body {b} has other triangles than when the "
                        "recording started"
                    )
                frame_state.triangles[b] = first.triangles[b]
            if len(frame_state.poses) != len(first.poses):
                raise ValueError(
                    f"FrameRecorder.record: the solver now has {len(frame_state.poses)} colliders, "
                    f"the recording started with {len(first.poses)}"
                )
        frame = self.num_frames
        if self.fmt is not None:
            bodies = list(solver.bodies)
            for b, (V, tris) in enumerate(zip(positions, triangles)):
                stem = f"frame_{frame:05d}" if len(positions) == 1 else f"body{b}_frame_{frame:05d}"
                if tris is None and self.surfaces:
                    from .surface import particle_surface

                    S, T = particle_surface(V, bodies[b].spacing)
                    self.files.append(write_mesh(self.directory / f"{stem}_surface.{self.fmt}", S, T))
                if tris is None:  # a particle set: a point cloud
                    tris = np.zeros((0, 3), dtype=np.int64)
                self.files.append(write_mesh(self.directory / f"{stem}.{self.fmt}", V, tris))
        # The frame is recorded for the .npz only once everything above succeeded.
        if not self._frames:
            self._colliders = list(getattr(solver, "colliders", ()))
        self._frames.append(frame_state)
        return frame

    def recording(self) -> Any:
        """The frames recorded so far as a :class:`peridyn.recording.Recording` (with the
        solver's collider objects), for :func:`peridyn.animate`, :func:`peridyn.show` and
        :func:`peridyn.write_usd`."""
        from .recording import stack

        return stack(self._frames, self._colliders)

    def close(self) -> Path:
        """Write the ``.npz`` archive (once) and return its path.

        The archive is written to a temporary file that replaces ``npz_path`` when complete;
        if writing fails, the recorder stays open and ``close`` can be called again.
        """
        if not self._closed:
            if self._frames:
                arrays = self.recording().to_arrays()
            else:
                arrays = {"times": np.zeros(0), "steps": np.zeros(0, dtype=np.int64)}
            _write_npz(self.npz_path, arrays)
            self._closed = True
        return self.npz_path

    def __enter__(self) -> "FrameRecorder":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"FrameRecorder({str(self.directory)!r}, fmt={self.fmt!r}, every={self.every}, "
            f"surfaces={self.surfaces}, "
            f"frames={self.num_frames})"
        )


def _write_npz(path: Path, arrays: Dict[str, np.ndarray]) -> None:
    """Writes ``arrays`` as a compressed ``.npz`` at exactly ``path``, through a temporary file
    in the same directory that replaces it once complete and on disk: a failed write leaves
    an earlier file at ``path`` intact."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            np.savez_compressed(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
