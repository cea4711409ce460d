"""Coulomb friction between membranes (issue 41, item 6): `Membrane(..., friction=mu)`, combined
per pair by the geometric mean, static and kinetic in the contact local step.

A 7 x 7 sheet (0.15 m) lies on a pinned 11 x 11 sheet (0.3 m), both turned to a slope of 10
degrees (tan = 0.176): with mu = 0.5 the upper sheet stays, with mu = 0.1 it slides as a block on
an incline would, `s_n = a h^2 n (n + 1) / 2` after `n` implicit Euler steps of `h`, with
`a = g (sin - mu cos)`.
"""

import numpy as np
import pytest

import peridyn
from conftest import G, make_grid, turned

ANGLE = np.radians(10.0)
DT = 2e-3
XI = 1e-3


def incline(mu, *, lower_mu=None):
    """The two sheets on the slope, the upper one at the gap it rests at (`xi + d_hat`, the
    barrier's reach) above the lower; returns the solver, the upper sheet and the downhill
    direction."""
    turn = turned(ANGLE, (0.0, 1.0, 0.0))  # x -> downhill (cos, 0, -sin); z -> the normal
    normal, downhill = turn[:, 2], turn[:, 0]
    lower_mu = mu if lower_mu is None else lower_mu

    def sheet(n, size, lift, friction):
        v, t = make_grid(n, n, size, size)
        v = (v - np.array([size / 2, size / 2, 0.0])) @ turn.T + lift * normal
        return peridyn.Membrane(v, t, thickness=XI, density=200.0,
                                material=peridyn.StretchA3(s0=2e4), bending=1e-3,
                                friction=friction)

    contact = peridyn.Contact(thickness=XI)
    lower = sheet(11, 0.3, 0.0, lower_mu)
    lower.pin(np.arange(lower.num_vertices))
    upper = sheet(7, 0.15, XI + contact.d_hat, mu)
    solver = peridyn.Solver(dt=DT, tol=1e-8, max_iters=200, gravity=(0.0, 0.0, -G),
                            contact=contact)
    solver.add(lower)
    solver.add(upper)
    return solver, upper, downhill


def slide(solver, upper, downhill, steps):
    x0 = upper.positions.copy()
    for _ in range(steps):
        solver.step()
    return float(((upper.positions - x0) @ downhill).mean())


def test_static_friction_holds_a_sheet_on_a_sheet():
    # tan 10 deg = 0.18 < 0.5: held. Frictionless it would slide 0.31 m in these 300 steps.
    solver, upper, downhill = incline(0.5)
    assert abs(slide(solver, upper, downhill, 300)) < 5e-4


def test_kinetic_friction_slides_a_sheet_as_a_block_on_an_incline():
    steps = 150
    solver, upper, downhill = incline(0.1)
    a = G * (np.sin(ANGLE) - 0.1 * np.cos(ANGLE))
    expected = a * DT**2 * steps * (steps + 1) / 2  # 33 mm
    assert slide(solver, upper, downhill, steps) == pytest.approx(expected, rel=0.05)


def test_a_frictionless_sheet_under_a_rough_one_lets_it_slide():
    # The geometric mean of 0.5 and 0: no friction, the block's free slide g sin h^2 n (n+1)/2.
    steps = 50
    solver, upper, downhill = incline(0.5, lower_mu=0.0)
    expected = G * np.sin(ANGLE) * DT**2 * steps * (steps + 1) / 2
    assert slide(solver, upper, downhill, steps) == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("bad", [-0.1, float("nan"), float("inf")])
def test_a_bad_friction_coefficient_is_refused_naming_it(bad):
    v, t = make_grid(3, 3, 0.1, 0.1)
    with pytest.raises(ValueError, match="friction"):
        peridyn.Membrane(v, t, thickness=XI, density=200.0, material=peridyn.StretchA3(s0=2e4),
                         friction=bad)
    sheet = peridyn.Membrane(v, t, thickness=XI, density=200.0,
                             material=peridyn.StretchA3(s0=2e4))
    assert sheet.friction == 0.0
    with pytest.raises(ValueError, match="friction"):
        sheet.friction = bad
