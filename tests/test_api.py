"""Contract of the Python API (the stubs python/peridyn/_core/*.pyi and the peridyn package)."""

import numpy as np
import pytest

import peridyn
from conftest import (a3_energy, a3_stress, has_number, k_ring, make_grid, membrane, nh_energy,
                      nh_stress, one_ring, triangle_areas)


# ------------------------------------------------------------------------------------------------
# grid


def test_grid_layout_and_orientation():
    """grid(nx, ny, size=(a, b)): vertex j*nx+i at (a i/(nx-1), b j/(ny-1), 0), 2(nx-1)(ny-1)
    triangles, all counter-clockwise seen from +z, covering area a*b (1e-12)."""
    nx, ny, a, b = 5, 4, 2.0, 1.5
    v, t = peridyn.grid(nx, ny, size=(a, b))
    v, t = np.asarray(v), np.asarray(t)
    assert v.shape == (nx * ny, 3) and t.shape == (2 * (nx - 1) * (ny - 1), 3)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny))
    np.testing.assert_allclose(v[:, 0], (a * i / (nx - 1)).ravel(), atol=1e-12)
    np.testing.assert_allclose(v[:, 1], (b * j / (ny - 1)).ravel(), atol=1e-12)
    assert np.all(v[:, 2] == 0)
    e1 = v[t[:, 1]] - v[t[:, 0]]
    e2 = v[t[:, 2]] - v[t[:, 0]]
    cz = np.cross(e1, e2)[:, 2]
    assert np.all(cz > 0)
    assert 0.5 * cz.sum() == pytest.approx(a * b, rel=1e-12)
    # usable as is
    m = peridyn.Membrane(v, t, thickness=1e-3, density=100.0, material=peridyn.StretchA3(s0=1e3))
    assert m.num_vertices == nx * ny


# ------------------------------------------------------------------------------------------------
# constructors and dtypes


@pytest.mark.parametrize("fdt", [np.float32, np.float64])
@pytest.mark.parametrize("idt", [np.int8, np.uint8, np.int16, np.uint16, np.int32, np.uint32,
                                 np.int64, np.uint64])
def test_membrane_accepts_any_float_and_integer_dtypes(grid44, fdt, idt):
    v, t = grid44
    m = peridyn.Membrane(v.astype(fdt), t.astype(idt), thickness=1e-3, density=100.0,
                         material=peridyn.StretchA3(s0=1e3))
    assert m.num_vertices == 16 and m.num_triangles == 18
    assert m.rest_positions.dtype == np.float64
    assert m.triangles.dtype == np.int64
    np.testing.assert_array_equal(m.triangles, t)
    np.testing.assert_array_equal(m.rest_positions, v.astype(fdt).astype(np.float64))
    np.testing.assert_array_equal(m.positions, m.rest_positions)
    np.testing.assert_array_equal(m.velocities, np.zeros((16, 3)))


def test_membrane_accepts_lists(grid44):
    v, t = grid44
    m = peridyn.Membrane(v.tolist(), t.tolist(), thickness=1e-3, density=100.0,
                         material=peridyn.StretchA3(s0=1e3))
    np.testing.assert_array_equal(m.triangles, t)


def test_keyword_only_arguments(grid44):
    v, t = grid44
    mat = peridyn.StretchA3(s0=1e3)
    with pytest.raises(TypeError):
        peridyn.Membrane(v, t, 1e-3, 100.0, mat)
    with pytest.raises(TypeError):
        peridyn.StretchA3(1e3)
    with pytest.raises(TypeError):
        peridyn.NeoHookean(1e3, 2e3)
    with pytest.raises(TypeError):
        peridyn.Solver(1e-3)
    with pytest.raises(TypeError):
        peridyn.Sphere((0, 0, 0), 1.0)
    with pytest.raises(TypeError):
        peridyn.Plane((0, 0, 0), (0, 0, 1))


