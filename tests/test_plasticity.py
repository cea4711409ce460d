"""Drucker-Prager plasticity and changing neighbourhoods of particle bodies (He et al. 2017,
section 5; issue 39): permanent set only past yield, dissipation over a load cycle, a body
stretched beyond its horizon, the step's phase timings and bad input."""

import functools

import numpy as np
import pytest

import peridyn as pd
from test_viscoelastic import layer_area

S = 0.01  # lattice spacing (m)
E, NU = 1e5, 0.3  # Pa
N, LENGTH = 4, 12  # bar cross-section and length in particles


def bar(plasticity):
    x = np.stack(
        np.meshgrid(np.arange(N), np.arange(N), np.arange(LENGTH), indexing="ij"), -1
    ).reshape(-1, 3) * S
    return pd.Particles(
        x,
        spacing=S,
        density=1000.0,
        material=pd.Elastic.from_young(E, NU),
        plasticity=plasticity,
    )


def ends(body):
    z = body.rest_positions[:, 2]
    return np.flatnonzero(z < 0.5 * S), np.flatnonzero(z > (LENGTH - 1.5) * S)


def solver():
    # Quasi-static: no gravity, steps long against the bar's periods (inertia 1e-6 of the
    # stiffness), each solved to a tight tolerance with the exact global solve.
    return pd.Solver(
        dt=1.0, gravity=(0.0, 0.0, 0.0), max_iters=300, tol=1e-10, global_solver="direct"
    )


def length(body):
    low, high = ends(body)
    p = body.positions
    return p[high, 2].mean() - p[low, 2].mean()


def pinned_ends(body):
    """The two end layers' particles in ascending order (the order of ``pin_targets``) and
    which of them are at the top."""
    low, high = ends(body)
    pinned = np.sort(np.concatenate([low, high]))
    return pinned, np.isin(pinned, high)


def pull(body, s, strains):
    """Moves the top end's pins to each axial strain in turn (one step each); returns the
    work done on the bar (J) by the top pins, trapezoid rule on their reaction."""
    pinned, top = pinned_ends(body)
    rest = body.rest_positions
    span = (LENGTH - 1) * S
    work, last_force, last_strain = 0.0, 0.0, strains[0]
    for strain in strains:
        targets = rest[pinned].copy()
        targets[top, 2] += strain * span
        body.pin_targets = targets
        s.step()
        # The force the pins apply = minus the internal force on the pinned particles.
        force = -body.internal_forces()[pinned[top], 2].sum()
        work += 0.5 * (force + last_force) * (strain - last_strain) * span
        last_force, last_strain = force, strain
    return work


def load_and_release(body, peak, steps=8):
    pinned, top = pinned_ends(body)
    body.pin(pinned)
    s = solver()
    s.add(body)
    pull(body, s, np.linspace(0.0, peak, steps))
    body.unpin(pinned[top])
    for _ in range(30):
        s.step()
    return length(body) / ((LENGTH - 1) * S) - 1.0


def test_no_permanent_set_below_yield_and_a_set_after_it():
    """Yield in tension at about 2 c / E = 0.2 % strain (phi = 0: Tresca's 2 c): a bar pulled
    to 0.05 % and released springs back to its length (1e-7 of it) with its reference bonds
    untouched; pulled to 5 % it keeps a set of most of it (above 3 %)."""
    law = pd.DruckerPrager(friction_angle=0.0, cohesion=100.0, rebuild_neighbours=False)
    elastic_side = bar(law)
    set_small = load_and_release(elastic_side, 5e-4)
    assert abs(set_small) < 1e-7, set_small
    sqrt_j2, strength = elastic_side.yield_state()
    assert np.all(sqrt_j2 < strength)
    offsets, _ = elastic_side.neighborhood()
    reference_offsets, _ = bar(None).neighborhood()
    assert np.array_equal(offsets, reference_offsets)

    plastic_side = bar(law)
    set_large = load_and_release(plastic_side, 0.05)
    assert 0.03 < set_large < 0.05, set_large


