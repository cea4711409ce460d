"""Geometric checks of contact results, shared by the contact tests: exact triangle-triangle
intersection (ipctk), the smallest distance between non-adjacent primitives, and all bodies'
meshes in one numbering. Importing this module skips the importing test module when ipctk is
missing.
"""

import numpy as np
import pytest

from peridyn._core import contact

ipctk = pytest.importorskip("ipctk")


def mesh_of(bodies):
    """All bodies' positions and triangles in one numbering, and each triangle's body."""
    points, triangles, owner, base = [], [], [], 0
    for b, body in enumerate(bodies):
        points.append(body.positions)
        triangles.append(body.triangles + base)
        owner.append(np.full(len(body.triangles), b))
        base += body.num_vertices
    return np.concatenate(points), np.concatenate(triangles), np.concatenate(owner)


def close_pairs(x, tris, pad):
    """Non-adjacent triangle pairs (no shared vertex) whose boxes, padded by `pad`, overlap."""
    corners = x[tris]
    lo, hi = corners.min(axis=1) - pad, corners.max(axis=1) + pad
    i, j = np.triu_indices(len(tris), k=1)
    overlap = np.all((lo[i] <= hi[j]) & (lo[j] <= hi[i]), axis=1)
    i, j = i[overlap], j[overlap]
    shared = (tris[i][:, :, None] == tris[j][:, None, :]).any(axis=(1, 2))
    return i[~shared], j[~shared]


def plane_separated(x, tris, a, b):
    """Pairs (a, b) where all of one triangle's vertices lie strictly on one side of the
    other's plane: they cannot intersect."""
    def one_side(p, q):
        tp, tq = x[tris[p]], x[tris[q]]
        n = np.cross(tp[:, 1] - tp[:, 0], tp[:, 2] - tp[:, 0])
        side = np.einsum("nj,nkj->nk", n, tq - tp[:, :1])
        return np.all(side > 0, axis=1) | np.all(side < 0, axis=1)
    return one_side(a, b) | one_side(b, a)


def intersecting_pairs(x, tris):
    """Exact triangle-triangle intersection: an edge of one crosses the other (ipctk), on the
    non-adjacent pairs whose boxes overlap and that no triangle's plane separates."""
    a, b = close_pairs(x, tris, 0.0)
    keep = ~plane_separated(x, tris, a, b)
    bad = []
    for i, j in zip(a[keep], b[keep]):
        for p, q in ((i, j), (j, i)):
            tp, tq = x[tris[p]], x[tris[q]]
            if any(ipctk.is_edge_intersecting_triangle(tp[k], tp[(k + 1) % 3], *tq)
                   for k in range(3)):
                bad.append((i, j))
                break
    return bad


def min_separation(x, tris, pad):
    """Smallest point-triangle / edge-edge distance between non-adjacent triangles closer than
    `pad` (batched kernels, checked against ipctk in test_contact_kernels.py); `pad` if none."""
    a, b = close_pairs(x, tris, pad)
    if len(a) == 0:
        return pad
    ta, tb = x[tris[a]], x[tris[b]]
    best = pad**2
    for p, q in ((ta, tb), (tb, ta)):
        for k in range(3):
            d2, _ = contact.point_triangle_distance(p[:, k], q[:, 0], q[:, 1], q[:, 2])
            best = min(best, d2.min())
    for k in range(3):
        for m in range(3):
            d2, _ = contact.edge_edge_distance(ta[:, k], ta[:, (k + 1) % 3],
                                               tb[:, m], tb[:, (m + 1) % 3])
            best = min(best, d2.min())
    return np.sqrt(best)


def assert_apart(bodies, colliders, thickness, eps):
    """The promises of the contact local step at one instant: no two non-adjacent triangles
    of `bodies` intersect, non-adjacent primitives are at least `eps * thickness` apart, and
    no vertex is inside a collider."""
    x, tris, _ = mesh_of(bodies)
    assert not intersecting_pairs(x, tris), "triangles intersect"
    gap = min_separation(x, tris, 2 * thickness)
    assert gap >= eps * thickness, f"primitives {gap:.3g} m apart, < eps xi"
    for collider in colliders:
        depth = collider.signed_distance(x).min()
        assert depth > -1e-6, f"a vertex is {-depth:.3g} m inside {collider!r}"