def test_defaults(grid44):
    v, t = grid44
    m = peridyn.Membrane(v, t, thickness=1e-3, density=100.0, material=peridyn.StretchA3(s0=1e3))
    assert m.bending == 0.0
    assert m.hourglass >= 0.0
    assert m.neighbors == 1
    s = peridyn.Solver(dt=1e-3)
    np.testing.assert_array_equal(s.gravity, [0.0, 0.0, -9.81])
    assert s.tol == 1e-4 and s.max_iters == 100
    assert s.threads >= 1
    p = peridyn.Plane()
    np.testing.assert_array_equal(p.point, [0, 0, 0])
    np.testing.assert_array_equal(p.normal, [0, 0, 1])


# ------------------------------------------------------------------------------------------------
# repr


def test_reprs_are_informative(grid44):
    v, t = grid44
    a3 = peridyn.StretchA3(s0=1234.5)
    r = repr(a3)
    assert "StretchA3" in r and has_number(r, 1234.5)
    nh = peridyn.NeoHookean(s0=321.25, s1=777.5)
    r = repr(nh)
    assert "NeoHookean" in r and has_number(r, 321.25) and has_number(r, 777.5)
    m = peridyn.Membrane(v, t, thickness=0.0025, density=123.0, material=a3, bending=0.0625)
    r = repr(m)
    assert "Membrane" in r and has_number(r, 16) and has_number(r, 0.0025)
    pl = peridyn.Plane(point=(0.0, 0.0, 0.75), normal=(0.0, 0.0, 1.0))
    r = repr(pl)
    assert "Plane" in r and has_number(r, 0.75)
    sp = peridyn.Sphere(center=(0.0, 0.0, 0.0), radius=0.375)
    r = repr(sp)
    assert "Sphere" in r and has_number(r, 0.375)
    s = peridyn.Solver(dt=0.0125, max_iters=37, particle_tol=0.375, max_speed=2.5e3,
                       two_level=False)
    r = repr(s)
    assert "Solver" in r and has_number(r, 0.0125) and has_number(r, 37)
    assert "particle_tol=0.375" in r and "max_speed=2500" in r and "two_level=False" in r
    s.add(m)
    st = s.step()
    r = repr(st)
    assert "StepStats" in r and has_number(r, st.iterations)


# ------------------------------------------------------------------------------------------------
# properties


def test_membrane_properties_round_trip(grid44, rng):
    v, t = grid44
    mat = peridyn.NeoHookean(s0=100.0, s1=200.0)
    m = peridyn.Membrane(v, t, thickness=2e-3, density=300.0, material=mat, bending=0.01,
                         hourglass=0.7, neighbors=2)
    assert m.thickness == 2e-3 and m.density == 300.0
    assert m.bending == 0.01 and m.hourglass == 0.7 and m.neighbors == 2
    assert isinstance(m.material, peridyn.NeoHookean)
    assert m.material.s0 == 100.0 and m.material.s1 == 200.0
    y = v + 0.01 * rng.normal(size=v.shape)
    m.positions = y
    np.testing.assert_array_equal(m.positions, y)
    vel = rng.normal(size=v.shape)
    m.velocities = vel.astype(np.float32)
    np.testing.assert_array_equal(m.velocities, vel.astype(np.float32).astype(np.float64))
    # rest positions are not changed by setting positions
    np.testing.assert_array_equal(m.rest_positions, v)
    # returned arrays are copies
    p = m.positions
    p[:] = 99.0
    np.testing.assert_array_equal(m.positions, y)
    masses = m.masses
    masses[:] = -1
    assert np.all(m.masses > 0)
    # kinetic energy = 1/2 sum m v^2 (1e-12)
    ke = 0.5 * np.sum(m.masses[:, None] * m.velocities**2)
    assert m.kinetic_energy() == pytest.approx(ke, rel=1e-12)
    # energy terms sum to the elastic energy (1e-12)
    terms = m.energy_terms()
    assert set(terms) == {"stretch", "bending", "hourglass"}
    assert sum(terms.values()) == pytest.approx(m.elastic_energy(), rel=1e-12)