def test_a_load_unload_cycle_dissipates_energy_only_when_plastic():
    """The work of the pins over a cycle (pull to 2 %, back to 0): for an elastic bar it is
    below 1 % of the work of the loading half; for a plastic one it is above a third of it."""
    ratios = {}
    for name, law in [
        ("elastic", None),
        ("plastic", pd.DruckerPrager(friction_angle=0.0, cohesion=100.0, rebuild_neighbours=False)),
    ]:
        body = bar(law)
        body.pin(pinned_ends(body)[0])
        s = solver()
        s.add(body)
        up = np.linspace(0.0, 0.02, 9)
        loading = pull(body, s, up)
        unloading = pull(body, s, up[::-1])
        ratios[name] = (loading + unloading) / loading
    assert abs(ratios["elastic"]) < 0.01, ratios
    assert ratios["plastic"] > 0.33, ratios


SOFT_PULL = 0.005  # the soft bar's stretch per 20 ms step: 1.5 times its length in 2 s


def pull_soft_bar(body, steps):
    """Pins both end layers of ``body`` and moves the top one by ``SOFT_PULL`` of its length
    per step of 20 ms (60 iterations each, no gravity) for ``steps`` steps, yielding after each step the stretch (the top's move over the length)
    and the step's statistics."""
    pinned, top = pinned_ends(body)
    body.pin(pinned)
    s = pd.Solver(dt=0.02, gravity=(0.0, 0.0, 0.0), max_iters=60)
    s.add(body)
    rest = body.rest_positions
    span = (LENGTH - 1) * S
    for k in range(1, steps + 1):
        targets = rest[pinned].copy()
        targets[top, 2] += SOFT_PULL * k * span
        body.pin_targets = targets
        yield SOFT_PULL * k, s.step()


def test_a_plastic_body_stretched_beyond_its_horizon_stays_whole():
    """A soft plastic bar (yield strain 0.1 %) that hardens (500 Pa per unit plastic strain)
    pulled to 1.5 times its length, its end moved 2.5 horizons, with its neighbours searched
    on the deformed positions: it stays one piece (every particle keeps neighbours, mean 8 to
    40, and reaches the pinned bottom through bonds), nothing blows up (speeds below 10 times
    the pull's), and the step reports the plastic and neighbour phases. Why the hardening:
    a perfectly plastic bar in tension necks from its yield (Considere: its force falls as
    its section does), and this one, without hardening, necks in its middle and parts there
    at 1.42 times its length (measured; 1.44 and 1.48 with a hardening of 100 and 200 Pa);
    with 500 Pa its layers' gaps at 1.5 are 1.05 spacings at the pins to 1.75 in the middle.
    (Until issue 40's round y its bonds kept the springs of their birth lengths while the
    flow stretched them, a hardening that kept the perfectly plastic bar whole to 1.5.)"""
    body = bar(pd.DruckerPrager(friction_angle=0.0, cohesion=50.0, hardening=500.0))
    low, _ = ends(body)
    for _, stats in pull_soft_bar(body, 100):
        pass
    assert np.all(np.isfinite(body.positions))
    assert np.abs(body.velocities).max() < 10 * SOFT_PULL * (LENGTH - 1) * S / 0.02
    offsets, indices = body.neighborhood()
    counts = np.diff(offsets)
    assert counts.min() >= 1, counts.min()
    assert 8 <= counts.mean() <= 40, counts.mean()
    # One piece: every particle reaches the pinned bottom through bonds.
    reached = np.zeros(body.num_particles, bool)
    front = list(low)
    reached[low] = True
    while front:
        i = front.pop()
        for j in indices[offsets[i] : offsets[i + 1]]:
            if not reached[j]:
                reached[j] = True
                front.append(j)
    assert reached.all(), np.flatnonzero(~reached)
    assert length(body) > 1.45 * (LENGTH - 1) * S
    t = stats.timings
    assert t["plasticity"] > 0.0 and t["neighbours"] > 0.0
    assert t["plasticity"] + t["neighbours"] <= t["finish"]


