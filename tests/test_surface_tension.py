"""A liquid's surface tension (``ViscoelasticFluid(surface_tension=sigma)``, N/m; issue 40,
round x): the cohesion force of Akinci, Akinci and Teschner 2013 between the liquid's
particles, calibrated on the rest lattice. A cube of liquid without gravity rounds towards a
ball with its momentum kept; the l = 2 oscillation of a drop against Rayleigh's frequency (a
strict xfail: the frequency measured does not follow sqrt(sigma)); the parameter is reported,
saved and refused when bad."""

import numpy as np
import pytest

import peridyn as pd

S = 0.01  # lattice spacing (m)
RHO = 1000.0  # kg/m^3


def centred_lattice(keep):
    """Lattice points ``k S`` (k integer, |k| <= 5 per axis) with ``keep(k)``."""
    k = np.arange(-5, 6)
    p = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3).astype(float)
    return p[keep(p)] * S


def free_drop(x, sigma, dt=0.005, velocities=None, threads=None, precision=None):
    body = pd.Particles(x, spacing=S, density=RHO,
                        material=pd.ViscoelasticFluid(viscosity=1e-3, surface_tension=sigma))
    if velocities is not None:
        body.velocities = velocities
    solver = pd.Solver(dt=dt, gravity=(0, 0, 0), global_solver="jacobi", threads=threads,
                       precision=precision)
    solver.add(body)
    return body, solver


def corner_over_face(y, corners, faces):
    """Mean distance of the corner particles from the centroid over the face centres'."""
    c = y - y.mean(0)
    r = np.linalg.norm(c, axis=1)
    return r[corners].mean() / r[faces].mean()


def test_a_cube_of_liquid_rounds_towards_a_ball_and_keeps_its_momentum():
    """A 5 x 5 x 5 cube of water (no gravity, 0.25 N/m, dt = 5 ms): its corners' distance
    from the centroid over its face centres' leaves sqrt 3 (1.73, the cube) for about 1 (a
    ball): within 0.15 of 1 after 0.4 s (measured 0.94; 1.06 at 0.1 s and 1.26 at 0.2 s: it
    swings about the ball, little damped at water's viscosity); without surface tension it
    stays a cube (measured 1.732: nothing moves). The pair forces are equal and opposite and
    the density projection and viscosity conserve momentum: the total momentum stays below
    1e-9 of the largest sum of the particles' momenta' magnitudes over the run (measured
    1.4e-11 of it; a ball of 389 started with the l = 2 flow: 1.3e-15)."""
    x = centred_lattice(lambda p: (np.abs(p) <= 2).all(1))
    k = np.rint(x / S).astype(int)
    corners = np.flatnonzero((np.abs(k) == 2).all(1))
    faces = np.flatnonzero((np.abs(k).sum(1) == 2) & (np.abs(k).max(1) == 2))
    assert len(corners) == 8 and len(faces) == 6
    ratios = {}
    for sigma in (0.0, 0.25):
        body, solver = free_drop(x, sigma)
        total, scale = 0.0, 0.0
        for _ in range(80):
            solver.step()
            v = body.velocities
            total = max(total, np.abs(v.sum(0)).max())
            scale = max(scale, np.linalg.norm(v, axis=1).sum())
        ratios[sigma] = corner_over_face(body.positions, corners, faces)
        assert total <= 1e-9 * scale, (sigma, total, scale)
    assert abs(ratios[0.25] - 1.0) < 0.15, ratios
    assert ratios[0.0] > 1.7, ratios


def test_threads_are_bit_identical_and_f32_follows_f64():
    """The rounding cube (0.25 N/m, 40 steps): 1 and 2 threads give the same bits (the pair
    sums run in neighbour order per particle). f32 rounds it as f64 does: its corners' over
    its face centres' distance within 0.05 of f64's (measured 1.275 against 1.262) and every
    particle within a spacing (measured 0.61; 0.0008 after 10 steps, 0.007 after 20: f64
    keeps the cube's symmetry to its round-off, f32's round-off breaks it sooner, and the
    swinging flow amplifies the difference)."""
    x = centred_lattice(lambda p: (np.abs(p) <= 2).all(1))
    runs = {}
    for key, threads, precision in [("one", 1, "f64"), ("two", 2, "f64"), ("f32", 2, "f32")]:
        body, solver = free_drop(x, 0.25, threads=threads, precision=precision)
        for _ in range(40):
            solver.step()
        runs[key] = (body.positions.copy(), body.velocities.copy())
    assert np.array_equal(runs["one"][0], runs["two"][0])
    assert np.array_equal(runs["one"][1], runs["two"][1])
    assert np.abs(runs["f32"][0] - runs["one"][0]).max() < S
    k = np.rint(x / S).astype(int)
    corners = np.flatnonzero((np.abs(k) == 2).all(1))
    faces = np.flatnonzero((np.abs(k).sum(1) == 2) & (np.abs(k).max(1) == 2))
    ratio = {key: corner_over_face(run[0], corners, faces) for key, run in runs.items()}
    assert abs(ratio["f32"] - ratio["one"]) < 0.05, ratio


