"""Contact adds no energy (issue 41, items 1 and 2): a membrane whose own primitives lie within
the barrier's reach at rest stays at rest, layers that start inside the reach are not launched,
and the mechanical energy of a scene with contact never rises.

The mechanical energy (J) is kinetic + gravitational (`-m g . y`) + elastic
(`Membrane.elastic_energy()`) + the barrier's (`StepStats.contact["barrier_energy"]`, its energy
`d mu B / h^2`, see docs/model.md). Small meshes: the file runs in seconds.
"""

import numpy as np
import pytest

import peridyn
from conftest import icosphere, make_grid

G = np.array([0.0, 0.0, -9.81])


def cloth(n, size, z, thickness, *, s0=2e4, bending=1e-3):
    v, t = make_grid(n, n, size, size)
    v = v + np.array([-size / 2, -size / 2, z])
    return peridyn.Membrane(v, t, thickness=thickness, density=200.0,
                            material=peridyn.StretchA3(s0=s0), bending=bending,
                            self_contact=True)


def solver_for(bodies, xi, *, gravity=(0.0, 0.0, 0.0), dt=1e-3, colliders=()):
    solver = peridyn.Solver(dt=dt, tol=1e-5, max_iters=60, gravity=gravity,
                            contact=peridyn.Contact(thickness=xi, eps=0.1))
    for b in bodies:
        solver.add(b)
    for c in colliders:
        solver.add_collider(c)
    return solver


def largest_speed(bodies):
    return max(np.linalg.norm(b.velocities, axis=1).max() for b in bodies)


def mechanical_energy(bodies, gravity, barrier):
    """Kinetic + gravitational + elastic + barrier energy (J)."""
    g = np.asarray(gravity, dtype=float)
    return sum(b.kinetic_energy() + b.elastic_energy() - float(b.masses @ (b.positions @ g))
               for b in bodies) + barrier


def energies(solver, bodies, gravity, steps):
    """The mechanical energy before the first step and after each of `steps` steps."""
    out = [mechanical_energy(bodies, gravity, 0.0)]
    for _ in range(steps):
        stats = solver.step()
        out.append(mechanical_energy(bodies, gravity, stats.contact["barrier_energy"]))
    return np.array(out)


def test_a_coarse_thick_sheet_at_rest_stays_at_rest():
    # Edges of 25 mm, reach xi + d_hat = 20 mm: each vertex lies about 18 mm from triangles of
    # its own sheet it does not belong to. Their start is their rest gap: no barrier, no motion.
    sheet = cloth(9, 0.2, 0.0, 4e-3)
    solver = solver_for([sheet], 4e-3)
    for _ in range(5):
        stats = solver.step()
        # Round-off may leave a pair a hair inside its rest gap: energy of order 1e-40 J.
        assert stats.contact["barrier_energy"] < 1e-12
    assert largest_speed([sheet]) < 1e-6


@pytest.mark.parametrize("spacing", [3e-3, 1.5e-3])
def test_layers_stacked_inside_the_reach_stay_still_in_zero_gravity(spacing):
    # Reach 5 mm (xi = 1 mm, d_hat = 4 mm): the layers start inside it, and stay where they are.
    layers = [cloth(9, 0.2, k * spacing, 1e-3) for k in range(3)]
    solver = solver_for(layers, 1e-3)
    for _ in range(20):
        solver.step()
        assert largest_speed(layers) < 0.03


def test_primitives_closer_than_eps_xi_are_not_launched():
    # Two layers 0.05 mm apart, below eps xi = 0.1 mm: held where they are, not pushed apart.
    layers = [cloth(7, 0.15, k * 5e-5, 1e-3) for k in range(2)]
    solver = solver_for(layers, 1e-3)
    for _ in range(10):
        solver.step()
        assert largest_speed(layers) < 0.03


