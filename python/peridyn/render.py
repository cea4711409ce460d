"""Quick-look pictures of membranes and colliders with matplotlib (no display needed).

:func:`render_png` draws off-screen with the Agg canvas and never touches pyplot's global
backend, so it is safe in scripts, tests and notebooks alike; :func:`draw_scene` draws on a 3-D
axes you own (for example from ``plt.subplots(subplot_kw={"projection": "3d"})``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, List, Optional, Sequence, Tuple, Union

import numpy as np

__all__ = ["render_png", "draw_scene"]

PathLike = Union[str, "os.PathLike[str]"]
MeshLike = Any  # a (V, F) pair, or an object with ``positions`` and ``triangles`` (a Membrane)

_MESH_COLORS = ("#4c8bd6", "#d6784c", "#5fb35f", "#b35fb3", "#c9b23c")
_COLLIDER_COLOR = "#8a8a8a"


def _sphere_surface(ax: Any, c: np.ndarray, r: float) -> None:
    u, v = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 40), np.linspace(0.0, np.pi, 20))
    ax.plot_surface(
        c[0] + r * np.cos(u) * np.sin(v), c[1] + r * np.sin(u) * np.sin(v), c[2] + r * np.cos(v),
        color=_COLLIDER_COLOR, alpha=0.35, linewidth=0.2, edgecolor="#555555", shade=True,
    )


def _frame(axis: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to the unit ``axis`` and to each other."""
    t1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(axis, t1)


def _draw_collider(ax: Any, c: Any, center: np.ndarray, half: float) -> None:
    """Draws one collider (Sphere, Capsule, Box, MeshCollider or Plane) translucently."""
    from . import _core

    if isinstance(c, _core.Sphere):
        _sphere_surface(ax, np.asarray(c.center, dtype=np.float64), float(c.radius))
    elif isinstance(c, _core.Capsule):
        a, b, r = np.asarray(c.a, dtype=np.float64), np.asarray(c.b, dtype=np.float64), float(c.radius)
        _sphere_surface(ax, a, r)
        _sphere_surface(ax, b, r)
        length = np.linalg.norm(b - a)
        if length > 0.0:
            t1, t2 = _frame((b - a) / length)
            u, s = np.meshgrid(np.linspace(0.0, 2.0 * np.pi, 40), [0.0, 1.0])
            P = a[:, None, None] + (b - a)[:, None, None] * s + r * (
                t1[:, None, None] * np.cos(u) + t2[:, None, None] * np.sin(u))
            ax.plot_surface(P[0], P[1], P[2], color=_COLLIDER_COLOR, alpha=0.35, linewidth=0, shade=True)
    elif isinstance(c, _core.Box):
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        R = np.asarray(c.rotation, dtype=np.float64)
        h = np.asarray(c.half_extents, dtype=np.float64)
        o = np.asarray(c.center, dtype=np.float64)
        corner = lambda sx, sy, sz: o + R @ (h * np.array([sx, sy, sz]))  # noqa: E731
        faces = []
        for axis in range(3):
            for sign in (-1.0, 1.0):
                quad = []
                for s1, s2 in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                    signs = [0.0, 0.0, 0.0]
                    signs[axis] = sign
                    signs[(axis + 1) % 3] = s1
                    signs[(axis + 2) % 3] = s2
                    quad.append(corner(*signs))
                faces.append(quad)
        ax.add_collection3d(Poly3DCollection(faces, facecolor=_COLLIDER_COLOR, alpha=0.35,
                                             edgecolor="#555555", linewidth=0.3))
    elif isinstance(c, _core.MeshCollider):
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        V = np.asarray(c.vertices, dtype=np.float64)
        F = np.asarray(c.triangles, dtype=np.int64)
        ax.add_collection3d(Poly3DCollection(V[F], facecolor=_COLLIDER_COLOR, alpha=0.35,
                                             edgecolor="#555555", linewidth=0.2))
    elif isinstance(c, _core.Plane):
        n = np.asarray(c.normal, dtype=np.float64)
        n = n / np.linalg.norm(n)
        p = np.asarray(c.point, dtype=np.float64)
        t1, t2 = _frame(n)
        origin = center - np.dot(center - p, n) * n  # the scene centre projected on the plane
        s, t = np.meshgrid([-1.2 * half, 1.2 * half], [-1.2 * half, 1.2 * half])
        X = origin[0] + s * t1[0] + t * t2[0]
        Y = origin[1] + s * t1[1] + t * t2[1]
        Z = origin[2] + s * t1[2] + t * t2[2]
        ax.plot_surface(X, Y, Z, color=_COLLIDER_COLOR, alpha=0.2, linewidth=0, shade=False)


