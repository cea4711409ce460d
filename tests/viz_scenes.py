"""Small recorded runs shared by the animation, notebook-view and USD tests."""

import numpy as np

import peridyn


class PointSet:
    """A body drawn as points: the protocol a particle set meets (``positions`` only)."""

    def __init__(self, positions):
        self.positions = np.asarray(positions, dtype=np.float64)


class WithPoints:
    """A solver seen with one more body, a :class:`PointSet`: what a recorder sees once
    particles are solver bodies (clock, colliders and poses are the real solver's)."""

    def __init__(self, solver, points):
        self._solver = solver
        self.points = points

    @property
    def bodies(self):
        return list(self._solver.bodies) + [self.points]

    def __getattr__(self, name):
        return getattr(self._solver, name)


def swinging_cloth(tmp_path, *, n=6, steps=24, every=6):
    """A pinned 0.5 m cloth falling towards a sphere, beside a box moving up at 1 m/s and a
    floor plane; returns ``(solver, cloth, recorder)`` with ``steps / every + 1`` frames."""
    V, F = peridyn.grid(n, n, size=(0.5, 0.5))
    cloth = peridyn.Membrane(V, F, thickness=1e-3, density=300.0, material=peridyn.StretchA3(s0=2e4))
    cloth.pin(np.flatnonzero(np.isclose(V[:, 1], 0.5)))
    solver = peridyn.Solver(dt=2e-3, threads=1)
    solver.add(cloth)
    solver.add_collider(peridyn.Sphere(center=(0.25, 0.2, -0.3), radius=0.15, friction=0.2))
    solver.add_collider(peridyn.Box(center=(1.0, 0.25, -0.5), half_extents=(0.1, 0.2, 0.05), velocity=(0.0, 0.0, 1.0)))
    solver.add_collider(peridyn.Plane(point=(0.0, 0.0, -0.8)))
    rec = peridyn.FrameRecorder(tmp_path, fmt=None, every=every)
    rec.record(solver)
    solver.run(steps, callback=rec)
    return solver, cloth, rec


def box_centre(recording, frame, c=1):
    """Where the box collider's centre is at ``frame``, from its recorded pose."""
    R, t = recording.collider_pose(frame, c)
    return R @ np.asarray(recording.colliders[c].center) + t

