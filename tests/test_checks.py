"""peridyn.checks at small sizes against brute force: the broad phase behind it finds every
non-adjacent triangle pair closer than the reach, the distances are the primitive distances,
crossing triangles are found and separated ones are not, bad input names the bad value."""

import numpy as np
import pytest

from peridyn import checks
from peridyn._core import contact


def crumpled_sheet(n=10, seed=1):
    """A unit grid rolled into a spiral (layers about 0.03 apart) and jittered."""
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="xy")
    theta = 3 * np.pi * i.ravel() / (n - 1)
    r = 0.1 + 0.03 * theta / (2 * np.pi)
    x = np.column_stack([r * np.cos(theta), 0.05 * j.ravel(), r * np.sin(theta)])
    x += rng.uniform(-0.004, 0.004, x.shape)
    v = (j[:-1, :-1] * n + i[:-1, :-1]).ravel()
    tris = np.concatenate([np.column_stack([v, v + 1, v + n + 1]),
                           np.column_stack([v, v + n + 1, v + n])])
    return x, tris


def primitive_distance(x, tris, a, b):
    """Smallest of the 15 point-triangle / edge-edge distances of each pair, by the batched
    kernels."""
    ta, tb = x[tris[a]], x[tris[b]]
    best = np.full(len(a), np.inf)
    for p, q in ((ta, tb), (tb, ta)):
        for k in range(3):
            d2, _ = contact.point_triangle_distance(p[:, k], q[:, 0], q[:, 1], q[:, 2])
            best = np.minimum(best, d2)
    for k in range(3):
        for m in range(3):
            d2, _ = contact.edge_edge_distance(ta[:, k], ta[:, (k + 1) % 3],
                                               tb[:, m], tb[:, (m + 1) % 3])
            best = np.minimum(best, d2)
    return np.sqrt(best)


def test_near_pairs_hold_every_pair_closer_than_the_reach():
    x, tris = crumpled_sheet()
    reach = 0.04
    pairs, d = contact.near_triangle_pairs(x, tris, reach)
    a, b = np.triu_indices(len(tris), k=1)
    shared = (tris[a][:, :, None] == tris[b][:, None, :]).any(axis=(1, 2))
    a, b = a[~shared], b[~shared]
    brute = primitive_distance(x, tris, a, b)
    close = {(int(i), int(j)) for i, j in zip(a[brute < reach], b[brute < reach])}
    found = {tuple(p) for p in pairs.tolist()}
    assert len(close) > 50, "the spiral's layers are within reach of each other"
    assert close <= found
    assert len(found) < len(a) / 4, "a broad phase, not all pairs"
    # Distances agree with the batched kernels, and no pair shares a vertex.
    np.testing.assert_allclose(d, primitive_distance(x, tris, pairs[:, 0], pairs[:, 1]),
                               rtol=1e-12, atol=1e-15)
    assert not (tris[pairs[:, 0]][:, :, None] == tris[pairs[:, 1]][:, None, :]).any()
    assert checks.min_separation(x, tris, reach) == pytest.approx(brute.min())


def test_crossing_triangles_are_found_and_separated_ones_are_not():
    x, tris = crumpled_sheet()
    assert checks.intersecting_pairs(x, tris) == []
    # Push one vertex of the inner layer through the layer outside it.
    y = x.copy()
    inner = 3 * 10 + 2  # row 3, column 2: about one layer gap inside the next turn
    y[inner] *= [1.6, 1.0, 1.6]
    crossed = checks.intersecting_pairs(y, tris)
    assert crossed, "the moved vertex's triangles cross the outer layer"
    for i, j in crossed:
        assert not set(tris[i]) & set(tris[j])
        assert inner in tris[i] or inner in tris[j], "only the moved vertex's triangles cross"


@pytest.mark.parametrize("reach, positions, triangles, match", [
    (0.0, np.zeros((3, 3)), [[0, 1, 2]], "reach"),
    (np.nan, np.zeros((3, 3)), [[0, 1, 2]], "reach"),
    (0.1, np.zeros((3, 2)), [[0, 1, 2]], "positions"),
    (0.1, [[0, 0, 0], [1, 0, 0], [0, np.inf, 0]], [[0, 1, 2]], "row 2"),
    (0.1, np.zeros((3, 3)), [[0, 1, 3]], r"triangles\[0\]"),
    (0.1, np.zeros((3, 3)), [[0.5, 1, 2]], "integers"),
])
def test_bad_input_names_the_value(reach, positions, triangles, match):
    with pytest.raises(ValueError, match=match):
        contact.near_triangle_pairs(positions, triangles, reach)
