"""Liquid with wet sand (He et al. 2017, section 8, Fig. 16; issue 40): the liquid's density
constraints see the sand's grains (incompressibility over both), so liquid poured on a sand
bed stays on it; the grains it reaches get wet (their saturation rises, and with it their
cohesion: docs/particles/couplings.md, "Liquid with wet sand")."""

import numpy as np
import pytest

import peridyn as pd

S = 0.01  # lattice spacing of sand and liquid (m)
RHO = 1600.0  # packed sand (kg/m^3)
DT = 1.0 / 500.0  # s
WATER = pd.ViscoelasticFluid(viscosity=1e-3)


def lattice(n, origin):
    axes = [np.arange(k) * S for k in n]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + np.asarray(origin)


def solver(**kwargs):
    s = pd.Solver(dt=DT, max_iters=10, tol=0.0, **kwargs)
    s.add_collider(pd.Plane(friction=0.3))
    return s


def bed_and_water(threads=None, density_solver="cg"):
    """A 4 x 4 x 4 block of water (its density constraints solved by `density_solver`)
    released 2 cm above the middle of a 10 x 10 x 3 bed of dry sand (friction angle 30
    degrees, layers at 0.5, 1.5 and 2.5 spacings) on the ground. Returns the solver, the sand
    and the water."""
    bed = pd.Particles(lattice((10, 10, 3), (-4.5 * S, -4.5 * S, 0.5 * S)), spacing=S,
                       density=RHO, material=pd.Granular(friction_angle=30.0))
    water = pd.Particles(lattice((4, 4, 4), (-1.5 * S, -1.5 * S, 4.5 * S)), spacing=S,
                         density=1000.0,
                         material=pd.ViscoelasticFluid(viscosity=1e-3,
                                                       density_solver=density_solver))
    s = solver(threads=threads)
    s.add(bed)
    s.add(water)
    return s, bed, water


def over_the_middle(water):
    """The water particles over the bed's middle (7 x 7 spacings; the rest runs off its edges
    to the ground)."""
    y = water.positions
    return y[(np.abs(y[:, 0]) < 3.5 * S) & (np.abs(y[:, 1]) < 3.5 * S)]


@pytest.mark.parametrize("density_solver", ["cg", "jacobi"])
def test_liquid_poured_on_a_sand_bed_stays_on_it_and_wets_the_grains_it_reaches(density_solver):
    """Over 0.4 s the bed spreads under the water (three layers to two: the water runs off its
    edges and carries surface grains with it) and the water settles into the gaps of the
    spread surface layer, but it never passes through the bed: no water particle over its
    middle comes below 0.9 spacings, into the bottom layer of grains (measured lowest 1.08
    spacings with the conjugate gradients, 1.16 with Jacobi, water resting on the bottom
    layer; the grains are partners in the water's density constraints). The conjugate
    gradients' multipliers beside a grain never pull: when they did, the water drew grains
    of the bottom layer into itself and sank into the gaps this opened, to 0.83 spacings (and
    to the ground, 0.5, in each of four runs with the water's start jittered by 1e-4
    spacings; docs/particles/couplings.md). At 0.2 s the grains the water touches (a water particle
    within 1.05 spacings) are wet (theta > 0.4, measured from 0.42), and the grains the water never
    came within 2 spacings of, at any step so far, are dry (theta < 0.01; measured at most 0.002,
    26 grains; asserted: at least 5): the wetting is local, the kernel peaked
    (docs/particles/couplings.md). A grain keeps the saturation it reached: the top layer's rim,
    carried off the bed's edges by the water that touched it, stays wet when the water runs on. So
    the dry grains are those the water never reached, not those it is far from at one instant, as
    asserted before: with the conjugate-gradient density solver 21 rim grains the water had touched
    (within 0.97-1.14 spacings; theta 0.40-0.84) were 2.7-3.1 spacings from all of it at
    0.2 s."""
    s, bed, water = bed_and_water(density_solver=density_solver)
    lowest = np.inf
    closest = np.full(bed.num_particles, np.inf)
    for step in range(1, 201):
        s.step()
        if step <= 100:
            x = bed.positions
            gap = np.linalg.norm(x[:, None] - water.positions[None], axis=2).min(1)
            closest = np.minimum(closest, gap)
        if step % 10 == 0:
            over = over_the_middle(water)
            assert len(over) >= 16, len(over)
            lowest = min(lowest, over[:, 2].min())
        if step == 100:
            theta = bed.saturation
            assert theta.shape == (bed.num_particles,)
            touching, unreached = gap < 1.05 * S, closest > 2.0 * S
            assert touching.sum() > 20 and unreached.sum() >= 5, (touching.sum(), unreached.sum())
            assert theta[touching].min() > 0.4, theta[touching]
            assert theta[unreached].max() < 0.01, theta[unreached]
    assert lowest > 0.9 * S, lowest / S


