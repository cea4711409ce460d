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
MeshLike = Any  # a (V, F) pair, or a body: ``positions`` and, for a membrane, ``triangles``

_MESH_COLORS = ("#4c8bd6", "#d6784c", "#5fb35f", "#b35fb3", "#c9b23c")
_COLLIDER_COLOR = "#8a8a8a"


def _draw_collider(ax: Any, c: Any, center: np.ndarray, half: float, pose: Any = None) -> Any:
    """Draws one collider (Sphere, Capsule, Box, MeshCollider or Plane) translucently, at
    ``pose`` (``(rotation, translation)``) if given; returns the artist."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from . import _core
    from .shapes import at_pose, collider_mesh

    V, F = collider_mesh(c, center, half)
    V = at_pose(V, pose)
    alpha = 0.2 if isinstance(c, _core.Plane) else 0.35
    edge = 0.0 if isinstance(c, (_core.Plane, _core.Sphere, _core.Capsule)) else 0.3
    return ax.add_collection3d(Poly3DCollection(V[F], facecolor=_COLLIDER_COLOR, alpha=alpha,
                                                edgecolor="#555555", linewidth=edge))


def _as_mesh_list(meshes: Union[MeshLike, Sequence[MeshLike]],
                  particles: str = "points") -> List[Tuple[np.ndarray, Optional[np.ndarray]]]:
    """``(V, F)`` per body; ``F`` is None for a body without triangles (particles, as points),
    or with ``particles="surface"`` a particle body's surface mesh."""
    from .recording import body_triangles

    if particles not in ("points", "surface"):
        raise ValueError(f"render: particles must be 'points' or 'surface', got {particles!r}")

    def one(m: MeshLike) -> Tuple[np.ndarray, Optional[np.ndarray]]:
        if hasattr(m, "positions") and particles == "surface" and body_triangles(m) is None:
            from .surface import particle_surface

            V, F = particle_surface(m)
            if len(F) == 0:  # too sparse for a surface: its points
                V, F = m.positions, None
        elif hasattr(m, "positions"):
            V, F = m.positions, body_triangles(m)
        else:
            V, F = m
        V = np.asarray(V, dtype=np.float64)
        if V.ndim != 2 or V.shape[1] != 3:
            raise ValueError(f"render: a body needs positions V (N, 3), got {V.shape}")
        if F is None:
            return V, None
        F = np.asarray(F, dtype=np.int64)
        if F.ndim != 2 or F.shape[1] != 3:
            raise ValueError(f"render: a mesh needs F (M, 3), got {F.shape}")
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


def _view_box(meshes: List[Tuple[np.ndarray, Any]], colliders: Sequence[Any]) -> Tuple[np.ndarray, float]:
    """Centre (m) and half side (m, 0.5 for an empty or flat-to-a-point scene) of the cube a
    view shows: it holds every mesh vertex and every solid collider."""
    lo, hi = _bounds(meshes, colliders)
    half = 0.5 * float(np.max(hi - lo))
    return 0.5 * (lo + hi), half if half > 0.0 else 0.5


def _run_view_box(rec: Any) -> Tuple[np.ndarray, float]:
    """:func:`_view_box` of a whole recorded run: every body at every frame."""
    return _view_box([(t.positions.reshape(-1, 3), None) for t in rec.bodies], rec.colliders)


def draw_scene(
    ax: Any,
    meshes: Union[MeshLike, Sequence[MeshLike]],
    *,
    colliders: Sequence[Any] = (),
    title: Optional[str] = None,
    elev: float = 25.0,
    azim: float = -60.0,
    particles: str = "points",
) -> Any:
    """Draw membranes and colliders on a matplotlib 3-D axes, with equal axis scaling.

    Parameters
    ----------
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
        The axes to draw on.
    meshes : (V, F) pair, Membrane, or a sequence of them
        Triangle meshes, positions in m, drawn as shaded surfaces; a body with ``positions``
        but no ``triangles`` (a particle set) is drawn as points.
    colliders : sequence of Sphere, Capsule, Box, MeshCollider or Plane
        Solids are drawn (a MeshCollider as its triangles) as translucent surfaces; planes as a translucent square patch
        spanning the drawn meshes.
    title : str, optional
        Axes title.
    elev, azim : float
        Camera elevation and azimuth in degrees.
    particles : {"points", "surface"}
        How particle bodies are drawn: as points, or as their surface
        (:func:`peridyn.particle_surface`, for fluids).

    Returns
    -------
    ax
        The same axes.
    """
    mesh_list = _as_mesh_list(meshes, particles)
    colliders = list(colliders)
    center, half = _view_box(mesh_list, colliders)

    for c in colliders:
        _draw_collider(ax, c, center, half)

    for k, (V, F) in enumerate(mesh_list):
        _draw_body(ax, V, F, _MESH_COLORS[k % len(_MESH_COLORS)])
    _set_view(ax, center, half, title, elev, azim)
    return ax


def _draw_body(ax: Any, V: np.ndarray, F: Optional[np.ndarray], color: Any,
               values: Optional[np.ndarray] = None, cmap: Any = None, norm: Any = None) -> Any:
    """Draws one body: a shaded surface, or points for a body without triangles; coloured by
    per-vertex ``values`` through ``cmap`` and ``norm`` when given. Returns the artist."""
    if F is None:
        c = color if values is None else cmap(norm(values))
        return ax.scatter(V[:, 0], V[:, 1], V[:, 2], s=4.0, c=c, depthshade=True)
    if len(F) == 0:
        return None
    if values is None:
        return ax.plot_trisurf(V[:, 0], V[:, 1], V[:, 2], triangles=F, color=color,
                               linewidth=0.0, antialiased=False, shade=True)
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    face = cmap(norm(values[F].mean(axis=1)))
    return ax.add_collection3d(Poly3DCollection(V[F], facecolors=face, linewidth=0.0, antialiased=False))


def _set_view(ax: Any, center: np.ndarray, half: float, title: Optional[str], elev: float, azim: float) -> None:
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
    particles: str = "points",
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
    particles : {"points", "surface"}
        See :func:`draw_scene`.

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
    draw_scene(ax, meshes, colliders=colliders, title=title, elev=elev, azim=azim,
               particles=particles)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(str(path), format="png")
    return path