def _as_mesh_list(meshes: Union[MeshLike, Sequence[MeshLike]]) -> List[Tuple[np.ndarray, np.ndarray]]:
    def one(m: MeshLike) -> Tuple[np.ndarray, np.ndarray]:
        if hasattr(m, "positions") and hasattr(m, "triangles"):
            V, F = m.positions, m.triangles
        else:
            V, F = m
        V = np.asarray(V, dtype=np.float64)
        F = np.asarray(F, dtype=np.int64)
        if V.ndim != 2 or V.shape[1] != 3 or F.ndim != 2 or F.shape[1] != 3:
            raise ValueError(f"render: a mesh needs V (N, 3) and F (M, 3), got {V.shape} and {F.shape}")
        return V, F

    if hasattr(meshes, "positions"):
        return [one(meshes)]
    if isinstance(meshes, tuple) and len(meshes) == 2 and np.ndim(meshes[0]) == 2:
        return [one(meshes)]  # a single (V, F) pair
    return [one(m) for m in meshes]


def _collider_extent(c: Any) -> List[Tuple[np.ndarray, np.ndarray]]:
    """Points and reaches whose boxes cover a solid collider (none for a plane)."""
    from . import _core

    if isinstance(c, _core.Sphere):
        return [(np.asarray(c.center, dtype=np.float64), np.full(3, c.radius))]
    if isinstance(c, _core.Capsule):
        return [(np.asarray(p, dtype=np.float64), np.full(3, c.radius)) for p in (c.a, c.b)]
    if isinstance(c, _core.Box):
        reach = np.abs(np.asarray(c.rotation, dtype=np.float64)) @ np.asarray(c.half_extents, dtype=np.float64)
        return [(np.asarray(c.center, dtype=np.float64), reach)]
    if isinstance(c, _core.MeshCollider):
        V = np.asarray(c.vertices, dtype=np.float64)
        lo, hi = V.min(axis=0), V.max(axis=0)
        return [(0.5 * (lo + hi), 0.5 * (hi - lo))]
    return []


def _bounds(meshes: List[Tuple[np.ndarray, np.ndarray]], colliders: Sequence[Any]) -> Tuple[np.ndarray, np.ndarray]:
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for V, _ in meshes:
        if len(V):
            lo = np.minimum(lo, V.min(axis=0))
            hi = np.maximum(hi, V.max(axis=0))
    for c in colliders:
        for point, reach in _collider_extent(c):
            lo = np.minimum(lo, point - reach)
            hi = np.maximum(hi, point + reach)
    if not np.all(np.isfinite(lo)):
        lo, hi = -np.ones(3), np.ones(3)
    return lo, hi


def draw_scene(
    ax: Any,
    meshes: Union[MeshLike, Sequence[MeshLike]],
    *,
    colliders: Sequence[Any] = (),
    title: Optional[str] = None,
    elev: float = 25.0,
    azim: float = -60.0,
) -> Any:
    """Draw membranes and colliders on a matplotlib 3-D axes, with equal axis scaling.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        The axes to draw on.
    meshes : (V, F) pair, Membrane, or a sequence of them
        Triangle meshes, positions in m, drawn as shaded surfaces.
    colliders : sequence of Sphere, Capsule, Box, MeshCollider or Plane
        Solids are drawn (a MeshCollider as its triangles) as translucent surfaces; planes as a translucent square patch
        spanning the drawn meshes.
    title : str, optional
        Axes title.
    elev, azim : float
        Camera elevation and azimuth in degrees.

    Returns
    -------
    ax
        The same axes.
    """
    mesh_list = _as_mesh_list(meshes)
    colliders = list(colliders)
    lo, hi = _bounds(mesh_list, colliders)
    center = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo))
    if not half > 0.0:
        half = 0.5

    for c in colliders:
        _draw_collider(ax, c, center, half)

    for k, (V, F) in enumerate(mesh_list):
        if len(F) == 0:
            continue
        ax.plot_trisurf(
            V[:, 0], V[:, 1], V[:, 2], triangles=F,
            color=_MESH_COLORS[k % len(_MESH_COLORS)], linewidth=0.0, antialiased=False, shade=True,
        )

    ax.set_xlim(center[0] - half, center[0] + half)
    ax.set_ylim(center[1] - half, center[1] + half)
    ax.set_zlim(center[2] - half, center[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.view_init(elev=elev, azim=azim)
    if title:
        ax.set_title(title)
    return ax


def render_png(
    path: PathLike,
    meshes: Union[MeshLike, Sequence[MeshLike]],
    *,
    colliders: Sequence[Any] = (),
    title: Optional[str] = None,
    elev: float = 25.0,
    azim: float = -60.0,
    size: Tuple[float, float] = (7.0, 6.0),
    dpi: int = 120,
) -> Path:
    """Render membranes and colliders to a PNG file, off-screen.

    Parameters
    ----------
    path : str or path-like
        Output PNG file.
    meshes : (V, F) pair, Membrane, or a sequence of them
        Triangle meshes, positions in m.
    colliders : sequence of Sphere, Capsule, Box, MeshCollider or Plane
        See :func:`draw_scene`.
    title : str, optional
        Figure title.
    elev, azim : float
        Camera elevation and azimuth in degrees.
    size : (float, float)
        Figure size in inches.
    dpi : int
        Resolution in dots per inch.

    Returns
    -------
    pathlib.Path
        The file written.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=size, dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    draw_scene(ax, meshes, colliders=colliders, title=title, elev=elev, azim=azim)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(str(path), format="png")
    return path
