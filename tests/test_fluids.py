"""Liquids as particles (He et al. 2017, section 6; issue 40): position-based density
constraints (Macklin and Mueller 2013) with an implicit viscosity. A hydrostatic column keeps
its height and density, the dam-break front follows Martin and Moyce 1952, liquid stays in
its container, threads and precisions agree, bad input is refused by name."""

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

import peridyn as pd
from fluid_scenes import blob_under_a_ceiling

S = 0.01  # lattice spacing (m)
RHO = 1000.0  # kg/m^3
G = 9.81
SUPPORT = 2.2 * S  # the fluids' SPH support (peridyn's FLUID_SUPPORT spacings)


def lattice(lo, hi):
    """Cell centres ``(k + 0.5) S`` of the integer box ``lo <= k < hi`` (per axis)."""
    axes = [np.arange(a, b) for a, b in zip(lo, hi)]
    return (np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + 0.5) * S


def spiky_density(x, mass):
    """Test-side oracle: the spiky kernel's SPH density (self term included), normalised on
    the cubic lattice of spacing S as peridyn does, so an undisturbed lattice gives RHO."""
    h = SUPPORT
    w = lambda r: np.where(r < h, 15.0 / (np.pi * h**6) * (h - r) ** 3, 0.0)
    k = np.arange(-3, 4)
    p = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3) * S
    scale = 1.0 / (S**3 * w(np.linalg.norm(p, axis=1)).sum())
    pairs = cKDTree(x).sparse_distance_matrix(cKDTree(x), h, output_type="coo_matrix")
    rho = np.full(len(x), w(0.0)) * mass
    np.add.at(rho, pairs.row, mass * w(pairs.data) * (pairs.row != pairs.col))
    return scale * rho


def walls(solver, lo, hi):
    """Planes along the faces of the box [lo, hi] (m), its top open."""
    for point, normal in [
        ((0, 0, lo[2]), (0, 0, 1)),
        ((lo[0], 0, 0), (1, 0, 0)),
        ((hi[0], 0, 0), (-1, 0, 0)),
        ((0, lo[1], 0), (0, 1, 0)),
        ((0, hi[1], 0), (0, -1, 0)),
    ]:
        solver.add_collider(pd.Plane(point=point, normal=normal))


def column(n=4, height=16, layers=2, **fluid):
    """A liquid column of n x n x height particles in a container whose walls and floor are
    `layers` layers of pinned particles of the same liquid (so the walls' particles fill the
    kernel sums of the liquid beside them), with planes on the container's faces."""
    cells = lattice((-layers, -layers, -layers), (n + layers, n + layers, height))
    k = np.floor(cells / S).astype(int)
    inside = (k[:, 0] >= 0) & (k[:, 0] < n) & (k[:, 1] >= 0) & (k[:, 1] < n) & (k[:, 2] >= 0)
    body = pd.Particles(cells, spacing=S, density=RHO, material=pd.ViscoelasticFluid(**fluid))
    body.pin(np.flatnonzero(~inside))
    return body, np.flatnonzero(inside)


