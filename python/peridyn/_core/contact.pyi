"""The contact primitives of ``peridyn._core.contact`` (Lu et al. 2023, section 6), for
checks and tests: distances with their gradients, the additive CCD, and the broad phase."""

from typing import Tuple

import numpy as np

from ._options import ArrayLike

def point_triangle_distance(
    p: ArrayLike, t0: ArrayLike, t1: ArrayLike, t2: ArrayLike
) -> Tuple[np.ndarray, np.ndarray]:
    """Squared point-triangle distances (m^2) of n queries (each argument (n, 3), m) and their
    gradients with respect to ``(p, t0, t1, t2)``, shape (n, 12)."""

def edge_edge_distance(
    a0: ArrayLike, a1: ArrayLike, b0: ArrayLike, b1: ArrayLike
) -> Tuple[np.ndarray, np.ndarray]:
    """Squared edge-edge distances (m^2) of n queries (each argument (n, 3), m) and their
    gradients with respect to ``(a0, a1, b0, b1)``, shape (n, 12)."""

def near_triangle_pairs(
    positions: ArrayLike, triangles: ArrayLike, reach: float
) -> Tuple[np.ndarray, np.ndarray]:
    """The pairs of triangles sharing no vertex whose bounding boxes at ``positions`` ((n, 3),
    m), inflated by ``reach / 2`` (m, > 0) on each side, overlap (the solver's broad phase:
    every pair closer than ``reach`` is among them), and per pair the smallest of its 15
    primitive distances (m; the triangles' distance unless they cross). Returns
    ``(pairs, distances)``: (m, 2) int64 with ``a < b``, sorted, and (m,)."""

def point_triangle_ccd_additive(
    start: ArrayLike, end: ArrayLike, min_distance: float = 0.0, *, s: float = 0.1,
    t_c: float = 0.95
) -> Tuple[np.ndarray, np.ndarray]:
    """Additive CCD of n point-triangle pairs moving linearly from ``start`` to ``end`` (each
    (n, 4, 3), m: the point, then the triangle's vertices). Returns ``(hit, toi)``: whether the
    distance reaches ``min_distance`` (m, >= 0) within the step (bool, (n,)), and a lower bound
    of that time as a fraction of the step (1 where no hit). ``0 < s < 1``, ``0 < t_c <= 1``:
    the additive CCD's parameters."""

def edge_edge_ccd_additive(
    start: ArrayLike, end: ArrayLike, min_distance: float = 0.0, *, s: float = 0.1,
    t_c: float = 0.95
) -> Tuple[np.ndarray, np.ndarray]:
    """Additive CCD of n edge-edge pairs (each (n, 4, 3), m: ``a0, a1, b0, b1``); see
    :func:`point_triangle_ccd_additive`."""
