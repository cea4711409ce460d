"""Colliders as triangle meshes, for drawing them (pictures, animations, notebook views, USD).

One tessellation per collider kind, shared by :mod:`peridyn.render`, :mod:`peridyn.view` and
:mod:`peridyn.usd`, so every view draws a collider the same way. Positions in m.
"""

from __future__ import annotations

from typing import Any, Optional, Tuple

import numpy as np

__all__ = ["collider_mesh", "at_pose"]

Pose = Tuple[np.ndarray, np.ndarray]


def _frame(axis: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to the unit ``axis`` and to each other."""
    t1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(axis, t1)


def _grid_triangles(rows: int, cols: int, wrap: bool) -> np.ndarray:
    """Triangles of a (rows, cols) vertex grid, row-major; ``wrap`` joins the last column to
    the first (a closed ring around an axis)."""
    c_end = cols if wrap else cols - 1
    tris = []
    for r in range(rows - 1):
        for c in range(c_end):
            a, b = r * cols + c, r * cols + (c + 1) % cols
            tris.append((a, b, b + cols))
            tris.append((a, b + cols, a + cols))
    return np.asarray(tris, dtype=np.int64)


def _sphere(center: np.ndarray, radius: float, n_u: int = 32, n_v: int = 16) -> Tuple[np.ndarray, np.ndarray]:
    """A UV sphere (poles repeated per column, which a viewer does not see)."""
    u = np.linspace(0.0, 2.0 * np.pi, n_u, endpoint=False)
    v = np.linspace(0.0, np.pi, n_v)
    U, W = np.meshgrid(u, v)  # rows: latitude, columns: longitude
    P = np.stack([np.cos(U) * np.sin(W), np.sin(U) * np.sin(W), np.cos(W)], axis=-1).reshape(-1, 3)
    return center + radius * P, _grid_triangles(n_v, n_u, wrap=True)


def _capsule(a: np.ndarray, b: np.ndarray, radius: float, n_u: int = 32, n_v: int = 8) -> Tuple[np.ndarray, np.ndarray]:
    """A capsule: a hemisphere at each end joined by the cylinder between them."""
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length == 0.0:
        return _sphere(a, radius, n_u, 2 * n_v)
    axis = axis / length
    t1, t2 = _frame(axis)
    u = np.linspace(0.0, 2.0 * np.pi, n_u, endpoint=False)
    rings = []
    # polar angle from the -axis pole at a to the +axis pole at b; the equator row repeats
    for end, thetas in ((a, np.linspace(np.pi, 0.5 * np.pi, n_v)), (b, np.linspace(0.5 * np.pi, 0.0, n_v))):
        for th in thetas:
            ring = end + radius * (np.cos(th) * axis + np.sin(th) * (np.outer(np.cos(u), t1) + np.outer(np.sin(u), t2)))
            rings.append(ring)
    V = np.concatenate(rings)
    return V, _grid_triangles(len(rings), n_u, wrap=True)


def _box(center: np.ndarray, half: np.ndarray, rotation: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=np.float64)
    V = center + (signs * half) @ rotation.T
    # corner index = 4*ix + 2*iy + iz; two triangles per face, outward
    F = np.array([
        (0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5),  # x = -, x = +
        (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),  # y = -, y = +
        (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3),  # z = -, z = +
    ], dtype=np.int64)
    return V, F


def collider_mesh(collider: Any, center: Optional[np.ndarray] = None, half: float = 1.0) -> Tuple[np.ndarray, np.ndarray]:
    """Triangles ``(V (n, 3) in m, F (m, 3))`` of a collider in the pose it was built with.

    A plane, which has no extent, becomes a square of side ``2.4 * half`` (m) centred on
    ``center`` (m, default the origin) projected onto it. Raises ``ValueError`` for an object
    that is no peridyn collider.
    """
    from . import _core

    if isinstance(collider, _core.Sphere):
        return _sphere(np.asarray(collider.center, dtype=np.float64), float(collider.radius))
    if isinstance(collider, _core.Capsule):
        return _capsule(np.asarray(collider.a, dtype=np.float64), np.asarray(collider.b, dtype=np.float64),
                        float(collider.radius))
    if isinstance(collider, _core.Box):
        return _box(np.asarray(collider.center, dtype=np.float64),
                    np.asarray(collider.half_extents, dtype=np.float64),
                    np.asarray(collider.rotation, dtype=np.float64))
    if isinstance(collider, _core.MeshCollider):
        return (np.asarray(collider.vertices, dtype=np.float64),
                np.asarray(collider.triangles, dtype=np.int64))
    if isinstance(collider, _core.Plane):
        n = np.asarray(collider.normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        p = np.asarray(collider.point, dtype=np.float64)
        c = np.zeros(3) if center is None else np.asarray(center, dtype=np.float64)
        t1, t2 = _frame(n)
        origin = c - np.dot(c - p, n) * n
        s = 1.2 * half
        V = np.array([origin + s * (i * t1 + j * t2) for i, j in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
        return V, np.array([(0, 1, 2), (0, 2, 3)], dtype=np.int64)
    raise ValueError(f"collider_mesh: {type(collider).__name__} is not a peridyn collider")


def at_pose(V: np.ndarray, pose: Optional[Pose]) -> np.ndarray:
    """Points ``V`` (n, 3) of a collider's geometry as given, moved to ``pose = (rotation,
    translation)`` (``Solver.collider_pose``: a point ``b`` is at ``rotation @ b +
    translation``); ``V`` unchanged for ``None``."""
    if pose is None:
        return V
    R, t = pose
    return V @ np.asarray(R, dtype=np.float64).T + np.asarray(t, dtype=np.float64)
