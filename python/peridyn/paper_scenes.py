"""The contact scenes of Lu et al. 2023 (Table 1): cloths over a ball, an antependium on a
table with books, and a closed shell shot into a cloth target.

Every builder takes a size argument (vertices per side, or the shell's subdivisions) so that
tests run small versions and benchmarks the paper's sizes, and returns a
:class:`peridyn.scenes.Scene`. Parameters follow Table 1 of the paper: time step ``h``, the
stretch stiffness ``s0`` of :class:`StretchA3` (Pa), the bending factor ``kb`` and the contact
thickness ``xi``.

Two conventions are ours, not the paper's:

* Bending. Table 1 gives the bending stiffness as a multiple ``kb`` of ``s0``; here it is that
  multiple of the rigidity of a plate of Young's modulus ``2 s0`` (the in-plane modulus of
  ``StretchA3``), ``bending = kb * E t^3 / 12`` with ``E = 2 s0`` (N*m).
* Barrier range. The barrier must not act between neighbouring primitives of one mesh at
  rest, or it would push a membrane's own triangles apart in its plane. The builders measure
  ``g``, the smallest distance between non-adjacent primitives of each mesh at rest (0.71
  edges on a square grid, less on a coarse icosphere), and cap ``d_hat = 4 xi`` (the paper's
  choice) so that the barrier reaches at most ``0.85 g`` (``xi + d_hat <= 0.85 g``: room
  for 15 % in-plane compression). A mesh too fine for its thickness (cap below ``xi / 2``)
  raises ``ValueError``.
"""

from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from . import _core
from .checks import min_separation
from .materials import plate_bending_stiffness
from .mesh import grid
from .scenes import Scene
from .solver import Solver

__all__ = ["antependium", "cloths_over_ball", "shooting_shell"]

#: Areal mass of the cloths: 1 mm at 300 kg/m^3 (0.3 kg/m^2, a heavy cotton).
THICKNESS = 1e-3
DENSITY = 300.0
#: The barrier reaches at most this fraction of the smallest distance between non-adjacent
#: primitives of a mesh at rest.
REST_GAP_FRACTION = 0.85


def _bending(kb: float, s0: float) -> float:
    """``kb`` times the rigidity of a plate of Young's modulus ``2 s0`` (N*m)."""
    return kb * plate_bending_stiffness(2.0 * s0, 0.0, THICKNESS)


def _cloth(V: np.ndarray, F: np.ndarray, s0: float, kb: float) -> _core.Membrane:
    """A membrane of the scenes' cloth (:data:`THICKNESS`, :data:`DENSITY`) with
    :class:`StretchA3` stiffness ``s0`` (Pa) and bending factor ``kb`` (see the module doc)."""
    return _core.Membrane(V, F, thickness=THICKNESS, density=DENSITY,
                          material=_core.StretchA3(s0=s0), bending=_bending(kb, s0))


def _rest_gap(V: np.ndarray, F: np.ndarray) -> float:
    """The smallest distance (m) between non-adjacent primitives of the mesh ``(V, F)``
    (looked for within its longest edge: two triangles sharing no vertex are closer than that
    wherever the mesh is regular)."""
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    longest = float(np.linalg.norm(V[edges[:, 0]] - V[edges[:, 1]], axis=1).max())
    return min_separation(V, F, longest)


def _solver(scene: str, xi: float, meshes: Sequence[tuple], solver_options: Optional[dict],
            **settings) -> Solver:
    """A solver with ``settings`` (``dt``, ``tol``, ``max_iters``, ``threads``) and the
    caller's ``solver_options``, and contact of thickness ``xi`` (m) with ``d_hat = min(4 xi,
    0.85 g - xi)`` (see the module doc), ``g`` the smallest rest gap of ``meshes``."""
    gap = min(_rest_gap(np.asarray(V, dtype=np.float64), np.asarray(F)) for V, F in meshes)
    d_hat = min(4.0 * xi, REST_GAP_FRACTION * gap - xi)
    if d_hat < 0.5 * xi:
        raise ValueError(
            f"{scene}: the mesh is too fine for the contact thickness {xi:g} m: non-adjacent "
            f"primitives {gap:g} m apart at rest leave a barrier range of {d_hat:g} m < xi / 2; "
            "use fewer vertices or a thinner contact"
        )
    return Solver(contact=_core.Contact(thickness=xi, d_hat=d_hat), **settings,
                  **(solver_options or {}))


