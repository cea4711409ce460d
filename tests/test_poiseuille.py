"""Plane Poiseuille flow of a liquid (issue 40; DESIGN.md section 7): a body force drives a
liquid between two walls of pinned particles; at steady state its velocity profile is the
parabola ``u(z) = g (b^2 - z^2) / (2 nu)`` of the kinematic viscosity ``nu`` the material
states (``viscosity / density``)."""

import numpy as np

import peridyn as pd

S = 0.01  # lattice spacing (m)
RHO = 1000.0  # kg/m^3


def lattice(lo, hi):
    """Cell centres ``(k + 0.5) S`` of the integer box ``lo <= k < hi`` (per axis)."""
    axes = [np.arange(a, b) for a, b in zip(lo, hi)]
    return (np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + 0.5) * S


def test_plane_poiseuille_flow_matches_its_parabola():
    """A liquid 2n = 10 layers deep, 20 spacings long and 8 wide between two walls (three
    layers of pinned particles each, longer than the liquid), driven along x by g = 0.1 m/s^2,
    viscosity 10 Pa s (nu = 0.01 m^2/s): after 1.5 s (15 times the slowest mode's decay time
    (2 b / pi)^2 / nu) the mean velocity of each layer in the middle third of the length and
    the middle two rows of the width matches the parabola within 10 % of its peak, and the
    peak within 10 %. The walls' velocity is zero at their first layer's centres (the
    discrete Laplacian's Dirichlet nodes), so b = (n + 1/2) S. The y faces are frictionless
    planes: the liquid there misses neighbours across them, so its two outer rows each side
    flow a little faster and drag the middle rows (measured below 5 %); the ends are free, so
    the pressure gradient along x is zero in the middle. Tolerance 10 %: that drag plus the
    discrete Laplacian on the flowing (no longer exactly cubic) lattice."""
    n, length, width, layers, extra = 5, 20, 8, 3, 4
    g, mu = 0.1, 10.0
    x = lattice((-extra, 0, -layers), (length + extra, width, 2 * n + layers))
    k = np.floor(x / S + 1e-9).astype(int)
    wall = (k[:, 2] < 0) | (k[:, 2] >= 2 * n)
    keep = wall | ((k[:, 0] >= 0) & (k[:, 0] < length))
    x, wall = x[keep], wall[keep]
    body = pd.Particles(x, spacing=S, density=RHO, material=pd.ViscoelasticFluid(viscosity=mu))
    body.pin(np.flatnonzero(wall))
    solver = pd.Solver(dt=0.01, gravity=(g, 0, 0), global_solver="jacobi")
    solver.add(body)
    solver.add_collider(pd.Plane(point=(0, 0, 0), normal=(0, 1, 0)))
    solver.add_collider(pd.Plane(point=(0, width * S, 0), normal=(0, -1, 0)))
    for _ in range(150):
        solver.step()
    liquid = np.flatnonzero(~wall)
    p, v = body.positions[liquid], body.velocities[liquid]
    row = np.floor(p[:, 1] / S).astype(int)
    middle = (p[:, 0] > length / 3 * S) & (p[:, 0] < 2 * length / 3 * S)
    middle &= (row == width // 2 - 1) | (row == width // 2)
    layer = np.floor(p[:, 2] / S).astype(int)
    nu, b = mu / RHO, (n + 0.5) * S
    u = np.array([v[middle & (layer == j), 0].mean() for j in range(2 * n)])
    z = np.array([p[middle & (layer == j), 2].mean() for j in range(2 * n)]) - n * S
    exact = g * (b * b - z * z) / (2 * nu)
    peak = g * b * b / (2 * nu)
    assert np.abs(u - exact).max() < 0.1 * peak, (u / peak, exact / peak)
    assert abs(u.max() / exact.max() - 1.0) < 0.1, (u.max(), exact.max())
    assert np.abs(v[:, 1:]).max() < 0.05 * peak