def test_a_perfectly_plastic_bar_necks_and_a_hardening_one_thins_evenly():
    """Considere: a perfectly plastic bar in tension carries a force that falls as its section
    does, so once it yields any thinner layer yields on and the bar necks; hardening (here
    500 Pa per unit plastic strain) outgrows the section's loss and spreads the thinning. The
    soft bar of the test above (c = 50 Pa, phi = 0) pulled to 1.15 and 1.3 times its length:
    each free layer's area is ``layer_area`` (exact for an affine map of the layer). Without
    hardening the narrowest layer shrinks faster than the mean section: narrowest over mean
    0.908 at 1.15 and 0.785 at 1.3 (the narrowest 0.784 and 0.606 of its start, the mean
    0.864 and 0.772; uniform thinning at constant volume gives 1 / 1.3 = 0.769 everywhere),
    asked below 0.85 at 1.3 and falling by more than 0.05 from 1.15. With hardening 500 the
    ratio is 0.945 and 0.920 (asked above 0.88 at 1.3, falling by less than 0.05). (The
    unhardened bar parts in its middle at 1.42, measured: the test above.)"""
    ratios = {}
    for hardening in (0.0, 500.0):
        body = bar(pd.DruckerPrager(friction_angle=0.0, cohesion=50.0, hardening=hardening))
        rest = body.rest_positions
        layers = [np.flatnonzero(np.abs(rest[:, 2] - j * S) < 0.5 * S)
                  for j in range(1, LENGTH - 1)]
        for stretch, _ in pull_soft_bar(body, 60):
            if np.isclose(stretch, 0.15) or np.isclose(stretch, 0.3):
                p = body.positions
                areas = np.array([layer_area(p[i], rest[i]) for i in layers])
                ratios[hardening, round(stretch, 2)] = areas.min() / areas.mean()
    assert ratios[0.0, 0.3] < 0.85, ratios
    assert ratios[0.0, 0.15] - ratios[0.0, 0.3] > 0.05, ratios
    assert ratios[500.0, 0.3] > 0.88, ratios
    assert ratios[500.0, 0.15] - ratios[500.0, 0.3] < 0.05, ratios


@functools.cache
def clay_cube_height_loss(h):
    """A clay cube (6^3 particles, spacing 1 cm, E = 500 kPa, nu = 0.3, phi = 0, c = 2 kPa,
    1800 kg/m^3) thrown at 0.5 m/s onto a frictionless floor 0.1 mm below its margin, no
    gravity, 30 iterations a step: its height's permanent loss (%, top and bottom layers'
    mean heights, averaged over the last 20 ms of 0.1 s) after a step of ``h`` (s)."""
    k = np.arange(6)
    x = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3) * S
    x[:, 2] += 0.5 * S + 1e-4
    cube = pd.Particles(x, spacing=S, density=1800.0, material=pd.Elastic.from_young(5e5, 0.3),
                        plasticity=pd.DruckerPrager(friction_angle=0.0, cohesion=2e3))
    cube.velocities = np.tile([0.0, 0.0, -0.5], (len(x), 1))
    s = pd.Solver(dt=h, gravity=(0.0, 0.0, 0.0), max_iters=30)
    s.add(cube)
    s.add_collider(pd.Plane(friction=0.0))
    top, bottom = x[:, 2] > x[:, 2].max() - 0.5 * S, x[:, 2] < x[:, 2].min() + 0.5 * S
    steps, last = int(round(0.1 / h)), int(round(0.02 / h))
    heights = []
    for i in range(steps):
        s.step()
        if i >= steps - last:
            p = cube.positions
            heights.append(p[top, 2].mean() - p[bottom, 2].mean())
    return 100.0 * (1.0 - np.mean(heights) / (x[top, 2].mean() - x[bottom, 2].mean()))


