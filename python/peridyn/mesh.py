"""Triangle meshes for membranes: a structured grid builder and a loader for mesh files.

Every function returns ``(V, F)``: ``V`` is a ``float64`` array of shape (N, 3) with vertex
positions in metres, ``F`` an ``int64`` array of shape (M, 3) with vertex indices per triangle.
"""

from __future__ import annotations

import os
from typing import Literal, Tuple, Union

import numpy as np

from ._validate import real

__all__ = ["grid", "load_mesh"]

PathLike = Union[str, "os.PathLike[str]"]


def grid(
    nx: int,
    ny: int,
    size: Tuple[float, float] = (1.0, 1.0),
    *,
    diagonal: Literal["uniform", "alternate"] = "uniform",
) -> Tuple[np.ndarray, np.ndarray]:
    """A flat rectangular sheet of ``nx`` x ``ny`` vertices in the ``z = 0`` plane.

    Parameters
    ----------
    nx, ny : int
        Number of vertices along x and along y (each >= 2).
    size : (float, float)
        Side lengths ``(a, b)`` in m (each > 0): x spans ``[0, a]``, y spans ``[0, b]``.
    diagonal : {"uniform", "alternate"}
        How each cell is split into two triangles. ``"uniform"`` always splits along the
        diagonal from vertex ``(i, j)`` to ``(i + 1, j + 1)``, giving the triangles
        ``(v, v + 1, v + nx + 1)`` and ``(v, v + nx + 1, v + nx)`` with ``v = j * nx + i``;
        ``"alternate"`` flips the diagonal in a checkerboard pattern (less directional bias
        when the sheet bends).

    Returns
    -------
    V : (nx * ny, 3) float64
        Vertex positions in m. Vertex ``(i, j)`` (``i`` along x, ``j`` along y) has index
        ``j * nx + i`` and position ``(i * a / (nx - 1), j * b / (ny - 1), 0)``.
    F : (2 * (nx - 1) * (ny - 1), 3) int64
        Triangles, counter-clockwise seen from +z (every normal is +z); two per cell, cells
        in the order of their lower-left vertex index.

    Raises
    ------
    ValueError
        If ``nx`` or ``ny`` is < 2, a side length is not a positive finite number, or
        ``diagonal`` is unknown.
    """
    for name, value in (("nx", nx), ("ny", ny)):
        if isinstance(value, bool) or int(value) != value or value < 2:
            raise ValueError(f"grid: {name} must be an integer >= 2, got {value!r}")
    nx, ny = int(nx), int(ny)
    if len(size) != 2:
        raise ValueError(f"grid: size must be a pair (a, b) in m, got {size!r}")
    a, b = real("grid", "size[0]", size[0]), real("grid", "size[1]", size[1])
    for name, value in (("size[0]", a), ("size[1]", b)):
        if not np.isfinite(value) or value <= 0.0:
            raise ValueError(f"grid: {name} must be a positive length in m, got {value!r}")
    if diagonal not in ("alternate", "uniform"):
        raise ValueError(f"grid: diagonal must be 'alternate' or 'uniform', got {diagonal!r}")

    x = np.linspace(0.0, a, nx)
    y = np.linspace(0.0, b, ny)
    xx, yy = np.meshgrid(x, y, indexing="xy")  # shape (ny, nx): row j, column i
    V = np.column_stack([xx.ravel(), yy.ravel(), np.zeros(nx * ny)])

    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), indexing="xy")
    i, j = i.ravel(), j.ravel()
    v00 = j * nx + i
    v10 = v00 + 1
    v01 = v00 + nx
    v11 = v01 + 1
    # Split along v00-v11:  (v00, v10, v11), (v00, v11, v01)
    # Split along v10-v01:  (v00, v10, v01), (v10, v11, v01)
    # Both pairs are counter-clockwise seen from +z.
    if diagonal == "uniform":
        flip = np.zeros(i.shape, dtype=bool)
    else:
        flip = (i + j) % 2 == 1
    t1 = np.where(flip[:, None], np.column_stack([v00, v10, v01]), np.column_stack([v00, v10, v11]))
    t2 = np.where(flip[:, None], np.column_stack([v10, v11, v01]), np.column_stack([v00, v11, v01]))
    F = np.empty((2 * i.size, 3), dtype=np.int64)
    F[0::2] = t1
    F[1::2] = t2
    return V, F