def _check(scene: str, **values: float) -> None:
    for name, value in values.items():
        if not math.isfinite(value) or value <= 0.0:
            raise ValueError(f"{scene}: {name} must be > 0, got {value!r}")


def _steps(duration: float, dt: float) -> int:
    return int(round(duration / dt))


def cloths_over_ball(
    *,
    layers: int = 1,
    n: int = 200,
    size: float = 1.7,
    dt: float = 1e-3,
    s0: float = 12000.0,
    kb: float = 0.1,
    xi: float = 1.5e-3,
    ball_radius: Optional[float] = None,
    drop: float = 5e-3,
    layer_gap: float = 1.5,
    friction: float = 0.3,
    duration: float = 2.0,
    tol: float = 1e-4,
    max_iters: int = 100,
    threads: Optional[int] = None,
    solver_options: Optional[dict] = None,
) -> Scene:
    """Square cloths stacked flat above a ball that rests on the ground, dropped onto it
    (Table 1: 1, 3 or 6 layers of 200 x 200 vertices, 1.7 m).

    The ball (a :class:`Sphere` of radius ``ball_radius``) touches the ground plane ``z = 0``
    at the origin; the lowest cloth lies ``drop`` above its top, the others above it, each
    ``layer_gap`` barrier reaches (``xi + d_hat``) above the one below, so that they start out
    of contact. The cloths are ``layer0`` (lowest) ... in ``Scene.bodies``, the colliders
    ``ball`` and ``ground``.

    Parameters
    ----------
    layers : int
        Number of cloths (>= 1; the paper: 1, 3, 6).
    n : int
        Vertices per side of each cloth (>= 2): ``layers * n * n`` vertices in all.
    size : float
        Side of each cloth in m.
    dt : float
        Time step in s.
    s0 : float
        :class:`StretchA3` stiffness in Pa.
    kb : float
        Bending factor (see the module doc).
    xi : float
        Contact thickness in m.
    ball_radius : float, optional
        In m; default ``0.3 * size``.
    drop : float
        Height of the lowest cloth above the ball's top in m.
    layer_gap : float
        Spacing of the layers in barrier reaches (> 1: out of contact at the start).
    friction : float
        Coulomb coefficient of the ball and of the ground.
    duration : float
        Simulated time in s covered by the suggested ``steps``.
    tol, max_iters, threads
        Passed to :class:`Solver`.
    solver_options : dict, optional
        Further keyword arguments of :class:`Solver` (``acceleration="chebyshev"``,
        ``chebyshev_rho=0.9``, ...).

    Returns
    -------
    Scene
    """
    name = "cloths_over_ball"
    if isinstance(layers, bool) or int(layers) != layers or layers < 1:
        raise ValueError(f"{name}: layers must be an integer >= 1, got {layers!r}")
    radius = 0.3 * size if ball_radius is None else ball_radius
    _check(name, size=size, dt=dt, s0=s0, xi=xi, ball_radius=radius, drop=drop)
    if not layer_gap > 1.0:
        raise ValueError(f"{name}: layer_gap must be > 1 barrier reach, got {layer_gap!r}")
    V, F = grid(n, n, size=(size, size), diagonal="alternate")
    V = V - np.array([0.5 * size, 0.5 * size, 0.0])
    solver = _solver(name, xi, [(V, F)], solver_options, dt=dt, tol=tol, max_iters=max_iters,
                     threads=threads)
    gap = layer_gap * (xi + solver.contact.d_hat)
    bodies = {}
    for k in range(int(layers)):
        z = 2.0 * radius + drop + k * gap
        cloth = _cloth(V + np.array([0.0, 0.0, z]), F, s0, kb)
        solver.add(cloth)
        bodies[f"layer{k}"] = cloth
    colliders = {
        "ball": _core.Sphere(center=(0.0, 0.0, radius), radius=radius, friction=friction),
        "ground": _core.Plane(friction=friction),
    }
    for collider in colliders.values():
        solver.add_collider(collider)
    description = (
        f"{layers} cloth(s) of {n}x{n} ({size:g} m, s0 = {s0:g} Pa, kb = {kb:g}) dropped onto "
        f"a ball of radius {radius:g} m; xi = {xi * 1e3:g} mm, h = {dt:g} s"
    )
    return Scene(solver, bodies, colliders, _steps(duration, dt), description)