def test_a_stack_under_gravity_never_beats_free_fall():
    # Three layers 3 mm apart, inside the reach, fall towards a ball 3 cm below (reached after
    # about 78 ms): no vertex rises above its start, and none moves faster than free fall.
    # (After the impact a draping cloth's edges may whip faster than free fall, legitimately.)
    layers = [cloth(9, 0.2, 0.03 + k * 3e-3, 1e-3) for k in range(3)]
    ball = peridyn.Sphere(center=(0.0, 0.0, -0.05), radius=0.05)
    solver = solver_for(layers, 1e-3, gravity=tuple(G), colliders=[ball])
    start = [b.positions[:, 2].copy() for b in layers]
    for k in range(1, 61):
        solver.step()
        t = k * 1e-3
        assert largest_speed(layers) <= 9.81 * t + 0.01, k
        for b, z0 in zip(layers, start):
            assert (b.positions[:, 2] - z0).max() < 1e-4, k


# The energy bound: the mechanical energy after any step is at most its start plus this
# share of the energy scale of the scene (the largest of its kinetic, gravitational release and
# elastic energies over the run), plus a floor for round-off (J).
ENERGY_SHARE = 0.01
ENERGY_FLOOR = 1e-6


def assert_energy_never_rises(e, scale):
    rise = np.max(e - e[0])
    assert rise <= ENERGY_SHARE * scale + ENERGY_FLOOR, (rise, scale, e)


def test_energy_never_rises_over_a_close_start():
    layers = [cloth(9, 0.2, k * 3e-3, 1e-3) for k in range(3)]
    solver = solver_for(layers, 1e-3)
    e = energies(solver, layers, (0, 0, 0), 20)
    # No energy to speak of: the rise is bounded by the floor alone.
    assert_energy_never_rises(e, 0.0)


def test_energy_never_rises_over_a_contact_drop():
    # Two layers, the upper 15 mm above the lower, dropped onto a ball.
    layers = [cloth(9, 0.2, 0.01, 1e-3), cloth(9, 0.2, 0.025, 1e-3)]
    ball = peridyn.Sphere(center=(0.0, 0.0, -0.05), radius=0.05)
    solver = solver_for(layers, 1e-3, gravity=tuple(G), colliders=[ball])
    e = energies(solver, layers, tuple(G), 120)
    mass = sum(b.masses.sum() for b in layers)
    scale = mass * 9.81 * 0.03  # the release of a 3 cm fall, about the drop's
    assert_energy_never_rises(e, scale)


@pytest.mark.parametrize("self_contact", [False, True])
def test_energy_never_rises_when_a_shell_hits_a_sheet_at_15_m_s(self_contact):
    # A closed shell (radius 4 cm) shot at 15 m/s, 15 mm per step, at a sheet pinned along its
    # border, zero gravity: the mechanical energy never rises above the shell's kinetic energy
    # (plus the bound), through the impact and the rebound.
    v, t = icosphere(subdiv=1, radius=0.04)
    shell = peridyn.Membrane(v + np.array([0.0, 0.0, 0.045]), t, thickness=1e-3, density=200.0,
                             material=peridyn.StretchA3(s0=2e4), bending=1e-4,
                             self_contact=self_contact)
    shell.velocities = np.tile([0.0, 0.0, -15.0], (shell.num_vertices, 1))
    sheet = cloth(9, 0.3, 0.0, 1e-3, s0=2e3)
    sheet.self_contact = self_contact
    edge = np.flatnonzero(np.isclose(np.abs(sheet.rest_positions[:, :2]).max(axis=1), 0.15))
    sheet.pin(edge)
    bodies = [shell, sheet]
    solver = solver_for(bodies, 1e-3)
    e = energies(solver, bodies, (0, 0, 0), 30)
    # The sheet stopped the shell (and threw it back), and was pushed down by it.
    assert shell.velocities[:, 2].mean() > -1.0
    assert sheet.positions[:, 2].min() < -3e-3
    assert_energy_never_rises(e, e[0])