def test_pin_unpin_and_targets(grid44):
    v, t = grid44
    m = membrane(v, t)
    assert m.pinned.shape == (0,) and m.pin_targets.shape == (0, 3)
    m.pin([5, 2, 9])
    np.testing.assert_array_equal(m.pinned, [2, 5, 9])
    assert m.pinned.dtype == np.int64
    np.testing.assert_array_equal(m.pin_targets, v[[2, 5, 9]])  # default: where they are now
    tg = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]])
    m.pin([12, 3], tg)
    np.testing.assert_array_equal(m.pinned, [2, 3, 5, 9, 12])
    np.testing.assert_array_equal(m.pin_targets[m.pinned == 12][0], tg[0])
    np.testing.assert_array_equal(m.pin_targets[m.pinned == 3][0], tg[1])
    new = m.pin_targets + 0.5
    m.pin_targets = new
    np.testing.assert_array_equal(m.pin_targets, new)
    m.unpin([5, 12])
    np.testing.assert_array_equal(m.pinned, [2, 3, 9])
    m.unpin()
    assert m.pinned.shape == (0,)


def test_masses_and_volumes(rng):
    """Lumped masses: density * thickness * (1/3 of incident triangle areas), per vertex (1e-12);
    they sum to density * thickness * total area; volumes = masses / density."""
    v, t = make_grid(5, 4, 1.3, 0.7)
    v[:, :2] += 0.03 * rng.normal(size=(len(v), 2))  # irregular triangles
    v[:, 2] = 0.1 * rng.normal(size=len(v))
    m = membrane(v, t, thickness=3e-3, density=450.0)
    areas = triangle_areas(v, t)
    lumped = np.zeros(len(v))
    for k in range(3):
        np.add.at(lumped, t[:, k], areas / 3)
    np.testing.assert_allclose(m.masses, 450.0 * 3e-3 * lumped, rtol=1e-12)
    assert m.masses.sum() == pytest.approx(450.0 * 3e-3 * areas.sum(), rel=1e-12)
    np.testing.assert_allclose(m.volumes, 3e-3 * lumped, rtol=1e-12)


@pytest.mark.parametrize("k", [1, 2])
def test_neighborhood_is_symmetric_k_ring(k):
    v, t = make_grid(6, 5, 1.0, 1.0)
    m = membrane(v, t, neighbors=k)
    off, idx = m.neighborhood()
    assert off.dtype == np.int64 and idx.dtype == np.int64
    assert off.shape == (len(v) + 1,) and off[0] == 0 and off[-1] == len(idx)
    assert np.all(np.diff(off) > 0)
    sets = [set(idx[off[i]:off[i + 1]].tolist()) for i in range(len(v))]
    # no duplicates, no self
    assert all(len(s) == off[i + 1] - off[i] for i, s in enumerate(sets))
    assert all(i not in s for i, s in enumerate(sets))
    assert all(i in sets[j] for i, s in enumerate(sets) for j in s)  # symmetric
    expected = one_ring(len(v), t) if k == 1 else k_ring(len(v), t, 2)
    assert sets == expected


# ------------------------------------------------------------------------------------------------
# materials


def test_stretch_a3_from_young_and_moduli():
    m = peridyn.StretchA3.from_young(3e5)
    assert m.s0 == pytest.approx(1.5e5, rel=1e-15)
    m = peridyn.StretchA3.from_young(3e5, 0.0)
    assert m.s0 == pytest.approx(1.5e5, rel=1e-15)
    assert m.youngs_modulus == pytest.approx(3e5, rel=1e-15)
    assert m.shear_modulus == pytest.approx(1.5e5, rel=1e-15)
    assert m.poisson_ratio == 0.0
    with pytest.raises(ValueError):
        peridyn.StretchA3.from_young(3e5, 0.3)