@pytest.mark.parametrize("density_solver, passes", [
    ("jacobi", 50),
    ("cg", 50),
    pytest.param("cg", 150, marks=pytest.mark.xfail(
        strict=True,
        reason="open: the top 1.58 % high at 0.1 s (+1.77 % at 0.11 s), within 0.7 % from "
        "0.2 s; without adhesion +1.11 %, Jacobi with 150 passes +1.12 %. Not a bounce of the "
        "column (mean speed within 7 mm/s): its top two layers overturn (the top corners sink "
        "0.67 spacing, the top centres rise 0.27, the corners below rise 0.9), the free "
        "surface holding no constraint of its own; 50 passes leave the column compressed "
        "enough to hide it (docs/particles/fluids.md, round w)")),
])
def test_a_hydrostatic_column_keeps_its_height_and_density(density_solver, passes):
    """A 4 x 4 x 16 column (0.16 m) over 2 s at dt = 0.01 s keeps its top within 1 % of its
    height and its interior's SPH density within 1 % of the rest density (mean, at every
    0.1 s) and comes to rest (|v| < 0.05 m/s at the end). Smaller than a real column (the
    test budget): the walls are two layers of ghost particles (pinned) with adhesion, so every
    particle has full kernel sums and the liquid's surface meets its walls at rest. Without
    adhesion the top particle wanders by 1-1.5 % and the top layer's mean sinks 3 % (surface
    particles, which hold no density constraint of their own, settle into the hollows of the
    layer below). With either density solver (measured, the ghosts holding their density at
    rest: Jacobi -0.36..+0.64 %, conjugate gradients -0.56..+0.75 %)."""
    n, height = 4, 16
    body, liquid = column(n, height, adhesion=True, density_solver=density_solver,
                          density_iterations=passes)
    solver = pd.Solver(dt=0.01, gravity=(0, 0, -G), global_solver="jacobi")
    solver.add(body)
    walls(solver, (0, 0, 0), (n * S, n * S, 1.0))
    top0 = (height - 0.5) * S
    tops, densities = [], []
    for k in range(200):
        stats = solver.step()
        if k % 10 == 9:
            x = body.positions
            tops.append(x[liquid, 2].max() / top0 - 1.0)
            rho = spiky_density(x, RHO * S**3)[liquid]
            interior = (x[liquid, 2] > 3 * S) & (x[liquid, 2] < (height - 3) * S)
            densities.append(rho[interior].mean() / RHO - 1.0)
    assert np.max(np.abs(tops)) < 0.01, tops
    assert np.max(np.abs(densities)) < 0.01, densities
    assert np.abs(body.velocities[liquid]).max() < 0.05
    assert stats.timings["density"] > 0.0 and stats.timings["neighbours"] > 0.0


@pytest.mark.parametrize("density_solver", ["jacobi", "cg"])
def test_a_resting_columns_pressure_is_hydrostatic(density_solver):
    """``Particles.pressure`` (Pa) of the first test's column after 1.5 s at rest: zeros
    before a step; in layers (the particles by height, 16 a layer) more than 4 spacings below the surface (depth d from the
    liquid's height H = 16 spacings, its volume over its area) the layer's mean within 10 %
    of ``rho0 g d`` (measured, 50 passes: Jacobi 0.92-1.06, conjugate gradients 0.95-1.08);
    within one layer's weight ``rho0 g S`` of it nearer the surface (two kernel supports),
    where the top layer's particles miss neighbours, hold no active constraint and rest on
    the layer below (the top layer 22 Pa against 75, the next three 0.85-1.19
    of ``rho0 g d``); rising with depth
    over pairs of layers (the kernel's 2.2 spacings: single layers near the surface may
    swap); never negative in the liquid; the bottom layer's mean times the floor's area
    within 5 % of the liquid's weight (0.99, 0.98) and ``sum p V`` within 3 % of ``W H / 2``,
    the integral of ``rho0 g d`` over the column (1.007, 1.016). Without the lattice's
    gradient factor kappa = 0.817 of peridyn's pressure the layers read 1.22 times
    ``rho0 g d`` (docs/particles/fluids.md, round y2)."""
    n, height = 4, 16
    body, liquid = column(n, height, adhesion=True, density_solver=density_solver,
                          density_iterations=50)
    assert body.pressure.shape == (body.num_particles,) and not body.pressure.any()
    solver = pd.Solver(dt=0.01, gravity=(0, 0, -G), global_solver="jacobi")
    solver.add(body)
    walls(solver, (0, 0, 0), (n * S, n * S, 1.0))
    for _ in range(150):
        solver.step()
    p, z = body.pressure[liquid], body.positions[liquid, 2]
    assert p.min() >= 0.0
    layers = np.argsort(z, kind="stable").reshape(height, n * n)  # by height, n * n each
    top = height * S
    depth = top - z[layers].mean(1)
    mean = p[layers].mean(1)
    hydrostatic = RHO * G * depth
    deep = depth > 4 * S
    assert np.all(np.abs(mean[deep] / hydrostatic[deep] - 1.0) < 0.10), mean / hydrostatic
    assert np.all(np.abs(mean - hydrostatic)[~deep] < RHO * G * S), mean - hydrostatic
    assert mean[-1] < 0.5 * RHO * G * S, mean[-1]
    pairs = mean.reshape(-1, 2).mean(1)
    assert np.all(np.diff(pairs) < 0.0), pairs
    weight = RHO * S**3 * G * len(liquid)
    assert abs(mean[0] * (n * S) ** 2 / weight - 1.0) < 0.05
    assert abs(p.sum() * S**3 / (weight * top / 2) - 1.0) < 0.03