def test_a_clay_cubes_set_converges_once_the_step_resolves_the_impact_wave():
    """The clay cube's permanent height loss at h = 1/6400 and 1/12800 s agrees within 8 %
    (measured 3.40 and 3.55 %; 3.65 % at 1/25600, converging as about h^0.6; the return after
    the iterations gave 2.73 and 3.14 %, 13 % apart, at commit 9a5b307, which fails it): steps of a
    quarter and an eighth of the time an elastic wave takes to cross a spacing,
    s / sqrt(E / rho) = 0.6 ms. Some set, less than the rigid-plastic estimate (the kinetic
    energy over the yield stress 2c: 5.6 %)."""
    fine, finer = clay_cube_height_loss(1 / 6400), clay_cube_height_loss(1 / 12800)
    assert 1.0 < fine < 5.6 and 1.0 < finer < 5.6, (fine, finer)
    assert abs(fine - finer) < 0.08 * finer, (fine, finer)


@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="open (issue 39): at steps longer than the impact wave's crossing of "
                   "a spacing (0.6 ms) the set depends on the step: 0, 1.31, 2.76 % at h = "
                   "1/100, 1/400, 1/1600 s against 3.40-3.65 % at 1/6400-1/25600 (the same "
                   "with the direct solver to 1e-9: not the iterations), with the return "
                   "within the local step; implicit Euler damps the impact's stress wave "
                   "(docs/particles/plasticity.md)")
def test_a_clay_cubes_set_does_not_depend_on_a_long_step():
    """At h = 1/400 and 1/1600 s the clay cube's set is within 8 % of its set at 1/6400."""
    fine = clay_cube_height_loss(1 / 6400)
    for h in (1 / 400, 1 / 1600):
        assert abs(clay_cube_height_loss(h) - fine) < 0.08 * fine, h


def clay_balls_colliding(friction_angle, steps=60):
    """Two clay balls (a 9^3 lattice cut to a radius of 4 spacings, E 1e5 Pa, nu 0.3, cohesion
    500 Pa) meet head-on at 1 m/s each without gravity, h = 1/200 s (notebook 04): the left
    ball's extent along the impact over its extent across it, and its fastest particle (m/s)."""
    g = np.arange(-4, 5) * S
    x = np.stack(np.meshgrid(g, g, g, indexing="ij"), -1).reshape(-1, 3)
    ball = x[np.linalg.norm(x, axis=1) <= 4 * S + 1e-9]
    solver = pd.Solver(dt=1 / 200, gravity=(0.0, 0.0, 0.0), max_iters=30)
    bodies = []
    for side in (-1, 1):
        body = pd.Particles(ball + [side * 0.05, 0.0, 0.0], spacing=S, density=1000.0,
                            material=pd.Elastic.from_young(E, NU),
                            plasticity=pd.DruckerPrager(friction_angle=friction_angle,
                                                        cohesion=500.0))
        body.velocities = np.tile([-side * 1.0, 0.0, 0.0], (len(ball), 1))
        solver.add(body)
        bodies.append(body)
    for _ in range(steps):
        solver.step()
    x, v = bodies[0].positions, bodies[0].velocities
    return np.ptp(x[:, 0]) / np.ptp(x[:, 1]), np.abs(v).max()


@pytest.mark.parametrize("friction_angle", [0.0, 0.001])
def test_colliding_clay_balls_keep_a_dent_without_diverging(friction_angle):
    """Issue 40, round v: the frictionless cone's rest-volume return (friction_angle 0) made
    the notebook's two clay balls diverge (residual 1.9e7 at step 25, DivergenceError at 40):
    the impact squeezes the balls' rims into flat discs whose det F measures the flattening,
    and the volume ratio R there ratcheted (1.0 to 1.5 over steps 9-17, then 5, 10, 517). With
    the kept mean moved at most 1 % per return from eq. 18's (`KEPT_CORRECTION`) both cones
    stay finite and slow (every speed below the 1 m/s of the approach, within 1.5x) and keep
    a set: the ball ends flatter than the elastic one (1.02) by far, below 0.9."""
    ratio, speed = clay_balls_colliding(friction_angle)
    assert np.isfinite(ratio) and speed < 1.5, (ratio, speed)
    assert ratio < 0.9, ratio