def antependium(
    *,
    n: int = 200,
    bending: float = 0.03,
    size: float = 1.0,
    dt: float = 1e-3,
    s0: float = 8000.0,
    xi: float = 1.4e-3,
    overhang: float = 0.35,
    friction: float = 0.6,
    books: int = 2,
    duration: float = 2.0,
    tol: float = 1e-4,
    max_iters: int = 100,
    threads: Optional[int] = None,
    solver_options: Optional[dict] = None,
) -> Scene:
    """A square cloth laid flat on a table, part of it sticking out over the front edge, with
    books on the part on the table (Table 1: 200 x 200 vertices, 1 m; bending 0, 0.003, 0.03,
    0.3). Released, the free part falls and hangs down the table's front.

    The table is a :class:`Box` whose top is ``z = 0`` and whose front edge is ``y = 0``
    (the table spans ``y`` in ``[-0.8 size, 0]``); the cloth spans ``x`` in
    ``[-size / 2, size / 2]`` and ``y`` in ``[overhang - size, overhang]``, lying at its half
    thickness above the top. The books are boxes resting on the cloth (fixed colliders: they
    keep it from lifting off). The table and books have Coulomb friction ``friction``, which
    holds the cloth on the table: the hanging part's weight must stay below ``friction``
    times the weight on the table (``overhang < friction / (1 + friction) size``).
    ``Scene.bodies``: ``cloth``; ``Scene.colliders``: ``table``, ``book0``, ...

    Parameters
    ----------
    n : int
        Vertices per side (>= 2).
    bending : float
        Bending factor ``kb`` (see the module doc; the paper: 0, 0.003, 0.03, 0.3).
    size : float
        Side of the cloth in m.
    dt, s0, xi
        Time step (s), :class:`StretchA3` stiffness (Pa), contact thickness (m).
    overhang : float
        Length of cloth beyond the table's edge at the start, in m.
    friction : float
        Coulomb coefficient of the table and the books.
    books : int
        Number of books (0 to 3), side by side along the table's edge.
    duration : float
        Simulated time in s covered by the suggested ``steps``.
    tol, max_iters, threads
        Passed to :class:`Solver`.
    solver_options : dict, optional
        Further keyword arguments of :class:`Solver` (``acceleration="chebyshev"``,
        ``chebyshev_rho=0.9``, ...).

    Returns
    -------
    Scene
    """
    name = "antependium"
    _check(name, size=size, dt=dt, s0=s0, xi=xi, overhang=overhang)
    if not math.isfinite(bending) or bending < 0.0:
        raise ValueError(f"{name}: bending must be >= 0, got {bending!r}")
    if not 0.0 < overhang < size:
        raise ValueError(f"{name}: overhang must be in (0, {size:g}) m, got {overhang!r}")
    if books not in (0, 1, 2, 3):
        raise ValueError(f"{name}: books must be 0, 1, 2 or 3, got {books!r}")
    V, F = grid(n, n, size=(size, size), diagonal="alternate")
    V = V + np.array([-0.5 * size, overhang - size, 0.5 * THICKNESS])
    solver = _solver(name, xi, [(V, F)], solver_options, dt=dt, tol=tol, max_iters=max_iters,
                     threads=threads)
    cloth = _cloth(V, F, s0, bending)
    solver.add(cloth)
    depth, height = 0.8 * size, 0.75
    colliders = {
        "table": _core.Box(
            center=(0.0, -0.5 * depth, -0.5 * height),
            half_extents=(0.6 * size, 0.5 * depth, 0.5 * height),
            friction=friction,
        )
    }
    book = np.array([0.1, 0.075, 0.02]) * (size / 1.0)  # half extents: a 20 x 15 x 4 cm book
    for k in range(books):
        x = (k - 0.5 * (books - 1)) * 3.0 * book[0]
        colliders[f"book{k}"] = _core.Box(
            center=(x, -0.5 * (size - overhang), THICKNESS + book[2]),
            half_extents=tuple(book),
            friction=friction,
        )
    for collider in colliders.values():
        solver.add_collider(collider)
    description = (
        f"{n}x{n} cloth ({size:g} m, s0 = {s0:g} Pa, kb = {bending:g}) on a table with "
        f"{books} book(s), {overhang:g} m over the edge; xi = {xi * 1e3:g} mm, h = {dt:g} s"
    )
    return Scene(solver, {"cloth": cloth}, colliders, _steps(duration, dt), description)