def test_neohookean_from_young_and_moduli():
    """s0 = E/(4(1+nu)), s1 = E nu/(2(1-nu^2)); plane-strain Lame mu = 2 s0, lambda = 2 s1 give
    back the plane-stress E = 4 mu (mu + lambda)/(2 mu + lambda), nu = lambda/(2 mu + lambda)."""
    E, nu = 2e6, 0.35
    m = peridyn.NeoHookean.from_young(E, nu)
    assert m.s0 == pytest.approx(E / (4 * (1 + nu)), rel=1e-14)
    assert m.s1 == pytest.approx(E * nu / (2 * (1 - nu**2)), rel=1e-14)
    assert m.youngs_modulus == pytest.approx(E, rel=1e-12)
    assert m.poisson_ratio == pytest.approx(nu, rel=1e-12)
    assert m.shear_modulus == pytest.approx(2 * m.s0, rel=1e-14)
    m = peridyn.NeoHookean(s0=100.0, s1=0.0)
    assert m.poisson_ratio == 0.0
    assert m.youngs_modulus == pytest.approx(400.0, rel=1e-14)


@pytest.mark.parametrize("which", ["a3", "nh"])
def test_material_stress_and_energy_formulas(rng, which):
    """stress() and energy_density() match the formulas (1e-12) for stretches of shape (..., 3),
    and the stress is the derivative of the energy density (central differences, 1e-7)."""
    if which == "a3":
        mat = peridyn.StretchA3(s0=1.7e3)
        E_ = lambda l: a3_energy(l, 1.7e3)  # noqa: E731
        P_ = lambda l: a3_stress(l, 1.7e3)  # noqa: E731
    else:
        mat = peridyn.NeoHookean(s0=1.1e3, s1=2.3e3)
        E_ = lambda l: nh_energy(l, 1.1e3, 2.3e3)  # noqa: E731
        P_ = lambda l: nh_stress(l, 1.1e3, 2.3e3)  # noqa: E731
    l = rng.uniform(0.6, 1.6, size=(4, 5, 3))
    P = mat.stress(l)
    W = mat.energy_density(l)
    assert P.shape == (4, 5, 3) and W.shape == (4, 5)
    np.testing.assert_allclose(P, P_(l), rtol=1e-12, atol=1e-12 * 1e3)
    np.testing.assert_allclose(W, E_(l), rtol=1e-12, atol=1e-12 * 1e3)
    assert mat.energy_density([1.0, 1.0, 1.0]) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(mat.stress([1.0, 1.0, 1.0]), 0.0, atol=1e-12)
    h = 1e-6
    for k in range(3):
        d = np.zeros(3)
        d[k] = h
        fd = (mat.energy_density(l + d) - mat.energy_density(l - d)) / (2 * h)
        np.testing.assert_allclose(fd, P[..., k], rtol=1e-7, atol=1e-7 * np.abs(P).max())


# ------------------------------------------------------------------------------------------------
# colliders


def test_collider_signed_distance(rng):
    n = np.array([1.0, 2.0, 2.0])
    pl = peridyn.Plane(point=(0.1, 0.2, 0.3), normal=n)
    np.testing.assert_allclose(np.linalg.norm(pl.normal), 1.0, rtol=1e-15)  # normalised
    np.testing.assert_allclose(pl.normal, n / 3.0, rtol=1e-15)
    p = rng.normal(size=(7, 3))
    np.testing.assert_allclose(pl.signed_distance(p), (p - [0.1, 0.2, 0.3]) @ (n / 3), atol=1e-14)
    sp = peridyn.Sphere(center=(1.0, -1.0, 0.5), radius=0.4)
    np.testing.assert_array_equal(sp.center, [1.0, -1.0, 0.5])
    assert sp.radius == 0.4
    np.testing.assert_allclose(sp.signed_distance(p),
                               np.linalg.norm(p - [1.0, -1.0, 0.5], axis=1) - 0.4, atol=1e-14)


# ------------------------------------------------------------------------------------------------
# solver