def test_pressure_reads_zeros_once_positions_are_set_until_the_next_step():
    """The pressure of the last step belongs to the positions it ended at: once ``positions``
    are set (``load_state`` sets them too) it reads zeros, as before the first step, and the
    next step writes its own. Before, the last step's pressure stayed, beside positions it
    was not of. A 4 x 4 x 6 column settling on a plane for 5 steps of 10 ms reads a bottom
    pressure above 0 (a fifth of its hydrostatic 540 Pa or more)."""
    body = pd.Particles(lattice((0, 0, 0), (4, 4, 6)), spacing=S, density=RHO,
                        material=pd.ViscoelasticFluid())
    solver = pd.Solver(dt=0.01, gravity=(0, 0, -G))
    solver.add(body)
    solver.add_collider(pd.Plane())
    for _ in range(5):
        solver.step()
    assert body.pressure.max() > 0.2 * RHO * G * 5.5 * S, body.pressure.max()
    body.positions = body.positions + [0.0, 0.0, 0.001]
    assert body.pressure.shape == (body.num_particles,) and not body.pressure.any()
    solver.step()
    assert body.pressure.max() > 0.0


@pytest.mark.parametrize("density_solver", ["jacobi", "cg"])
def test_every_density_constraint_holds_where_an_adhered_liquid_rests(density_solver):
    """Without gravity, the column between its ghost walls and a honey blob under its ghost
    ceiling (5 x 5 x 6, a ceiling one spacing wider) rest where they were made: every density
    constraint holds there, the ghosts' on the walls' edges and the ceiling's rim and corners
    too, so no step projects (0 passes, the largest violation under 1e-9). Their rest density
    was `rho0` of a density corrected for a flat face: on the walls' outer top edge 6.6 %
    beyond reach, on the ceiling's corners 15 %, and every step ran to the cap of 50."""
    body, _ = column(4, 16, adhesion=True, density_solver=density_solver)
    x, ceiling = blob_under_a_ceiling(5, 6, S)
    honey = pd.Particles(x, spacing=S, density=1400.0, material=pd.ViscoelasticFluid(
        viscosity=10.0, shear_modulus=500.0, adhesion=True, density_solver=density_solver))
    honey.pin(np.flatnonzero(ceiling))
    for scene in (body, honey):
        solver = pd.Solver(dt=0.01, gravity=(0, 0, 0), global_solver="jacobi")
        solver.add(scene)
        for _ in range(3):
            p = solver.step().particles
            assert p["density_passes"] == 0 and p["density_error"] < 1e-9, p


def test_a_viscous_blob_under_a_ceiling_hangs_on_by_its_viscosity():
    """A Newtonian blob (5 x 5 x 6 particles, 1400 kg/m^3, 1000 Pa s, no elasticity) under a
    ceiling of two layers of pinned particles of its body, dt = 5 ms: the viscosity acts on
    the velocity before the positions are predicted, so the particles next to the ceiling
    move at the viscous flow's speed (the steady shear flow gives the top layer about
    g S H / nu = 8 mm/s, H the blob's height), not by g dt^2 per step whatever the
    viscosity. After 0.3 s the blob is still one piece with the ceiling (neighbours within
    1.6 spacings) and its lowest particle has dropped less than 3 spacings (free fall: 44
    spacings). With the viscosity applied after the positions it parted within 0.15 s."""
    x, ceiling = blob_under_a_ceiling(5, 6, S)
    blob = pd.Particles(x, spacing=S, density=1400.0,
                        material=pd.ViscoelasticFluid(viscosity=1000.0))
    blob.pin(np.flatnonzero(ceiling))
    solver = pd.Solver(dt=0.005, gravity=(0, 0, -G), global_solver="jacobi")
    solver.add(blob)
    low0 = x[~ceiling, 2].min()
    for _ in range(60):
        solver.step()
    p = blob.positions
    pairs = cKDTree(p).query_pairs(1.6 * S, output_type="ndarray")
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(p),) * 2)
    count, label = connected_components(graph, directed=False)
    assert count == 1, count
    drop = low0 - p[~ceiling, 2].min()
    assert 0.0 < drop < 3 * S, drop


MARTIN_MOYCE = [(0.832, 1.217), (1.997, 2.292), (3.345, 4.134), (5.091, 6.98)]