def shooting_shell(
    *,
    subdivisions: int = 4,
    n: int = 120,
    s0: float = 8000.0,
    kb: float = 0.005,
    radius: float = 0.3,
    size: float = 2.0,
    target_s0: float = 12000.0,
    speed: float = 15.0,
    dt: float = 5e-4,
    xi: float = 6.1e-3,
    distance: float = 0.02,
    duration: float = 0.5,
    tol: float = 1e-4,
    max_iters: int = 100,
    threads: Optional[int] = None,
    solver_options: Optional[dict] = None,
) -> Scene:
    """A closed shell (an icosphere standing in for the paper's panda) shot straight down at
    ``speed`` into a horizontal square cloth pinned along its four edges (Table 1: h = 5e-4 s,
    s0 = 2000, 8000 or 40000 Pa, kb = 0.005, xi = 6.1 mm, 15 m/s).

    The target lies in ``z = 0`` centred on the origin; the shell's lowest point starts
    ``distance`` above it. Gravity is g. ``Scene.bodies``: ``shell`` (self-contact on) and
    ``target``; no colliders.

    Size and contact thickness: the default (subdivision 4 of a 0.3 m sphere, 2562 vertices,
    shortest edge 21 mm; a 2 m target of 120 x 120, 17 mm) keeps ``xi = 6.1 mm`` below the
    spacing of both meshes, as the paper's 27.8K-vertex panda does. Finer meshes need a
    thinner ``xi`` (see the module doc); coarser ones keep it.

    Parameters
    ----------
    subdivisions : int
        Icosphere subdivisions of the shell (>= 1): ``10 * 4^k + 2`` vertices.
    n : int
        Vertices per side of the target (>= 2).
    s0 : float
        The shell's :class:`StretchA3` stiffness in Pa (the paper: 2000, 8000, 40000).
    kb : float
        The shell's bending factor (see the module doc).
    radius : float
        Shell radius in m.
    size : float
        Side of the target in m.
    target_s0 : float
        The target's stiffness in Pa (its bending factor is 0.1).
    speed : float
        Initial speed of the shell in m/s, along -z.
    dt, xi
        Time step (s), contact thickness (m).
    distance : float
        Initial gap between the shell and the target in m.
    duration : float
        Simulated time in s covered by the suggested ``steps``.
    tol, max_iters, threads
        Passed to :class:`Solver`.
    solver_options : dict, optional
        Further keyword arguments of :class:`Solver` (``acceleration="chebyshev"``,
        ``chebyshev_rho=0.9``, ...).

    Returns
    -------
    Scene
    """
    import trimesh

    name = "shooting_shell"
    _check(name, radius=radius, size=size, s0=s0, target_s0=target_s0, dt=dt, xi=xi,
           distance=distance)
    if not math.isfinite(speed):
        raise ValueError(f"{name}: speed must be finite, got {speed!r}")
    if isinstance(subdivisions, bool) or int(subdivisions) != subdivisions or subdivisions < 1:
        raise ValueError(f"{name}: subdivisions must be an integer >= 1, got {subdivisions!r}")
    if 2.0 * radius >= size:
        raise ValueError(f"{name}: the shell (radius {radius:g} m) must be smaller than the "
                         f"target ({size:g} m)")
    ball = trimesh.creation.icosphere(subdivisions=int(subdivisions), radius=radius)
    Vs = np.asarray(ball.vertices, dtype=np.float64) + np.array([0.0, 0.0, radius + distance])
    Fs = np.asarray(ball.faces, dtype=np.int64)
    Vt, Ft = grid(n, n, size=(size, size), diagonal="alternate")
    Vt = Vt - np.array([0.5 * size, 0.5 * size, 0.0])
    solver = _solver(name, xi, [(Vs, Fs), (Vt, Ft)], solver_options, dt=dt, tol=tol,
                     max_iters=max_iters, threads=threads)
    shell = _cloth(Vs, Fs, s0, kb)
    shell.velocities = np.tile([0.0, 0.0, -speed], (len(Vs), 1))
    target = _cloth(Vt, Ft, target_s0, 0.1)
    border = np.flatnonzero(np.isclose(np.abs(Vt[:, :2]).max(axis=1), 0.5 * size))
    target.pin(border)
    solver.add(shell)
    solver.add(target)
    description = (
        f"icosphere shell ({len(Vs)} vertices, r = {radius:g} m, s0 = {s0:g} Pa) shot at "
        f"{speed:g} m/s into a {n}x{n} target ({size:g} m) pinned along its edges; "
        f"xi = {xi * 1e3:g} mm, h = {dt:g} s"
    )
    return Scene(solver, {"shell": shell, "target": target}, {}, _steps(duration, dt),
                 description)