def l2_frequency(sigma, dt=0.005, duration=2.5):
    """The angular frequency (rad/s) of the l = 2 oscillation of a drop of 389 particles
    (radius 4.5 spacings; volume radius R = 0.0453 m) started at its rest shape with the
    mode's potential flow ``v = a (-x, -y, 2 z)``, ``a`` 0.3 of Rayleigh's frequency: pi
    over the first time the quadrupole moment ``<z^2> - (<x^2> + <y^2>) / 2`` returns to its
    start, and Rayleigh's frequency ``sqrt(8 sigma / (rho R^3))`` (1879)."""
    x = centred_lattice(lambda p: np.linalg.norm(p, axis=1) <= 4.5)
    radius = (3 * len(x) / (4 * np.pi)) ** (1 / 3) * S
    omega = np.sqrt(8 * sigma / (RHO * radius**3))
    v = np.stack([-x[:, 0], -x[:, 1], 2 * x[:, 2]], 1) * 0.3 * omega
    body, solver = free_drop(x, sigma, dt, v)

    def moment():
        c = body.positions - body.positions.mean(0)
        return (c[:, 2] ** 2).mean() - 0.5 * ((c[:, 0] ** 2).mean() + (c[:, 1] ** 2).mean())

    q0, previous = moment(), 0.0
    for step in range(1, int(round(duration / dt)) + 1):
        solver.step()
        q = moment() - q0
        if step > 1 and previous > 0.0 >= q:
            return np.pi / ((step - 1 + previous / (previous - q)) * dt), omega
        previous = q
    return 0.0, omega


@pytest.mark.xfail(strict=True, raises=AssertionError, reason="open (issue 40, round x): "
                   "the drop's l = 2 frequency does not follow sqrt(sigma): 2.78, 4.11 and "
                   "2.04 rad/s at 0.1, 0.25 and 0.5 N/m against Rayleigh's 2.94, 4.64 and "
                   "6.56; at 0.05 N/m the moment does not return within 4 s. Nor does the "
                   "drop's Young-Laplace pressure read sigma (round y2): its interior's "
                   "Particles.pressure is 9-10 times 2 sigma / R, the cohesion's own bulk "
                   "(virial) pressure nearly cancelling it, their sum -0.6, -14 and -5 Pa "
                   "against 4.4, 11 and 22 Pa at 0.1, 0.25, 0.5 N/m (docs/particles/fluids.md)")
def test_a_drop_oscillates_at_rayleighs_frequency():
    """The l = 2 mode of a free drop oscillates at ``omega^2 = 8 sigma / (rho R^3)`` (Rayleigh
    1879) within 15 % at 0.1 and 0.5 N/m (so its frequency scales as sqrt(sigma)): 15 % for a
    drop 4.5 spacings in radius, whose lattice surface and volume radius differ by a few per
    cent, and water's viscous damping shifts the frequency by less than 1e-4."""
    for sigma, dt in ((0.1, 0.005), (0.5, 0.0025)):
        measured, rayleigh = l2_frequency(sigma, dt)
        assert abs(measured / rayleigh - 1.0) < 0.15, (sigma, measured, rayleigh)


def test_surface_tension_is_reported_saved_and_checked():
    water = pd.ViscoelasticFluid(surface_tension=0.072)
    assert water.surface_tension == 0.072 and "surface_tension=0.072" in repr(water)
    assert pd.ViscoelasticFluid().surface_tension == 0.0
    for bad in (-0.1, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="surface_tension"):
            pd.ViscoelasticFluid(surface_tension=bad)
    x = centred_lattice(lambda p: (np.abs(p) <= 1).all(1))
    body = pd.Particles(x, spacing=S, density=RHO, material=water)
    state = body.material_state
    other = pd.Particles(x, spacing=S, density=RHO, material=pd.ViscoelasticFluid())
    other.material_state = state
    assert other.material.surface_tension == 0.072
    assert other.material_state["fluid"][11] == 0.072
    older = dict(state, fluid=state["fluid"][:11])  # a state written before the tension
    other.material_state = older
    assert other.material.surface_tension == 0.0