def dam_break(dt=0.005, threads=None, precision=None, **fluid):
    """The dam break of DESIGN.md section 7 at a small size: a column a = 0.1 m wide, 2a high
    and 3 spacings deep (10 x 3 x 20 particles) against the left wall of a 0.8 m tank with
    slip walls (planes), water viscosity."""
    a, length, depth = 0.1, 0.8, 3
    na = round(a / S)
    body = pd.Particles(
        lattice((0, 0, 0), (na, depth, 2 * na)), spacing=S, density=RHO,
        material=pd.ViscoelasticFluid(**{"viscosity": 1e-3, **fluid}),
    )
    solver = pd.Solver(dt=dt, gravity=(0, 0, -G), global_solver="jacobi", threads=threads,
                       precision=precision)
    solver.add(body)
    walls(solver, (0, 0, 0), (length, depth * S, 1.0))
    return body, solver, a, (0, 0, 0), (length, depth * S, 1.0)


def density_gradients(x, mass):
    """Test-side oracle: ``||grad_i rho||^2`` (kg^2/m^8) of every particle, the spiky kernel's
    gradient normalised on the cubic lattice as ``spiky_density``."""
    h = SUPPORT
    w = lambda r: np.where(r < h, 15.0 / (np.pi * h**6) * (h - r) ** 3, 0.0)
    k = np.arange(-3, 4)
    p = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3) * S
    scale = 1.0 / (S**3 * w(np.linalg.norm(p, axis=1)).sum())
    pairs = cKDTree(x).query_pairs(h, output_type="ndarray")
    d = x[pairs[:, 0]] - x[pairs[:, 1]]
    r = np.linalg.norm(d, axis=1)
    g = (-45.0 / (np.pi * h**6) * (h - r) ** 2 / np.maximum(r, 1e-300))[:, None] * d
    grad = np.zeros_like(x)
    np.add.at(grad, pairs[:, 0], g)
    np.add.at(grad, pairs[:, 1], -g)
    return (scale * mass) ** 2 * (grad**2).sum(axis=1)


@pytest.mark.parametrize("redistribution, density_solver",
                         [(0.0, "jacobi"), (0.5, "jacobi"), (0.0, "cg")])
def test_the_dam_break_front_follows_martin_and_moyce(redistribution, density_solver):
    """The front Z = (max x + S/2) / a at T = t sqrt(2 g / a) (the nearest step) within 10 % of
    Martin and Moyce's points, and the liquid stays within its tank (its walls' planes, to
    1e-9 m) at every step; with redistribution too (strength 0.5, 5 passes: a position
    correction whose moves do not become velocity, one-sided at the free surface); with the
    conjugate-gradient density solver too."""
    body, solver, a, lo, hi = dam_break(
        redistribution=redistribution, redistribution_iterations=5,
        density_solver=density_solver,
    )
    assert body.material.density_solver == density_solver
    c = np.sqrt(2 * G / a)
    dt, k, errors = 0.005, 0, []
    for T, Z in MARTIN_MOYCE:
        while k < round(T / (c * dt)):
            solver.step()
            k += 1
            x = body.positions
            assert (x >= np.array(lo) - 1e-9).all() and (x <= np.array(hi) + 1e-9).all()
        front = (body.positions[:, 0].max() + 0.5 * S) / a
        errors.append(front / Z - 1.0)
    assert np.max(np.abs(errors)) < 0.10, errors


def test_the_conjugate_gradients_reach_the_tolerance_more_often_than_jacobi_in_a_tank():
    """Over the first 0.2 s of the dam break (3 particles deep: most particles touch a side
    wall, the floor's row an edge of two walls) the conjugate-gradient density solver runs to
    the pass cap (50) on at most half as many steps as the Jacobi projection (measured 11
    against 32 of 40), and it meets the tolerance (1e-3) on every step of the column's first
    collapse (the first 15 steps, to T = 1.05; the 16th left 1.7e-3 with the walls found
    within each step, where walls kept across steps reached the 18th). Members held by two
    walls slide along both in the linear solve: with one normal for the sum of the pushes the
    colliders took part of every move back (on 432 particles 36 of 73 steps at the cap against
    Jacobi's 13)."""
    capped = {}
    for density_solver in ["jacobi", "cg"]:
        body, solver, *_ = dam_break(density_solver=density_solver)
        capped[density_solver] = 0
        for k in range(40):
            stats = solver.step()
            capped[density_solver] += stats.particles["density_passes"] >= 50
            if density_solver == "cg" and k < 15:
                assert stats.particles["density_error"] <= 1e-3, (k, stats.particles)
    assert 2 * capped["cg"] <= capped["jacobi"], capped


