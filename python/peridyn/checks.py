"""Geometric checks of contact results, at any mesh size: whether non-adjacent triangles
intersect (exactly, with ``ipctk``), the smallest distance between their primitives, and how
deep vertices are inside colliders.

Candidate triangle pairs come from the solver's own broad phase
(:func:`peridyn._core.contact.near_triangle_pairs`), so a check costs about one broad phase
plus the exact tests, not a test of every pair. "Non-adjacent" means sharing no vertex, the
pairs the contact local step keeps apart (Lu et al. 2023, section 6).

The exact intersection test needs the optional ``ipctk`` package (``pip install
peridyn[test]``); the distances do not.
"""

from __future__ import annotations

from typing import Iterable, List, Sequence, Tuple

import numpy as np

from ._core import contact

__all__ = [
    "deepest_inside",
    "intersecting_pairs",
    "mesh_of",
    "min_separation",
    "plane_separated",
]

#: Box padding (m) of the intersection candidates: boxes that merely touch are candidates too.
_TOUCH = 1e-12


def mesh_of(bodies: Iterable) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All bodies' positions (n, 3) and triangles (m, 3) in one numbering, and each triangle's
    body index (m,)."""
    points, triangles, owner, base = [], [], [], 0
    for b, body in enumerate(bodies):
        points.append(body.positions)
        triangles.append(body.triangles + base)
        owner.append(np.full(len(body.triangles), b))
        base += body.num_vertices
    return np.concatenate(points), np.concatenate(triangles), np.concatenate(owner)


def plane_separated(x: np.ndarray, tris: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per pair ``(a[k], b[k])`` of triangle indices: whether all of one triangle's vertices lie
    strictly on one side of the other's plane, so that they cannot intersect."""

    def one_side(p, q):
        tp, tq = x[tris[p]], x[tris[q]]
        n = np.cross(tp[:, 1] - tp[:, 0], tp[:, 2] - tp[:, 0])
        side = np.einsum("nj,nkj->nk", n, tq - tp[:, :1])
        return np.all(side > 0, axis=1) | np.all(side < 0, axis=1)

    return one_side(a, b) | one_side(b, a)


def intersecting_pairs(x: np.ndarray, tris: np.ndarray) -> List[Tuple[int, int]]:
    """The non-adjacent triangle pairs that intersect: an edge of one crosses the other
    (``ipctk.is_edge_intersecting_triangle``), tested on the pairs whose boxes touch and that
    no triangle's plane separates.

    Raises ImportError when ``ipctk`` is missing.
    """
    try:
        import ipctk
    except ImportError as e:  # pragma: no cover - depends on the environment
        raise ImportError(
            "peridyn.checks.intersecting_pairs needs ipctk (pip install 'peridyn[test]')"
        ) from e
    x = np.asarray(x, dtype=np.float64)
    pairs, _ = contact.near_triangle_pairs(x, tris, _TOUCH)
    a, b = pairs[:, 0], pairs[:, 1]
    keep = ~plane_separated(x, tris, a, b)
    bad = []
    for i, j in zip(a[keep], b[keep]):
        for p, q in ((i, j), (j, i)):
            tp, tq = x[tris[p]], x[tris[q]]
            if any(ipctk.is_edge_intersecting_triangle(tp[k], tp[(k + 1) % 3], *tq)
                   for k in range(3)):
                bad.append((int(i), int(j)))
                break
    return bad


def min_separation(x: np.ndarray, tris: np.ndarray, pad: float) -> float:
    """Smallest point-triangle / edge-edge distance (m) between non-adjacent triangles, looked
    for among the pairs closer than ``pad`` (m); ``pad`` if there are none."""
    _, d = contact.near_triangle_pairs(np.asarray(x, dtype=np.float64), tris, pad)
    return float(min(pad, d.min())) if len(d) else float(pad)


def deepest_inside(solver, colliders: Sequence, x: np.ndarray) -> float:
    """How far (m) the deepest of the points ``x`` (n, 3) is inside any of ``colliders`` (in
    the order they were added to ``solver``, each at its current pose there): the largest
    ``-signed_distance``; negative when every point is outside, ``-inf`` without colliders."""
    deepest = -np.inf
    for k, collider in enumerate(colliders):
        rotation, translation = solver.collider_pose(k)
        local = (np.asarray(x, dtype=np.float64) - translation) @ rotation
        deepest = max(deepest, float(-collider.signed_distance(local).min()))
    return deepest
