"""Solver(method="newton") from Python: the method switch, and the same implicit Euler steps as
SISSM on the validation scenes (docs/model.md; the Rust tests in
src/solve/membranes/newton_tests.rs check the Hessian model, colliders, contact, threads and
f32)."""

import numpy as np
import pytest

import peridyn
from conftest import G, make_grid, membrane


def test_bad_method_names_the_choices():
    with pytest.raises(ValueError, match=r"'sissm', 'descent', 'newton' or 'auto'.*\"quasi\""):
        peridyn.Solver(dt=1e-3, method="quasi")


def test_newton_refuses_chebyshev():
    with pytest.raises(ValueError, match=r"chebyshev.*newton"):
        peridyn.Solver(dt=1e-3, method="newton", acceleration="chebyshev")
    assert peridyn.Solver(dt=1e-3, method="newton").method == "newton"


def steps(method, scene, n_steps):
    """Positions after `n_steps` steps of a validation scene, every step converged to 1e-11 m."""
    m, sol = scene(method)
    for _ in range(n_steps):
        st = sol.step()
        assert st.converged, (method, st.iterations, st.residual)
    return m.positions


def hanging_strip(method):
    """The A3 strip of test_validation's hanging tests (3 x 11, 1 m, pinned at the top), dt 0.03 s."""
    v, t = make_grid(3, 11, 0.2, 1.0)
    m = membrane(v, t, s0=1000.0 * G * 2.0, thickness=1e-3, density=1000.0, hourglass=0.5)
    m.pin(np.where(np.isclose(v[:, 1], 1.0))[0])
    return m, solver(m, method, dt=0.03, gravity=(0.0, -G, 0.0))


def cantilever(method):
    """The clamped neo-Hookean plate of test_validation's cantilever, with bending, dt 0.02 s."""
    v, t = make_grid(9, 5, 0.5, 0.25)
    m = membrane(v, t, s0=1e5, thickness=1e-3, density=100.0, bending=1.25)
    m.pin(np.where(v[:, 0] < 1.5 * 0.5 / 8)[0])
    return m, solver(m, method, dt=2e-2, gravity=(0.0, 0.0, -G))


def solver(m, method, **kw):
    extra = dict(acceleration="chebyshev", chebyshev_rho=0.99) if method == "sissm" else {}
    sol = peridyn.Solver(tol=1e-11, max_iters=40000, method=method, **kw, **extra)
    sol.add(m)
    return sol


@pytest.mark.parametrize("scene", [hanging_strip, cantilever])
def test_newton_takes_the_same_implicit_euler_steps_as_sissm(scene):
    """Five steps, each converged to the residual measure 1e-11 m: the positions agree within
    1e-9 m (the steps move the bodies by millimetres to centimetres)."""
    a = steps("sissm", scene, 5)
    b = steps("newton", scene, 5)
    m0, _ = scene("sissm")
    assert np.abs(a - m0.positions).max() > 1e-3
    assert np.abs(a - b).max() < 1e-9


def test_linear_products_count_newtons_cg_only():
    """StepStats.linear_products: the Newton step's CG products (at least one per Newton
    iteration that moved), zero for SISSM."""
    counts = {}
    for method in ("sissm", "newton"):
        m, sol = cantilever(method)
        st = sol.step()
        assert st.converged
        counts[method] = (st.linear_products, st.iterations)
    assert counts["sissm"][0] == 0
    assert counts["newton"][0] >= counts["newton"][1] - 1 > 0


def stiff_sheet(n):
    """An n x n sheet of 0.6 m, the paper's stiff neo-Hookean at 1 mm, pinned along one edge,
    given a swing; a step of 1 ms (h^2 k / m of order 1e3 at n = 32)."""
    v, t = make_grid(n, n, 0.6, 0.6)
    m = membrane(v, t, material=peridyn.NeoHookean(s0=4.8e7, s1=1.2e7), density=300.0,
                 hourglass=0.5)
    m.pin(np.where(np.isclose(v[:, 1], 0.6))[0])
    m.velocities = np.tile([0.0, 0.3, -1.0], (n * n, 1))
    return m


def auto_step(n, tol):
    m = stiff_sheet(n)
    sol = peridyn.Solver(dt=1e-3, tol=tol, max_iters=3000, method="auto", gravity=(0, -G, 0),
                         acceleration="chebyshev", chebyshev_rho=0.99)
    sol.add(m)
    return sol.step(), m.positions


def test_auto_picks_newton_for_a_fine_stiff_sheet_and_a_tight_tol():
    """method="auto" takes Newton steps (CG products) on a stiff 32 x 32 sheet with tol 1e-8 m
    (min(h^2 k / m, N / pi^2) = 104 > 100), SISSM (none) on the same sheet with the default
    1e-4 m, and on an 8 x 8 sheet (N / pi^2 = 6.5) at any tol; each step converges, and the
    Newton step (to 1e-8 m) lands within 1e-7 m of SISSM's (to 1e-11 m)."""
    assert peridyn.Solver(dt=1e-3, method="auto").method == "auto"
    st, y_auto = auto_step(32, 1e-8)
    assert st.converged and st.linear_products > 0, (st.iterations, st.linear_products)
    m = stiff_sheet(32)
    sol = peridyn.Solver(dt=1e-3, tol=1e-11, max_iters=40000, gravity=(0, -G, 0),
                         acceleration="chebyshev", chebyshev_rho=0.99)
    sol.add(m)
    assert sol.step().converged
    assert np.abs(m.positions - y_auto).max() < 1e-7
    for n, tol in ((32, 1e-4), (8, 1e-8)):
        st, _ = auto_step(n, tol)
        assert st.converged and st.linear_products == 0, (n, tol, st.iterations)