@pytest.mark.parametrize("density_solver", ["jacobi", "cg"])
def test_a_member_pushed_up_off_the_floor_leaves_it(density_solver):
    """Two 4 x 4 layers of liquid on the floor plane, the bottom one at its margin (S/2), the
    top one 0.7 S above it, over two layers of pinned ghosts of its body inside the floor, no
    gravity. Step 1: the squeezed top layer presses the bottom one into the floor. Then the
    ghosts are moved up by 0.45 S, and step 2's density constraints push the bottom layer up,
    away from the floor it touches. A wall holds by an inequality, so every bottom particle
    rises by more than S/10 (measured with Jacobi, which has no walls: 0.29 S at least, 0.31 S
    on average). With the floor's normal kept two-sided from step 1 a particle stayed on the
    floor (the least rise 6e-6 S) while the layer rose by 0.40 S on average."""
    bottom = lattice((0, 0, 0), (4, 4, 1))
    x = np.vstack([bottom, bottom + [0, 0, 0.7 * S], lattice((-2, -2, -2), (6, 6, 0))])
    body = pd.Particles(x, spacing=S, density=RHO,
                        material=pd.ViscoelasticFluid(density_solver=density_solver))
    ghosts = np.arange(2 * len(bottom), len(x))
    body.pin(ghosts)
    solver = pd.Solver(dt=0.005, gravity=(0, 0, 0), global_solver="jacobi")
    solver.add(body)
    solver.add_collider(pd.Plane())
    assert solver.step().particles["density_passes"] > 0
    assert body.positions[: len(bottom), 2].min() == pytest.approx(0.5 * S, abs=1e-12)
    body.pin(ghosts, x[ghosts] + [0, 0, 0.45 * S])
    assert solver.step().particles["density_passes"] > 0
    rise = body.positions[: len(bottom), 2] - 0.5 * S
    assert rise.min() > 0.1 * S, rise / S


def test_adhered_liquid_is_solved_to_the_tolerance_or_to_the_pass_cap():
    """A blob (4 x 4 x 4, 1 Pa s) under a ceiling of ghosts it adheres to, conjugate
    gradients, density tolerance 1 %, 40 steps of 5 ms: every step ends within the tolerance
    or at the pass cap (50). An adhered ghost below rest asks a quarter of its violation per
    linearisation; when the solve's stop looked at that quarter, a violation between 1 and 2
    tolerances stopped it before its first iteration: 47 of 60 steps ended 1.1-2 tolerances
    above it with passes to spare."""
    x, ceiling = blob_under_a_ceiling(4, 4, S)
    tolerance, cap = 1e-2, 50
    blob = pd.Particles(x, spacing=S, density=RHO, material=pd.ViscoelasticFluid(
        viscosity=1.0, adhesion=True, density_solver="cg", density_tolerance=tolerance,
        density_iterations=cap))
    blob.pin(np.flatnonzero(ceiling))
    solver = pd.Solver(dt=0.005, gravity=(0, 0, -G), global_solver="jacobi")
    solver.add(blob)
    for k in range(40):
        p = solver.step().particles
        assert p["density_error"] <= tolerance or p["density_passes"] >= cap, (k, p)


@pytest.mark.parametrize("density_solver", ["jacobi", "cg"])
def test_threads_are_bit_identical_and_f32_follows_f64(density_solver):
    """1 and 2 threads give the same bits (positions, velocities and pressures); f32 stays
    within 2 spacings of f64 after 20 steps of the dam break (the flow's round-off grows as
    it splashes); with either density solver (the conjugate gradients' inner products sum
    fixed chunks in order)."""
    runs = {}
    for key, threads, precision in [("one", 1, "f64"), ("two", 2, "f64"), ("f32", 2, "f32")]:
        body, solver, *_ = dam_break(threads=threads, precision=precision,
                                     density_solver=density_solver)
        for _ in range(20):
            solver.step()
        runs[key] = (body.positions.copy(), body.velocities.copy(), body.pressure)
    assert np.array_equal(runs["one"][0], runs["two"][0])
    assert np.array_equal(runs["one"][1], runs["two"][1])
    assert np.array_equal(runs["one"][2], runs["two"][2]) and runs["one"][2].max() > 0.0
    assert np.abs(runs["f32"][0] - runs["one"][0]).max() < 2 * S


