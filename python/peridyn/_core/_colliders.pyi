"""Colliders and the contact model."""

from typing import Any, Optional, Tuple

import numpy as np

from ._options import ArrayLike, Vec3, DescentStep, ProximalMetric

class Collider:
    """Base of every collider. Every collider takes ``friction`` (Coulomb coefficient, >= 0:
    membranes stick while the tangential force stays within ``friction`` times the contact
    force, and slide against it otherwise) and ``velocity`` (m/s, constant; the pose given is
    the one at time 0). A solver can also drive any collider by rigid poses
    (:meth:`Solver.set_collider_pose`).

    Vertices are kept half their membrane's thickness outside, on the side they came from:
    a move that would cross a collider within one step (a fast impact on a thin plate, or a
    plate sweeping through a cloth) stops on the near face and slides along it, whatever the
    speed and thickness."""

    def signed_distance(self, points: ArrayLike, time: float = 0.0) -> np.ndarray:
        """Signed distances (m, positive outside) of (n, 3) points at ``time`` (s)."""
    @property
    def friction(self) -> float:
        """Coulomb friction coefficient against membranes (>= 0)."""
    @property
    def velocity(self) -> np.ndarray:
        """Constant velocity (m/s); the pose given is the one at time 0."""

class Plane(Collider):
    """Half-space collider: vertices stay on the side the ``normal`` points to."""

    def __init__(self, *, point: Vec3 = (0.0, 0.0, 0.0), normal: Vec3 = (0.0, 0.0, 1.0), friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None: ...
    @property
    def point(self) -> np.ndarray: ...
    @property
    def normal(self) -> np.ndarray: ...

class Sphere(Collider):
    """Solid sphere collider (m)."""

    def __init__(self, *, center: Vec3, radius: float, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None: ...
    @property
    def center(self) -> np.ndarray: ...
    @property
    def radius(self) -> float: ...

class Box(Collider):
    """Solid oriented box collider (m)."""

    def __init__(self, *, center: Vec3, half_extents: Vec3, rotation: Optional[ArrayLike] = None, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """``rotation``: 3x3 rotation matrix (orthonormal within 1e-6, re-orthonormalised; det +1)
        whose columns are the box axes (default: axis-aligned)."""
    @property
    def center(self) -> np.ndarray: ...
    @property
    def half_extents(self) -> np.ndarray: ...
    @property
    def rotation(self) -> np.ndarray: ...

class Capsule(Collider):
    """Solid capsule collider: the points within ``radius`` (m) of the segment from ``a`` to ``b``."""

    def __init__(self, *, a: Vec3, b: Vec3, radius: float, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None: ...
    @property
    def a(self) -> np.ndarray: ...
    @property
    def b(self) -> np.ndarray: ...
    @property
    def radius(self) -> float: ...

class MeshCollider(Collider):
    """Solid bounded by a closed triangle mesh, turned into a signed distance field on a grid.

    Every grid node holds the exact distance to the nearest triangle (a bounding volume
    hierarchy finds it), signed by the angle-weighted pseudonormal of the nearest feature
    (negative inside). Queries interpolate trilinearly; the normal is the normalised gradient
    of that interpolated field. Outside the grid the field continues as the distance to the
    grid box plus the value there. Error: O(h^2) where the surface is smooth, up to about
    h/2 near sharp edges, for the cell size ``h`` = :attr:`cell_size`.

    The mesh must be closed (watertight: every edge shared by exactly two triangles) and
    consistently oriented; an inside-out mesh is turned outward. Open, non-manifold or
    inconsistently oriented meshes, degenerate triangles, non-finite vertices and triangle
    indices out of range raise ``ValueError`` naming the edge, triangle or vertex.
    """

    def __init__(self, vertices: Any, triangles: Optional[ArrayLike] = None, *, resolution: int = 64, margin: Optional[float] = None, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """``vertices`` (n, 3) in m and ``triangles`` (m, 3) vertex indices, or a
        ``trimesh.Trimesh`` alone. ``resolution``: cells along the longest side of the mesh's
        bounding box (>= 2; cell size = longest side / resolution, m): the speed/accuracy
        knob (the default 64 gives about 78^3 = 475K nodes; measured build cost about 4 CPU-s
        per million nodes for a 5K-triangle mesh, 9 for 20K triangles, spread over the
        threads). ``margin`` (m, >= 0): how far the grid reaches beyond the mesh's bounding box
        (default max(0.1 longest side, 2 cells)); keep the membranes' reach within it. A grid of
        more than 2^27 nodes (1 GiB) is a ValueError naming the resolution and the margin."""
    @property
    def cell_size(self) -> float:
        """Grid node spacing h (m)."""
    @property
    def grid_shape(self) -> Tuple[int, int, int]:
        """Grid nodes along x, y and z."""
    @property
    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """Lowest and highest corner of the grid box (m)."""
    @property
    def vertices(self) -> np.ndarray:
        """(n, 3) mesh vertices (m)."""
    @property
    def triangles(self) -> np.ndarray:
        """(m, 3) triangles, oriented outward (counter-clockwise seen from outside)."""

class Contact:
    """Contact between and within membranes: the local step of Algorithm 2 (Lu et al. 2023).

    Parameters
    ----------
    thickness : contact thickness xi in m (> 0): mid-surfaces stay about xi apart, never closer
        than eps * xi.
    d_hat : barrier range in m on the gap f(d) - xi (None: thickness / 2; Table 1 has
        4 * thickness). Layers at rest on one another lie about thickness + d_hat apart.
    eps : minimal separation multiplier of eq. 51 in (0, 1); also the largest descent move per
        iteration in units of xi.
    weight : barrier weight mu of eq. 47 (> 0; with proximal="jacobi" in units of the mean
        Jacobi block d, see below).
    max_iters : descent iterations per local step (>= 1). A local step stops earlier once its
        largest move is below eps * xi / 100, or below tol / 5 where the solver's tol is
        smaller: its result is only that exact, and a stop above about tol / 2 lets the global
        iteration go on at tol without converging. A tight tol thus also costs local
        iterations (on three layers at tol = 1e-6 m, 19 per step median against 11).
    step : the descent's step rule: "curvature" (default) moves each vertex by its direction
        times (W + K)^-1, W the proximal metric (below) and K the barrier's curvature along the
        contact normals there (a block-Jacobi-preconditioned descent: stiff along the normals,
        free along the contact), or
        "uniform", eq. 53 of the paper: one step length for all vertices from the barrier's
        steepest slope. Both move no vertex more than eps * xi per iteration; near contact
        "uniform" creeps and a local step usually ends at max_iters, far from its minimum. A
        move shorter than a quarter of the stopping distance (eps * xi / 400 unless tol asks
        for less) is not taken (the vertex has settled).
    toi_threshold : times of impact in (toi_threshold, 1) clamp vertices inside the descent.
    ccd_s, ccd_t_c : the additive CCD's s and t_c (paper: 0.1 and 0.95).
    warm_start : start each local step's descent from the global step's result plus the move
        the last local step made (where the barrier pushed), instead of the global step's result
        alone (the paper): the local steps of a time step continue one another's descent. Same
        guarantees; on the 3-layer drop about half the descent iterations, and steps whose
        contacts persist converge instead of stalling at the local step's stopping test.
    parallel_angle : radians in [0, pi/2); default asin(sqrt(1e-3)), 1.8 degrees, IPC's
        edge-edge mollifier (not in the paper). An edge-edge pair whose edges are closer to
        parallel than this at the local step's start enters the barrier with a weight falling
        to 0 for parallel edges; the point-triangle pairs hold the contact there. The closest
        points of nearly parallel edges jump along them, and without the fade (0) stacked
        layers stall at a convergence measure of about a micrometre: a tol below that runs
        steps to max_iters, and every local step to its own max_iters.
    proximal : the metric W_i of eq. 47's proximal term, sum_i (z_i - y_i)^T W_i (z_i - y_i) / 2.
        "jacobi" (default, not in the paper): W_i = D_i / d, the global step's Jacobi block of
        the vertex (m_i I + h^2 sum (C_i + C_j), kg) over d, the mean of trace(D_i) / 3 over the
        free vertices. Both steps then work in one metric: the iteration's fixed points are the
        stationary points of the implicit Euler energy plus d * weight * B / h^2, and a pair's
        contact forces cancel (contact conserves momentum); the barrier's weight is effectively
        d * weight. "identity": the paper's W_i = I; the contact force on a vertex is then
        scaled by its own D_i, so contact between bodies of different mass or stiffness makes
        momentum (a light sheet stops a heavy one as hard as it is stopped). On stacked layers
        landing at speed "jacobi" also took 44 % fewer local iterations.
    """

    def __init__(
        self,
        *,
        thickness: float = 1.5e-3,
        d_hat: Optional[float] = None,
        eps: float = 0.1,
        weight: float = 1.0,
        max_iters: int = 32,
        step: DescentStep = "curvature",
        toi_threshold: float = 0.1,
        ccd_s: float = 0.1,
        ccd_t_c: float = 0.95,
        warm_start: bool = True,
        parallel_angle: Optional[float] = None,
        proximal: ProximalMetric = "jacobi",
    ) -> None: ...
    @property
    def thickness(self) -> float: ...
    @property
    def d_hat(self) -> float: ...
    @property
    def eps(self) -> float: ...
    @property
    def weight(self) -> float: ...
    @property
    def max_iters(self) -> int: ...
    @property
    def step(self) -> DescentStep: ...
    @property
    def toi_threshold(self) -> float: ...
    @property
    def warm_start(self) -> bool: ...
    @property
    def proximal(self) -> ProximalMetric: ...
    @property
    def parallel_angle(self) -> float: ...
    @property
    def ccd_s(self) -> float: ...
    @property
    def ccd_t_c(self) -> float: ...
    def stop_distance(self, tol: float) -> float:
        """The local step's stopping distance in m under the solver tolerance ``tol`` (m, >= 0;
        0 for a fixed iteration count): eps * xi / 100, or tol / 5 where that is smaller. The
        local step's result is only this exact."""
    def replace(self, **changes: Any) -> "Contact":
        """A copy with the parameters named by keyword (the constructor's names) changed and the
        rest kept, validated as the constructor validates: ``c.replace(parallel_angle=0.0)``.
        ``d_hat`` is kept unless named, also where ``thickness`` changes."""