@pytest.mark.parametrize("viscosity, tolerance", [(0.0, 1e-12), (1.0, 1e-6)])
def test_liquids_of_two_densities_conserve_their_momentum(viscosity, tolerance):
    """A block of water pressed against a block of a liquid 1.6 times as dense (their lattices
    0.6 spacings apart, so the density constraints and the bodies' repulsion push both) in
    zero gravity, with no collider: the total momentum stays zero while the blocks fly apart.
    Without viscosity the density projection alone acts: it moves each particle by its
    inverse mass (Macklin et al. 2014), measured 1e-16 of the momentum each block carries
    (10 % with equal moves for both, as before). With 1 Pa s the viscosity solve's pair
    forces are equal and opposite too (the momentum form, docs/particles/couplings.md), up to its
    conjugate-gradient residual (sqrt of the precision's epsilon, relative): measured 1.1e-8
    (1.1e-2 with the velocity form symmetrised on `nu V`, as before). The sand grains
    among a liquid's partners are moved by the same rules."""
    still = pd.ViscoelasticFluid(viscosity=viscosity)
    dense = pd.Particles(lattice((3, 3, 3), (0.0, 0.0, 0.0)), spacing=S, density=RHO,
                         material=still)
    water = pd.Particles(lattice((3, 3, 3), (-2.6 * S, 0.0, 0.0)), spacing=S, density=1000.0,
                         material=still)
    s = pd.Solver(dt=DT, gravity=(0.0, 0.0, 0.0))
    s.add(dense)
    s.add(water)
    for _ in range(5):
        s.step()
    momenta = [b.velocities.sum(0) * b.density * S**3 for b in (dense, water)]
    apart = np.linalg.norm(momenta[0])
    assert momenta[0][0] > 0.0 and momenta[1][0] < 0.0, momenta
    assert np.linalg.norm(momenta[0] + momenta[1]) < tolerance * apart, (momenta, apart)


def test_threads_are_bit_identical_for_liquid_on_sand():
    runs = []
    for threads in (1, 2):
        s, bed, water = bed_and_water(threads)
        for _ in range(10):
            s.step()
        runs.append((bed, water))
    for a, b in zip(*runs):
        assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(runs[0][0].saturation, runs[1][0].saturation)