def front_after(steps=30, **fluid):
    """The dam break's front x (m) after `steps` steps; the liquid checked inside its tank."""
    body, solver, a, lo, hi = dam_break(**fluid)
    for _ in range(steps):
        stats = solver.step()
    x = body.positions
    assert (x >= np.array(lo) - 1e-9).all() and (x <= np.array(hi) + 1e-9).all()
    return x[:, 0].max(), stats


def test_a_viscous_liquid_spreads_slower_than_water():
    """After 0.15 s the front of a liquid of viscosity 10 Pa s (honey-like) lags water's by
    more than 2 spacings (measured 0.223 m against 0.247 m); both stay in the tank."""
    water, _ = front_after()
    honey, _ = front_after(viscosity=10.0)
    assert honey < water - 2 * S, (honey, water)


@pytest.mark.parametrize("density_solver", ["jacobi", "cg"])
def test_redistribution_lowers_the_density_gradient_and_is_timed(density_solver):
    """After 0.15 s of the dam break, redistribution (strength 0.5, 5 passes) leaves the sum
    of ``||grad rho||^2`` over the particles lower than without (the quantity eq. 21 makes
    a constraint, measured by the test's own SPH sum), its front within 10 % of water's and
    the liquid in its tank, both runs with the same density solver. Measured 7.51e11 against
    7.69e11 (Jacobi), 7.57e11 against 8.02e11 (conjugate gradients); 7.96e11 (Jacobi) before
    its moves were held to the density constraints (their added density, pushed apart by the
    next step's projection, became velocity), and 8.19e11 (conjugate gradients) when the
    hold was solved by them: their equalities pulled members back to their ceilings."""
    body, solver, *_ = dam_break(density_solver=density_solver)
    body_r, solver_r, *_ = dam_break(
        density_solver=density_solver, redistribution=0.5, redistribution_iterations=5
    )
    for _ in range(30):
        solver.step()
        stats = solver_r.step()
    assert stats.timings["redistribution"] > 0.0
    m = RHO * S**3
    plain = density_gradients(body.positions, m).sum()
    redistributed = density_gradients(body_r.positions, m).sum()
    assert redistributed < plain, (redistributed, plain)
    front, front_r = body.positions[:, 0].max(), body_r.positions[:, 0].max()
    assert abs(front_r / front - 1.0) < 0.1, (front_r, front)
    assert front_r <= 0.8


def test_redistribution_leaves_pinned_ghosts_where_they_are():
    """The ghost walls of the resting column (pinned, partly inside the floor's and the
    walls' planes) stay exactly where they were pinned through steps with redistribution
    (strength 1): its push out of the colliders had moved the ghosts under the floor onto the
    liquid's first layer (a density of 12 rho0 there)."""
    body, liquid = column(4, 16, redistribution=1.0, redistribution_iterations=5)
    solver = pd.Solver(dt=0.01, gravity=(0, 0, -G), global_solver="jacobi")
    solver.add(body)
    walls(solver, (0, 0, 0), (4 * S, 4 * S, 1.0))
    ghosts = np.setdiff1d(np.arange(body.num_particles), liquid)
    x0 = body.positions[ghosts].copy()
    for _ in range(3):
        solver.step()
        assert np.array_equal(body.positions[ghosts], x0)
    assert spiky_density(body.positions, RHO * S**3).max() < 1.1 * RHO


