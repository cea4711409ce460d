"""A recorded run in memory: the frames that animations, notebook views and USD files show.

A :class:`Recording` holds, per recorded frame, the time, the step count, every body's
positions (and, where the body has them, velocities and principal stretches) and every
collider's pose. :class:`peridyn.FrameRecorder` builds one while a solver runs
(:meth:`FrameRecorder.recording`) and writes it to its ``.npz``, which :func:`load_recording`
reads back.

A body is anything with ``positions`` ((N, 3), m): a membrane also has ``triangles`` (or
``faces``) and is drawn as a surface; a body without them (a particle set) is drawn as points.
``velocities`` ((N, 3), m/s) and ``stretches()`` ((N, 3) principal stretches) are recorded when
the body has them.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, List, Optional, Sequence, Union

import numpy as np

__all__ = ["BodyTrack", "Recording", "capture", "load_recording", "as_recording", "FIELDS"]

PathLike = Union[str, "os.PathLike[str]"]

#: The named colour fields: per-vertex values a view can colour by.
FIELDS = {
    "speed": "speed |v| (m/s)",
    "stretch": "largest in-plane principal stretch (1 = rest length)",
    "contact": "distance to the nearest collider (m; 0 = touching)",
    "height": "height along +z (m)",
}


def _robust_range(values: np.ndarray) -> tuple:
    """Default colour limits of a field: its minimum to its 99th percentile, so that a few
    outliers (a whipping corner) do not wash out the colours of the rest; (0, 1) if empty."""
    if len(values) == 0:
        return 0.0, 1.0
    lo, hi = float(values.min()), float(np.percentile(values, 99.0))
    return (lo, hi) if hi > lo else (lo, lo + 1.0)


def body_triangles(body: Any) -> Optional[np.ndarray]:
    """The body's triangles (M, 3) as int64, or None for a body without faces (particles)."""
    for name in ("triangles", "faces"):
        tris = getattr(body, name, None)
        if tris is not None:
            return np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    return None


@dataclass
class BodyTrack:
    """One body over the recorded frames.

    Attributes
    ----------
    positions : (F, N, 3) float64, m
    triangles : (M, 3) int64, or None for a point body (particles)
    velocities : (F, N, 3) float64 in m/s, or None when the body has none
    stretch : (F, N) float64, the largest in-plane principal stretch, or None
    """

    positions: np.ndarray
    triangles: Optional[np.ndarray] = None
    velocities: Optional[np.ndarray] = None
    stretch: Optional[np.ndarray] = None


@dataclass
class Recording:
    """Frames of a run: ``times`` (F,) in s, ``steps`` (F,) steps taken, ``bodies`` (one
    :class:`BodyTrack` each), ``colliders`` (the collider objects, possibly none) and their
    poses per frame, ``collider_rotations`` (F, C, 3, 3) and ``collider_translations``
    (F, C, 3) in m (a point ``b`` of collider ``c`` as given is at ``R @ b + t``)."""

    times: np.ndarray
    steps: np.ndarray
    bodies: List[BodyTrack]
    colliders: List[Any] = field(default_factory=list)
    collider_rotations: Optional[np.ndarray] = None
    collider_translations: Optional[np.ndarray] = None

    @property
    def num_frames(self) -> int:
        return len(self.times)

    def collider_pose(self, frame: int, c: int) -> Optional[tuple]:
        """``(rotation, translation)`` of collider ``c`` at ``frame``, or None if not recorded."""
        if self.collider_rotations is None or c >= self.collider_rotations.shape[1]:
            return None
        return self.collider_rotations[frame, c], self.collider_translations[frame, c]

    def field(self, name: Union[str, Callable[..., Any]], frame: int, body: int) -> np.ndarray:
        """Per-vertex values (N,) of a colour field at ``frame`` for ``body``.

        ``name`` is one of :data:`FIELDS` or a function ``f(recording, frame, body)`` returning
        (N,) numbers. Raises ``ValueError`` naming the field when the recording lacks it.
        """
        track = self.bodies[body]
        X = track.positions[frame]
        if callable(name):
            values = np.asarray(name(self, frame, body), dtype=np.float64).reshape(-1)
            if values.shape != (len(X),):
                raise ValueError(f"field function gave shape {values.shape} for body {body}, "
                                 f"expected ({len(X)},)")
            return values
        if name == "speed":
            if track.velocities is None:
                raise ValueError(f"field 'speed': body {body} has no recorded velocities")
            return np.linalg.norm(track.velocities[frame], axis=1)
        if name == "stretch":
            if track.stretch is None:
                raise ValueError(f"field 'stretch': body {body} has no recorded stretches")
            return track.stretch[frame]
        if name == "height":
            return X[:, 2].copy()
        if name == "contact":
            if not self.colliders:
                raise ValueError("field 'contact': the recording has no colliders")
            gaps = []
            for c, col in enumerate(self.colliders):
                pose = self.collider_pose(frame, c)
                if pose is None:
                    gaps.append(np.asarray(col.signed_distance(X, float(self.times[frame]))))
                else:
                    R, t = pose
                    gaps.append(np.asarray(col.signed_distance((X - t) @ R)))
            return np.maximum(np.min(gaps, axis=0), 0.0)
        raise ValueError(f"unknown field {name!r}; use one of {sorted(FIELDS)} or a function")

    def to_arrays(self) -> Dict[str, np.ndarray]:
        """The recording as named arrays (the ``.npz`` layout of :class:`FrameRecorder`)."""
        arrays = {"times": np.asarray(self.times, dtype=np.float64),
                  "steps": np.asarray(self.steps, dtype=np.int64)}
        for b, track in enumerate(self.bodies):
            arrays[f"positions_{b}"] = track.positions
            if track.triangles is not None:
                arrays[f"triangles_{b}"] = track.triangles
            if track.velocities is not None:
                arrays[f"velocities_{b}"] = track.velocities
            if track.stretch is not None:
                arrays[f"stretch_{b}"] = track.stretch
        if self.collider_rotations is not None:
            arrays["collider_rotations"] = self.collider_rotations
            arrays["collider_translations"] = self.collider_translations
        return arrays