def load_mesh(path: PathLike, *, merge_vertices: bool = True) -> Tuple[np.ndarray, np.ndarray]:
    """Read a triangle mesh from any file format trimesh reads (OBJ, PLY, STL, OFF, GLB, ...).

    Parameters
    ----------
    path : str or path-like
        The mesh file. Coordinates are taken as metres, as stored.
    merge_vertices : bool
        Weld vertices at identical positions (also across UV or normal seams, which OBJ and
        glTF files split), so the membrane is one connected sheet. With ``False`` the file's
        vertices and their order are kept exactly.

    Returns
    -------
    V : (N, 3) float64
        Vertex positions in m.
    F : (M, 3) int64
        Triangles (quads and polygons are triangulated by trimesh). A multi-object file
        (a scene) is concatenated into one mesh, with the scene's transforms applied.

    Raises
    ------
    FileNotFoundError
        If ``path`` does not exist.
    ValueError
        If the file cannot be read as a mesh (unknown format, truncated or corrupt), holds no
        triangles (for example a point cloud or a line drawing), a vertex that is not finite
        (NaN, inf, or a number too large for a float64) or a triangle whose vertex indices are
        out of range. The message names the file.
    """
    import trimesh

    path = os.fspath(path)
    if not os.path.exists(path):
        raise FileNotFoundError(f"load_mesh: no such file: {path!r}")
    if os.path.isdir(path):
        raise ValueError(f"load_mesh: {path!r} is a directory, not a mesh file")
    try:
        loaded = trimesh.load(path, process=False, maintain_order=True)
        if isinstance(loaded, trimesh.Scene):
            meshes = [g for g in loaded.geometry.values() if isinstance(g, trimesh.Trimesh)]
            if not meshes or all(len(g.faces) == 0 for g in meshes):
                raise _MeshError(f"load_mesh: {path!r} holds no triangles")
            if hasattr(loaded, "to_mesh"):
                loaded = loaded.to_mesh()
            else:  # trimesh < 4.6
                loaded = loaded.dump(concatenate=True)
        if not isinstance(loaded, trimesh.Trimesh) or len(loaded.faces) == 0:
            raise _MeshError(
                f"load_mesh: {path!r} holds no triangles (trimesh read a {type(loaded).__name__})"
            )
        V = np.asarray(loaded.vertices)
        F = np.asarray(loaded.faces)
        _check_mesh(path, V, F)
        if merge_vertices:
            loaded.merge_vertices(merge_tex=True, merge_norm=True)
            loaded.remove_unreferenced_vertices()
        V = np.ascontiguousarray(loaded.vertices, dtype=np.float64)
        F = np.ascontiguousarray(loaded.faces, dtype=np.int64)
    except _MeshError:
        raise
    except Exception as e:  # trimesh's loaders raise whatever a bad file leads them to
        raise _MeshError(
            f"load_mesh: {path!r} is not a readable mesh file ({type(e).__name__}: {e})"
        ) from e
    _check_mesh(path, V, F)
    return V, F


class _MeshError(ValueError):
    """A file that :func:`load_mesh` refuses (a ``ValueError`` naming the file)."""


def _check_mesh(path: str, V: np.ndarray, F: np.ndarray) -> None:
    """A ``ValueError`` naming ``path`` unless ``V`` is (N, 3) finite real and ``F`` (M, 3)
    integer indices in [0, N)."""
    if V.dtype.kind not in "fiu" or V.ndim != 2 or V.shape[1] != 3:
        raise _MeshError(f"load_mesh: {path!r} gave vertices of shape {V.shape} and dtype {V.dtype}")
    if F.dtype.kind not in "iu" or F.ndim != 2 or F.shape[1] != 3:
        raise _MeshError(f"load_mesh: {path!r} gave triangles of shape {F.shape} and dtype {F.dtype}")
    finite = np.isfinite(V).all(axis=1)
    if not finite.all():
        i = int(np.flatnonzero(~finite)[0])
        raise _MeshError(
            f"load_mesh: {path!r}: vertex {i} is not finite: {V[i].tolist()} (NaN, inf, or a "
            "coordinate too large for a float64)"
        )
    out = (F < 0) | (F >= len(V))
    if out.any():
        t = int(np.flatnonzero(out.any(axis=1))[0])
        raise _MeshError(
            f"load_mesh: {path!r}: triangle {t} holds {F[t].tolist()}, vertex indices must be "
            f"in [0, {len(V)})"
        )