def test_solver_properties_and_step_stats(grid44):
    v, t = grid44
    m = membrane(v, t)
    m.pin([0])
    s = peridyn.Solver(dt=0.01, gravity=(0.0, -1.0, -2.0), tol=1e-7, max_iters=42, threads=1)
    assert s.dt == 0.01 and s.tol == 1e-7 and s.max_iters == 42 and s.threads == 1
    np.testing.assert_array_equal(s.gravity, [0.0, -1.0, -2.0])
    s.add(m)
    pl = peridyn.Plane(point=(0, 0, -5))
    s.add_collider(pl)
    assert len(s.bodies) == 1 and len(s.colliders) == 1
    assert s.time == 0.0 and s.steps_taken == 0
    for k in range(3):
        st = s.step()
        assert st.step == k
        assert st.time == pytest.approx((k + 1) * 0.01, rel=1e-12)
        assert 1 <= st.iterations <= 42
        assert st.iterations == len(st.moves)
        assert st.last_move == st.moves[-1]
        assert st.converged == (st.residual < 1e-7)
        # The measure after each iteration: the step stopped at the first one below tol.
        assert len(st.residuals) == st.iterations
        assert st.residuals[-1] == st.residual
        assert np.all(st.residuals[:-1] >= 1e-7)
        assert {"predict", "global", "colliders", "finish", "total"} <= set(st.timings)
        assert all(val >= 0 for val in st.timings.values())
    assert s.steps_taken == 3 and s.time == pytest.approx(0.03, rel=1e-12)
    s.dt = 0.02
    assert s.dt == 0.02
    s.step()
    assert s.time == pytest.approx(0.05, rel=1e-12)


def test_solver_tolerances_and_iteration_cap_are_settable_between_steps(grid44):
    """tol, particle_tol and max_iters trade speed for accuracy between steps: a cap of one
    iteration stops the next step after one, a looser tol stops it earlier than a tight one,
    and bad values are refused by name, leaving the old value."""
    v, t = grid44
    s = peridyn.Solver(dt=0.01, tol=1e-9)
    m = membrane(v, t)
    m.pin([0, 3])  # hangs from two corners, so a step takes iterations
    s.add(m)
    tight = s.step()
    assert tight.iterations > 1
    s.max_iters = 1
    assert s.max_iters == 1 and s.step().iterations == 1
    s.max_iters = 100
    s.tol = 1e-4
    assert s.tol == 1e-4
    loose = s.step()
    assert loose.converged and loose.iterations < tight.iterations
    s.particle_tol = 0.5
    assert s.particle_tol == 0.5
    for name, bad in [("max_iters", 0), ("max_iters", -1), ("tol", -1.0), ("tol", float("nan")),
                      ("particle_tol", 0.0)]:
        before = getattr(s, name)
        with pytest.raises(ValueError, match=name):
            setattr(s, name, bad)
        assert getattr(s, name) == before


def test_solver_run_and_callback(grid44):
    """run(steps) takes the steps, calls callback(solver, stats) after each; returning False stops
    the run after that step."""
    v, t = grid44
    m = membrane(v, t)
    s = peridyn.Solver(dt=0.01)
    s.add(m)
    calls = []
    summary = s.run(4, progress=False, callback=lambda sol, st: calls.append((sol, st)))
    assert s.steps_taken == 4 and len(calls) == 4
    assert all(sol is s for sol, _ in calls)
    assert [st.step for _, st in calls] == [0, 1, 2, 3]
    assert summary.steps == 4
    s.run(2)
    assert s.steps_taken == 6
    summary = s.run(5, callback=lambda sol, st: False)
    assert s.steps_taken == 7 and summary.steps == 1


def test_positions_setter_takes_effect(grid44):
    """Setting positions/velocities is what the next step starts from: free fall from a given
    state is y1 = y + h v + h^2 g (no forces: translated rest shape), 1e-12."""
    v, t = grid44
    m = membrane(v, t)
    s = peridyn.Solver(dt=0.01, gravity=(0, 0, -10.0), tol=1e-10)
    s.add(m)
    y = v + [1.0, 2.0, 3.0]
    vel = np.tile([0.5, 0.0, 1.0], (16, 1))
    m.positions = y
    m.velocities = vel
    s.step()
    np.testing.assert_allclose(m.positions, y + 0.01 * vel + 1e-4 * np.array([0, 0, -10.0]),
                               rtol=0, atol=1e-12)
