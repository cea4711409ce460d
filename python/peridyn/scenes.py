"""Ready-made scenes: a solver with its bodies and colliders, set up and ready to ``run``."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Dict, Literal, Optional, Tuple

import numpy as np

from . import _core
from .materials import plate_bending_stiffness
from .mesh import grid
from .solver import Solver, gravity_tolerance

__all__ = ["Scene", "colliding_sheets", "default_scene", "elastic_torus_scene"]


@dataclass
class Scene:
    """A solver together with the objects it simulates.

    Bodies and colliders are also attributes by name: ``scene.cloth`` is
    ``scene.bodies["cloth"]``, ``scene.sphere`` is ``scene.colliders["sphere"]``.

    Attributes
    ----------
    solver : Solver
        The time stepper, bodies and colliders already added.
    bodies : dict of str to Membrane or Particles
        The bodies, by name, in the order they were added to the solver.
    colliders : dict of str to Collider
        The colliders, by name, in the order they were added to the solver.
    steps : int
        Suggested number of steps to run (``duration / dt``).
    description : str
        One line saying what the scene is.
    """

    solver: Solver
    bodies: Dict[str, Any]
    colliders: Dict[str, Any]
    steps: int
    description: str

    def __getattr__(self, name: str) -> Any:
        # Only called when ordinary lookup fails; the fields themselves never come here
        # (except while half-built, e.g. during unpickling: then they are simply missing).
        if name not in ("bodies", "colliders"):
            for group in (self.bodies, self.colliders):
                if name in group:
                    return group[name]
        raise AttributeError(f"Scene has no attribute, body or collider named {name!r}")


def default_scene(
    *,
    n: int = 120,
    size: float = 1.0,
    dt: float = 2e-3,
    duration: float = 1.0,
    thickness: float = 1e-3,
    density: float = 300.0,
    s0: float = 2e4,
    bending: Optional[float] = None,
    sphere_radius: float = 0.25,
    tol: Optional[float] = None,
    max_iters: int = 100,
    acceleration: Optional[str] = "chebyshev",
    chebyshev_rho: float = 0.9,
    threads: Optional[int] = None,
    backend: Literal["cpu", "gpu"] = "cpu",
) -> Scene:
    """A square cloth, pinned along one edge, swings down under gravity onto a sphere.

    The cloth is an ``n`` x ``n`` :func:`peridyn.mesh.grid` (alternating diagonals) of side
    ``size`` lying flat at ``z = 0`` (x and y in ``[0, size]``), pinned along its edge
    ``y = size``. A sphere of radius ``sphere_radius`` sits under the middle of the cloth's
    free part, so the cloth, swinging down about the pinned edge, catches on it and drapes
    over it.

    Parameters
    ----------
    n : int
        Vertices per side (>= 2); ``n * n`` vertices in all.
    size : float
        Side length of the cloth in m.
    dt : float
        Time step in s.
    duration : float
        Simulated time in s that the suggested ``steps`` cover.
    thickness : float
        Cloth thickness in m (1 mm).
    density : float
        Mass density in kg/m^3; ``density * thickness`` is the areal density (0.3 kg/m^2 by
        default, a heavy cotton).
    s0 : float
        Stiffness of the :class:`StretchA3` model in Pa (in-plane Young's modulus ``2 s0``).
        Real fabrics are stiffer; this value keeps the stretch under gravity at a few percent
        while converging in few iterations.
    bending : float, optional
        Bending rigidity in N*m; default: that of a plate of Young's modulus ``2 s0``,
        ``E t^3 / 12``.
    sphere_radius : float
        Sphere radius in m.
    tol, max_iters, acceleration, chebyshev_rho, threads, backend
        Passed to :class:`Solver` (``tol`` in m bounds the distance of each step from the exact
        implicit Euler solution; default :func:`gravity_tolerance` of ``dt``, which Chebyshev
        acceleration at ``rho = 0.9`` reaches in a quarter to a third fewer iterations than plain
        iterations from 40 x 40 vertices up (47 against 70 per step at 120 x 120, where plain
        iterations also hit ``max_iters``); ``acceleration=None`` for plain iterations;
        ``backend="gpu"`` takes ``threads=None``).

    Returns
    -------
    Scene
    """
    if size <= 0.0:
        raise ValueError(f"default_scene: size must be > 0 m, got {size!r}")
    if duration < 0.0:
        raise ValueError(f"default_scene: duration must be >= 0 s, got {duration!r}")
    if bending is None:
        bending = plate_bending_stiffness(2.0 * s0, 0.0, thickness)

    V, F = grid(n, n, size=(size, size), diagonal="alternate")
    cloth = _core.Membrane(
        V,
        F,
        thickness=thickness,
        density=density,
        material=_core.StretchA3(s0=s0),
        bending=bending,
    )
    pinned_edge = np.flatnonzero(np.isclose(V[:, 1], size))
    cloth.pin(pinned_edge)

    sphere = _core.Sphere(
        center=(0.5 * size, 0.45 * size, -0.3 * size),
        radius=sphere_radius,
    )
    tol = gravity_tolerance(dt) if tol is None else tol
    solver = Solver(dt=dt, tol=tol, max_iters=max_iters, threads=threads, backend=backend,
                    acceleration=acceleration, chebyshev_rho=chebyshev_rho)
    solver.add(cloth)
    solver.add_collider(sphere)
    steps = int(round(duration / dt))
    description = (
        f"{n}x{n} cloth ({size:g} m, s0 = {s0:g} Pa, t = {thickness * 1e3:g} mm), "
        f"pinned along y = {size:g} m, draping onto a sphere of radius {sphere_radius:g} m"
    )
    return Scene(
        solver=solver,
        bodies={"cloth": cloth},
        colliders={"sphere": sphere},
        steps=steps,
        description=description,
    )


def colliding_sheets(
    *,
    n: int = 7,
    size: float = 0.1,
    densities: Tuple[float, float] = (200.0, 1600.0),
    speed: float = 0.5,
    gap: float = 8e-3,
    thickness: float = 1e-3,
    s0: float = 2e3,
    bending: float = 1e-5,
    contact: Optional[_core.Contact] = None,
    dt: float = 1e-3,
    duration: float = 0.04,
    tol: float = 1e-7,
    max_iters: int = 100,
    threads: Optional[int] = None,
) -> Scene:
    """Two parallel sheets meet head-on in zero gravity: the momentum test of contact.

    Two ``n`` x ``n`` :func:`peridyn.mesh.grid` sheets of side ``size``, ``gap`` apart along
    z, the upper one shifted by half a grid spacing along x and y (so no vertex meets a
    vertex), approach each other at ``speed``: the lower one (``scene.lower``, density
    ``densities[0]``) moves up at ``speed / 2`` and the upper one (``scene.upper``,
    ``densities[1]``) down at ``speed / 2``. Without self-contact, and without gravity or
    colliders, every force between them is contact, so their total momentum
    ``sum(masses @ velocities)`` is conserved by exact contact; with unequal densities it shows
    whether the contact forces of a pair cancel (``Contact(proximal=...)``).

    Parameters
    ----------
    n : int
        Vertices per side of each sheet (>= 2).
    size : float
        Side length of each sheet in m.
    densities : (float, float)
        Mass densities of the lower and the upper sheet in kg/m^3.
    speed : float
        Closing speed in m/s, shared equally (each sheet moves at ``speed / 2``).
    gap : float
        Distance between the sheets' planes at the start, in m.
    thickness : float
        Sheet thickness in m (the membrane's mass; contact has its own thickness).
    s0 : float
        Stiffness of the :class:`StretchA3` model in Pa.
    bending : float
        Bending rigidity in N*m.
    contact : Contact, optional
        The contact parameters; default ``Contact(thickness=2e-3, d_hat=4e-3)``.
    dt : float
        Time step in s.
    duration : float
        Simulated time in s that the suggested ``steps`` cover (the default sees the sheets
        meet and part).
    tol, max_iters, threads
        Passed to :class:`Solver`.

    Returns
    -------
    Scene
        Bodies ``lower`` and ``upper``, no colliders.
    """
    if not size > 0.0:
        raise ValueError(f"colliding_sheets: size must be > 0 m, got {size!r}")
    if not gap > 0.0:
        raise ValueError(f"colliding_sheets: gap must be > 0 m, got {gap!r}")
    if not duration >= 0.0:
        raise ValueError(f"colliding_sheets: duration must be >= 0 s, got {duration!r}")
    if contact is None:
        contact = _core.Contact(thickness=2e-3, d_hat=4e-3)
    V, F = grid(n, n, size=(size, size))
    half_spacing = 0.5 * size / (n - 1)

    def sheet(shift: Tuple[float, float, float], density: float, velocity: float):
        body = _core.Membrane(V + np.array(shift), F, thickness=thickness, density=density,
                              material=_core.StretchA3(s0=s0), bending=bending,
                              self_contact=False)
        body.velocities = np.tile([0.0, 0.0, velocity], (body.num_vertices, 1))
        return body

    lower = sheet((0.0, 0.0, 0.0), densities[0], 0.5 * speed)
    upper = sheet((half_spacing, half_spacing, gap), densities[1], -0.5 * speed)
    solver = Solver(dt=dt, gravity=(0.0, 0.0, 0.0), tol=tol, max_iters=max_iters,
                    contact=contact, threads=threads)
    solver.add(lower)
    solver.add(upper)
    description = (
        f"two {n}x{n} sheets ({size:g} m, {densities[0]:g} and {densities[1]:g} kg/m^3) "
        f"meeting at {speed:g} m/s from {gap * 1e3:g} mm apart in zero gravity"
    )
    return Scene(
        solver=solver,
        bodies={"lower": lower, "upper": upper},
        colliders={},
        steps=int(round(duration / dt)),
        description=description,
    )


def elastic_torus_scene(
    *,
    n: int = 16,
    major_radius: float = 0.08,
    minor_radius: float = 0.03,
    young: float = 2e5,
    poisson: float = 0.3,
    density: float = 1000.0,
    drop: float = 0.15,
    tilt: float = 30.0,
    dt: float = 1.0 / 240.0,
    duration: float = 1.0,
    tol: Optional[float] = None,
    max_iters: int = 100,
    threads: Optional[int] = None,
) -> Scene:
    """An elastic torus of particles, tilted, falls onto the ground and comes to rest on it.

    The torus (a :func:`trimesh.creation.torus` in the xy-plane, turned by ``tilt`` about x) is
    filled by :func:`peridyn.sample_volume` with a lattice of ``n`` particles across its outer
    diameter, made a :class:`peridyn.Particles` body of ``Elastic.from_young(young, poisson)``,
    and dropped so that its lowest particle starts ``drop`` above a :class:`peridyn.Plane` at
    ``z = 0``.

    Parameters
    ----------
    n : int
        Particles across the torus's outer diameter ``2 (major_radius + minor_radius)`` (>= 4);
        the lattice spacing is that diameter over ``n``.
    major_radius, minor_radius : float
        Radii of the torus's centre circle and of its tube in m.
    young : float
        Young's modulus in Pa (a soft rubber by default).
    poisson : float
        Poisson's ratio, in [0, 0.45].
    density : float
        Mass density in kg/m^3.
    drop : float
        Height in m of the lowest particle above the ground at the start.
    tilt : float
        Angle in degrees between the torus's plane and the ground.
    dt : float
        Time step in s.
    duration : float
        Simulated time in s that the suggested ``steps`` cover.
    tol, max_iters, threads
        Passed to :class:`Solver` (``tol`` in m bounds the distance of each step from the exact
        implicit Euler solution; default :func:`gravity_tolerance` of ``dt``). The particles
        run on the CPU backend only.

    Returns
    -------
    Scene
        With the body ``torus`` and the collider ``ground``.
    """
    import trimesh

    if isinstance(n, bool) or int(n) != n or n < 4:
        raise ValueError(f"elastic_torus_scene: n must be an integer >= 4, got {n!r}")
    if not 0.0 < minor_radius < major_radius:
        raise ValueError(
            "elastic_torus_scene: the radii must satisfy 0 < minor_radius < major_radius, got "
            f"minor_radius={minor_radius!r} m, major_radius={major_radius!r} m"
        )
    if not drop >= 0.0:
        raise ValueError(f"elastic_torus_scene: drop must be >= 0 m, got {drop!r}")
    if duration < 0.0:
        raise ValueError(f"elastic_torus_scene: duration must be >= 0 s, got {duration!r}")
    spacing = 2.0 * (major_radius + minor_radius) / int(n)
    mesh = trimesh.creation.torus(major_radius=major_radius, minor_radius=minor_radius)
    X = _core.sample_volume(mesh, spacing=spacing)
    a = np.radians(tilt)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    X = X @ turn.T
    X[:, 2] += drop - X[:, 2].min()
    torus = _core.Particles(
        X, spacing=spacing, density=density, material=_core.Elastic.from_young(young, poisson)
    )
    ground = _core.Plane()
    tol = gravity_tolerance(dt) if tol is None else tol
    solver = Solver(dt=dt, tol=tol, max_iters=max_iters, threads=threads)
    solver.add(torus)
    solver.add_collider(ground)
    description = (
        f"an elastic torus of {len(X)} particles (radii {major_radius:g} and {minor_radius:g} m, "
        f"E = {young:g} Pa, nu = {poisson:g}) dropped {drop:g} m onto the ground"
    )
    return Scene(
        solver=solver,
        bodies={"torus": torus},
        colliders={"ground": ground},
        steps=int(round(duration / dt)),
        description=description,
    )