def wetted_bar(wicking, length=40, side=3):
    """A bar of sand `length` x `side` x `side` grains along x, pinned where it is sampled,
    its first half saturated (through the material state, as a state file sets it) and the
    rest dry, in a solver without gravity. Returns the solver and the bar."""
    bar = pd.Particles(lattice((length, side, side), (0.0, 0.0, 0.5 * S)), spacing=S,
                       density=RHO, material=pd.Granular(friction_angle=30.0, wicking=wicking))
    state = bar.material_state
    state["wetted"] = np.where(np.arange(bar.num_particles) // side**2 < length // 2, 1.0, 0.0)
    bar.material_state = state
    bar.pin(np.arange(bar.num_particles))
    s = pd.Solver(dt=0.01, gravity=(0.0, 0.0, 0.0))
    s.add(bar)
    return s, bar


def test_held_water_wicks_along_a_bar_as_the_square_root_of_time():
    """The water the grains hold moves from grain to grain by the capillary diffusion
    `d theta / dt = D lap theta` (docs/particles/couplings.md, "Liquid with wet sand"): in a 40 x 3
    x 3 bar saturated over its first half, at `D` = 1e-3 m^2/s, the front where the layers' mean
    saturation falls to 0.1 lies past the interface at `2 sqrt(D t) erfc^-1(0.2)` (the
    analytic 1D diffusion from a step) within 15 % after 0.25 s and 1 s, and moves as
    `sqrt(t)` (the ratio of the two within 5 % of 2). The surface correction keeps a bar
    three grains thick near the interior's rate (measured fronts 1.11 and 1.10 of the analytic; a
    7 x 7 bar's 1.04-1.05, Rust `wicking_tests.rs`). The held water (`theta n V`) is
    conserved to 1e-12 of itself."""
    s, bar = wetted_bar(1e-3)
    total = bar.saturation.sum()
    fronts = []
    for step in range(1, 101):
        s.step()
        if step in (25, 100):
            layers = bar.saturation.reshape(40, 9).mean(1)
            k = 20 + np.argmax(layers[20:] < 0.1)
            a, b = layers[k - 1], layers[k]
            depth = (k - 1 + (a - 0.1) / (a - b) - 19.5) * S
            analytic = 2.0 * np.sqrt(1e-3 * step * 0.01) * 0.9061938
            fronts.append(depth)
            assert abs(depth / analytic - 1.0) < 0.15, (step, depth, analytic)
    assert abs(fronts[1] / fronts[0] / 2.0 - 1.0) < 0.05, fronts
    assert abs(bar.saturation.sum() - total) < 1e-12 * total
    assert bar.saturation.min() >= 0.0 and bar.saturation.max() <= 1.0


def test_wicking_in_a_falling_block_conserves_the_held_water():
    """A block of sand 6 x 6 x 6 grains, wetted on one side (theta 1 for x < 3 spacings, 0
    beyond), dropped 1 cm onto the ground at the default diffusivity times a hundred: its
    grains change neighbours as it lands and spreads, and the held water moves (the dry
    side's mean saturation rises above 0.02: measured 0.25) yet its total is conserved to
    1e-12 over 0.2 s (measured 1.3e-16).
    Without wicking (`wicking=0`) the saturations stay as set, bit for bit."""
    for wicking in (1e-3, 0.0):
        block = pd.Particles(lattice((6, 6, 6), (0.0, 0.0, 1.5 * S)), spacing=S, density=RHO,
                             material=pd.Granular(friction_angle=30.0, wicking=wicking))
        state = block.material_state
        start = np.where(block.positions[:, 0] < 2.5 * S, 1.0, 0.0)
        state["wetted"] = start
        block.material_state = state
        s = solver()
        s.add(block)
        for _ in range(100):
            s.step()
        theta = block.saturation
        if wicking:
            assert theta[start == 0.0].mean() > 0.02, theta[start == 0.0].mean()
            assert abs(theta.sum() - start.sum()) < 1e-12 * start.sum(), theta.sum()
        else:
            assert np.array_equal(theta, start)


def test_a_step_whose_wicking_needs_too_many_substeps_is_refused_and_keeps_the_state():
    """The explicit wicking's substeps grow as `D dt / spacing^2` (docs/particles/couplings.md,
    "Liquid with wet sand"): the largest diffusivity (0.01 m^2/s) over 10 ms steps on a 1 mm lattice
    would need about a thousand, more than the 100 allowed. The step is refused with a
    ValueError naming `wicking` and the substeps, and the bar keeps its positions and
    saturations; the same bar at a tenth of the diffusivity over 1 ms steps wicks."""
    def bar(wicking, dt):
        grains = pd.Particles(lattice((12, 3, 3), (0.0, 0.0, 0.0)) * 0.1, spacing=1e-3,
                              density=RHO,
                              material=pd.Granular(friction_angle=30.0, wicking=wicking))
        state = grains.material_state
        state["wetted"] = np.where(np.arange(grains.num_particles) < 54, 1.0, 0.0)
        grains.material_state = state
        grains.pin(np.arange(grains.num_particles))
        s = pd.Solver(dt=dt, gravity=(0.0, 0.0, 0.0))
        s.add(grains)
        return s, grains
    s, grains = bar(0.01, 0.01)
    positions, theta = grains.positions.copy(), grains.saturation.copy()
    with pytest.raises(ValueError, match=r"wicking=0\.01.*needs \d+ substeps"):
        s.step()
    assert np.array_equal(grains.positions, positions)
    assert np.array_equal(grains.saturation, theta)
    s, grains = bar(1e-3, 1e-3)
    s.step()
    assert grains.saturation[54:].max() > 0.0
    assert abs(grains.saturation.sum() - theta.sum()) < 1e-12 * theta.sum()


@pytest.mark.parametrize("wicking", [-1e-6, 0.011, float("nan")])
def test_a_bad_wicking_diffusivity_is_refused_by_name(wicking):
    with pytest.raises(ValueError, match="wicking"):
        pd.Granular(friction_angle=30.0, wicking=wicking)


def test_the_wicking_diffusivity_reads_back_and_shows_in_the_repr():
    assert pd.Granular(friction_angle=30.0).wicking == 1e-5
    sand = pd.Granular(friction_angle=30.0, wicking=2e-4)
    assert sand.wicking == 2e-4 and "wicking=0.0002" in repr(sand)


def column(radius, height, wicking=pd.Granular(friction_angle=30.0).wicking):
    n = int(round(radius / S))
    g = np.arange(-n, n + 1) * S
    x, y, z = np.meshgrid(g, g, (np.arange(int(round(height / S))) + 0.5) * S, indexing="ij")
    p = np.stack([x, y, z], -1).reshape(-1, 3)
    p = p[np.hypot(p[:, 0], p[:, 1]) <= radius + 1e-9]
    return pd.Particles(p, spacing=S, density=RHO,
                        material=pd.Granular(friction_angle=30.0, wicking=wicking))


def poured_and_released(wicking):
    """A column of dry sand (R = 6 cm, a = 1, capillary diffusivity `wicking` m^2/s), held by
    pins while water (7 x 7 x 4) is poured on its top for 0.12 s, then released without the
    water in a new solver for 0.3 s, next to a dry control. Returns the wetted column's
    saturations when released and 0.3 s later, and the 95th percentile heights (m) of both
    columns."""
    wet = column(0.06, 0.06, wicking)
    wet.pin(np.arange(wet.num_particles))
    water = pd.Particles(lattice((7, 7, 4), (-3 * S, -3 * S, 0.07)), spacing=S, density=1000.0,
                         material=WATER)
    s = solver()
    s.add(wet)
    s.add(water)
    for _ in range(60):
        s.step()
    theta = wet.saturation
    wet.unpin()
    heights = []
    for body in (wet, column(0.06, 0.06)):
        s = solver()
        s.add(body)
        for _ in range(150):
            s.step()
        heights.append(np.percentile(body.positions[:, 2], 95))
    return theta, wet.saturation, heights


@pytest.mark.xfail(strict=True, reason="the water poured for 0.12 s has not gone in: the "
                   "top layer is saturated and the wicking at sand's diffusivity (1e-5 m^2/s) "
                   "reaches about 1 mm (the next layer at theta 0.016), and the wetted column "
                   "stands 2.128 cm high against the dry column's 2.054 (2.029 without "
                   "wicking): docs/particles/couplings.md, 'Liquid with wet sand'")
def test_a_column_wetted_by_poured_liquid_stands_taller_than_a_dry_one():
    """The wetted column's 95th percentile height stands half a spacing above the dry one's
    (`poured_and_released` at the default wicking)."""
    theta, _, heights = poured_and_released(pd.Granular(friction_angle=30.0).wicking)
    assert (theta > 0.5).sum() > 20, (theta > 0.5).sum()
    assert heights[0] > heights[1] + 0.5 * S, heights


def test_a_column_the_water_soaked_through_stands_taller_than_a_dry_one():
    """With the capillary diffusivity at its largest, 0.01 m^2/s, the 0.12 s of pouring wet
    the column as about two minutes would at sand's 1e-5 (the saturations depend on `D t`
    alone): every layer holds water (means 0.38 at the bottom to 0.93 at the top, measured),
    its capillary cohesion holds the column up, and it stands 5.46 cm high against the dry
    column's 2.05 (asserted: 2 cm higher). Released without the liquid, the column's held
    water is conserved to 1e-12 while it wicks on and settles."""
    theta, after, heights = poured_and_released(0.01)
    assert theta.min() > 0.3, theta.min()
    assert abs(after.sum() - theta.sum()) < 1e-12 * theta.sum(), (after.sum(), theta.sum())
    assert heights[0] > heights[1] + 2.0 * S, heights