@pytest.mark.xfail(
    strict=True,
    reason="open, and the measure asks more than the column meets without redistribution: "
    "its highest particle, taken at every step, reaches 1.8 % above its start with strength "
    "0 (1.7 % with adhesion; the hydrostatic test samples every 0.1 s), 2.0 % with 0.5; its "
    "largest speed over the last 20 steps has median 0.039 m/s (max 0.081, 0.028 at the end) "
    "with 0 and 0.094 (max 0.139) with 0.5. The surface layers' settling out of the cubic "
    "lattice drives it (a converged projection too: 2.91 %; from a settled start 0.134 m/s "
    "at the end; docs/particles/fluids.md, round w)",
)
def test_a_resting_column_with_redistribution_stays_at_rest():
    """The hydrostatic column of the first test with redistribution (strength 0.5, 5 passes)
    over 1 s: its top stays within 1 % of its height and its particles come to rest
    (|v| < 0.05 m/s): the redistribution neither lifts the free surface nor drives a flow."""
    n, height = 4, 16
    body, liquid = column(n, height, redistribution=0.5, redistribution_iterations=5)
    solver = pd.Solver(dt=0.01, gravity=(0, 0, -G), global_solver="jacobi")
    solver.add(body)
    walls(solver, (0, 0, 0), (n * S, n * S, 1.0))
    top0 = (height - 0.5) * S
    tops = []
    for k in range(100):
        solver.step()
        tops.append(body.positions[liquid, 2].max() / top0 - 1.0)
    assert np.max(np.abs(tops)) < 0.01, tops
    assert np.abs(body.velocities[liquid]).max() < 0.05


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"viscosity": -1.0}, "viscosity"),
        ({"viscosity": float("nan")}, "viscosity"),
        ({"density_iterations": 0}, "density_iterations"),
        ({"density_iterations": -3}, "density_iterations"),
        ({"density_tolerance": 0.0}, "density_tolerance"),
        ({"density_tolerance": 0.5}, "density_tolerance"),
        ({"relaxation": 0.0}, "relaxation"),
        ({"density_solver": "gauss"}, "density_solver"),
        ({"relaxation": float("inf")}, "relaxation"),
        ({"redistribution": 1.5}, "redistribution"),
        ({"redistribution": -0.1}, "redistribution"),
        ({"redistribution_iterations": 0}, "redistribution_iterations"),
        ({"shear_modulus": -1.0}, "shear_modulus"),
        ({"shear_modulus": float("nan")}, "shear_modulus"),
        ({"shear_modulus": 10.0, "yield_stress": 0.0}, "yield_stress"),
        ({"shear_modulus": 10.0, "yield_stress": float("inf")}, "yield_stress"),
        ({"shear_modulus": 10.0, "bulk_modulus": 100.0}, "bulk_modulus"),
        ({"shear_modulus": 10.0, "bulk_modulus": 6.0}, "bulk_modulus"),
        ({"bulk_modulus": -1.0}, "bulk_modulus"),
        ({"surface_tension": -0.1}, "surface_tension"),
        ({"surface_tension": float("nan")}, "surface_tension"),
    ],
)
def test_bad_fluid_parameters_are_value_errors_naming_the_value(kwargs, needle):
    with pytest.raises(ValueError, match=needle):
        pd.ViscoelasticFluid(**kwargs)


def test_a_fluid_body_refuses_a_horizon_or_plasticity_and_bad_positions():
    x = lattice((0, 0, 0), (3, 3, 3))
    fluid = pd.ViscoelasticFluid()
    with pytest.raises(ValueError, match="horizon"):
        pd.Particles(x, spacing=S, density=RHO, material=fluid, horizon=0.03)
    with pytest.raises(ValueError, match="plasticity"):
        pd.Particles(x, spacing=S, density=RHO, material=fluid,
                     plasticity=pd.DruckerPrager(friction_angle=30.0, cohesion=0.0))
    bad = x.copy()
    bad[4, 1] = np.nan
    with pytest.raises(ValueError, match="4"):
        pd.Particles(bad, spacing=S, density=RHO, material=fluid)
    with pytest.raises(ValueError, match="density"):
        pd.Particles(x, spacing=S, density=-1.0, material=fluid)
    assert pd.ViscoelasticFluid().viscosity == 1e-3
    assert pd.ViscoelasticFluid().density_solver == "cg"


def test_two_fluids_of_different_spacings_in_one_solver_are_refused():
    a = pd.Particles(lattice((0, 0, 0), (3, 3, 3)), spacing=S, density=RHO,
                     material=pd.ViscoelasticFluid())
    b = pd.Particles(lattice((5, 0, 0), (8, 3, 3)) * 2, spacing=2 * S, density=RHO,
                     material=pd.ViscoelasticFluid())
    solver = pd.Solver(dt=0.01)
    solver.add(a)
    solver.add(b)
    with pytest.raises(ValueError, match="spacing"):
        solver.step()