def test_an_elastic_body_reports_no_plastic_phases():
    body = bar(None)
    s = pd.Solver(dt=0.01)
    s.add(body)
    t = s.step().timings
    assert t["plasticity"] == 0.0 and t["neighbours"] == 0.0
    assert body.plasticity is None and body.yield_state() is None


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(friction_angle=-1.0, cohesion=10.0), "friction_angle must be an angle in [0, 90) degrees, got -1"),
        (dict(friction_angle=90.0, cohesion=10.0), "friction_angle must be an angle in [0, 90) degrees, got 90"),
        (dict(friction_angle=float("nan"), cohesion=10.0), "friction_angle"),
        (dict(friction_angle=30.0, cohesion=-2.0), "cohesion must be a stress >= 0 Pa, got -2"),
        (dict(friction_angle=0.0, cohesion=0.0), "cohesion = 0 Pa with friction_angle = 0"),
        (dict(friction_angle=30.0, cohesion=1.0, hardening=-3.0), "hardening must be a modulus >= 0 Pa, got -3"),
        (dict(friction_angle="steep", cohesion=1.0), "friction_angle must be a real number"),
    ],
)
def test_bad_plastic_parameters_are_value_errors_naming_the_value(kwargs, needle):
    with pytest.raises(ValueError) as err:
        pd.DruckerPrager(**kwargs)
    assert needle in str(err.value)


def test_plasticity_must_be_a_drucker_prager():
    with pytest.raises(ValueError, match="plasticity must be None or a peridyn.DruckerPrager, got float"):
        bar(1.0)


def bond_pairs(body):
    """A plastic body's bond pattern: its reference bonds' CSR offsets and neighbours."""
    bonds = body.rest_bonds
    return bonds["offsets"].copy(), bonds["neighbours"].copy()


def test_the_direct_solver_refactors_a_flowing_bar_on_its_pattern():
    """A perfectly plastic bar (phi = 0, yield strain 0.05 %, hardening 500 Pa) pulled as the
    soft bar is, with ``global_solver="direct"`` and its neighbourhoods kept
    (``rebuild_neighbours=False``): its bonds are born again after every step it flows
    (``PlasticLaw::reanchor``), which changes the global matrix's values on the same pattern.
    The direct solver analyses the pattern once, on the first step, and refactors numerically
    (one factorisation or more) on every later step, so that each solve is exact for the
    matrix of the current bonds (the Rust test ``direct_tests`` measures that residual at
    rounding). Until issue 38's round z such a step dropped the solver and analysed anew (an
    analysis on every step), and the step's factorisations went uncounted (0 reported)."""
    body = bar(pd.DruckerPrager(friction_angle=0.0, cohesion=50.0, hardening=500.0,
                                rebuild_neighbours=False))
    pinned, top = pinned_ends(body)
    body.pin(pinned)
    s = pd.Solver(dt=0.02, gravity=(0.0, 0.0, 0.0), max_iters=60, global_solver="direct")
    s.add(body)
    rest, span = body.rest_positions, (LENGTH - 1) * S
    pattern = None
    for k in range(1, 16):
        targets = rest[pinned].copy()
        targets[top, 2] += SOFT_PULL * k * span
        body.pin_targets = targets
        stats = s.step()
        counts = stats.particles["analyses"], stats.particles["factorizations"]
        if k == 1:
            assert counts[0] == 1, counts
        else:
            assert counts[0] == 0 and counts[1] >= 1, (k, counts)
            offsets, neighbours = bond_pairs(body)
            assert np.array_equal(offsets, pattern[0]), k
            assert np.array_equal(neighbours, pattern[1]), k
        pattern = bond_pairs(body)
    flowed = body.rest_bonds["plastic_strain"].max()
    assert flowed > 0.01, flowed