class Frame:
    """One frame captured from a solver (see :func:`capture`)."""

    __slots__ = ("time", "steps", "positions", "triangles", "velocities", "stretch", "poses")

    def __init__(self, solver: Any) -> None:
        bodies = list(solver.bodies)
        self.time = float(solver.time)
        self.steps = int(solver.steps_taken)
        self.positions = [np.array(b.positions, dtype=np.float64).reshape(-1, 3) for b in bodies]
        self.triangles = [body_triangles(b) for b in bodies]
        self.velocities = [None if getattr(b, "velocities", None) is None
                           else np.array(b.velocities, dtype=np.float64).reshape(-1, 3) for b in bodies]
        self.stretch = [np.array(b.stretches(), dtype=np.float64)[:, 0] if hasattr(b, "stretches") else None
                        for b in bodies]
        n = len(getattr(solver, "colliders", ()))
        pose = getattr(solver, "collider_pose", None)
        self.poses = [tuple(np.array(p, dtype=np.float64) for p in pose(c)) for c in range(n)] if pose else []


def capture(solver: Any) -> Frame:
    """The state of every body and collider of ``solver`` now (copies)."""
    return Frame(solver)


def stack(frames: Sequence[Frame], colliders: Sequence[Any] = ()) -> Recording:
    """A :class:`Recording` of captured frames (all with the same bodies)."""
    if not frames:
        raise ValueError("a recording needs at least one frame")
    first = frames[0]
    bodies = []
    for b, tris in enumerate(first.triangles):
        vel = None if first.velocities[b] is None else np.stack([f.velocities[b] for f in frames])
        st = None if first.stretch[b] is None else np.stack([f.stretch[b] for f in frames])
        bodies.append(BodyTrack(np.stack([f.positions[b] for f in frames]), tris, vel, st))
    rot = trans = None
    if first.poses:
        rot = np.array([[p[0] for p in f.poses] for f in frames], dtype=np.float64)
        trans = np.array([[p[1] for p in f.poses] for f in frames], dtype=np.float64)
    return Recording(np.array([f.time for f in frames]), np.array([f.steps for f in frames], dtype=np.int64),
                     bodies, list(colliders), rot, trans)


def load_recording(path: PathLike, colliders: Sequence[Any] = ()) -> Recording:
    """Read a :class:`FrameRecorder` ``.npz`` back. The file holds no collider objects: pass
    the ones of the run as ``colliders`` (in the solver's order) to have them drawn."""
    with np.load(path, allow_pickle=False) as data:
        keys = set(data.files)
        for key in ("times", "steps", "positions_0"):
            if key not in keys:
                raise ValueError(f"load_recording: {str(path)!r} has no {key!r}: not a FrameRecorder file")
        bodies = []
        b = 0
        while f"positions_{b}" in keys:
            get = lambda k: data[f"{k}_{b}"] if f"{k}_{b}" in keys else None  # noqa: E731
            bodies.append(BodyTrack(data[f"positions_{b}"], get("triangles"), get("velocities"), get("stretch")))
            b += 1
        rot = data["collider_rotations"] if "collider_rotations" in keys else None
        trans = data["collider_translations"] if "collider_translations" in keys else None
        return Recording(data["times"], data["steps"], bodies, list(colliders), rot, trans)


def as_recording(source: Any, colliders: Optional[Sequence[Any]] = None) -> Recording:
    """A :class:`Recording` from a Recording, a :class:`FrameRecorder` (its frames so far), a
    path to a recorder's ``.npz``, or a solver (its state now, one frame). ``colliders``
    replaces the recording's collider objects when given."""
    if isinstance(source, Recording):
        rec = source
    elif hasattr(source, "recording") and callable(source.recording):
        rec = source.recording()
    elif isinstance(source, (str, os.PathLike)):
        rec = load_recording(source)
    elif hasattr(source, "bodies"):
        rec = stack([capture(source)], list(getattr(source, "colliders", ())))
    else:
        raise ValueError(f"cannot make a recording of a {type(source).__name__}: pass a Solver, "
                         "a FrameRecorder, a Recording or the path of a recorder's .npz")
    if colliders is not None:
        rec = Recording(rec.times, rec.steps, rec.bodies, list(colliders),
                        rec.collider_rotations, rec.collider_translations)
    return rec
