"""Granular particle bodies: dry and wet sand (He et al. 2017, section 7, eq. 25-28; issue
39), at small sizes: a column's collapse against Lube et al. 2004, the deposit's slope
against the friction angle, the angle of repose measured by tilting a layer, wet sand
standing taller than dry, a pile held by static friction and creeping without, sand poured
into a pile, sand kept out of colliders, threads bit-identical, bad input."""


import numpy as np
import pytest

import peridyn as pd

S = 0.01  # lattice spacing (m)
RHO = 1600.0  # reference density of the packed sand (kg/m^3)
DT = 1.0 / 500.0  # s (the paper steps its sand at 1/500 s)


def column(radius, height, material):
    """A cylinder of sand of ``radius`` and ``height`` (m) standing on the plane z = 0, its
    lowest layer half a spacing above it (the particles' margin)."""
    n = int(round(radius / S))
    layers = int(round(height / S))
    g = np.arange(-n, n + 1) * S
    x, y, z = np.meshgrid(g, g, (np.arange(layers) + 0.5) * S, indexing="ij")
    p = np.stack([x, y, z], -1).reshape(-1, 3)
    p = p[np.hypot(p[:, 0], p[:, 1]) <= radius + 1e-9]
    return pd.Particles(p, spacing=S, density=RHO, material=material)


def ground_solver(**kwargs):
    s = pd.Solver(dt=DT, max_iters=kwargs.pop("max_iters", 10), tol=0.0, **kwargs)
    s.add_collider(pd.Plane(friction=0.3))
    return s


def settle(body, seconds, **kwargs):
    s = ground_solver(**kwargs)
    s.add(body)
    for _ in range(int(round(seconds / DT))):
        stats = s.step()
    return s, stats


def runout(body):
    """The deposit's radius (m): the 98th percentile of the particles' distances from the
    axis."""
    p = body.positions
    return np.percentile(np.hypot(p[:, 0], p[:, 1]), 98)


def sand(angle=30.0, **kwargs):
    return pd.Granular(friction_angle=angle, **kwargs)


def slope_angle(body):
    """The deposit's mean surface slope (degrees): a straight line through the highest
    particle of each ring of one spacing's width from the axis out to the deposit's radius,
    fitted by least squares on the rings that hold particles above the first layer."""
    p = body.positions
    r = np.hypot(p[:, 0], p[:, 1])
    rings = np.floor(r / S).astype(int)
    tops = np.array([[k * S, p[rings == k, 2].max()] for k in np.unique(rings)])
    tops = tops[tops[:, 1] > 1.5 * S]
    slope = -np.polyfit(tops[:, 0], tops[:, 1], 1)[0]
    return np.degrees(np.arctan(slope))


def test_a_column_collapse_runs_out_as_lube_et_al_2004_found():
    """An axisymmetric column of dry sand (R = 6 cm, six spacings; a = H / R = 1, friction
    angle 30 degrees) on a rough plane spreads to `dR / R = 1.24 a` (Lube et al. 2004,
    a < 1.7), within 25 %. Measured 1.21 with the return within the local step (1.14 and
    1.21 at 20 and 40 degrees); 0.45 when the return ran once after the iterations, the
    bonds' within-step viscosity ~ K_f h / 6 holding the sand back (docs/particles/granular.md)."""
    radius, a = 0.06, 1.0
    body = column(radius, a * radius, sand(30.0))
    settle(body, 0.5)
    spread = (runout(body) - radius) / radius
    assert abs(spread / (1.24 * a) - 1.0) < 0.25, spread


SLOPES = ("measured deposit slopes 4.8, 6.2 and 7.1 degrees at friction angles 20, 30 and 40 "
          "(runouts 1.14, 1.21, 1.21, as Lube's law has it): the column's middle falls from "
          "6 cm to 2.5-2.9 cm (Lube et al. find the height kept for a < 1.15). The grains' "
          "repulsion (balls of half a spacing, frictionless) carries the weight, not the bonds: "
          "in the deposit's middle the bonds' mean pressure I1 / 3 is 31, 56, 48, 58 Pa where "
          "the weight above is 417, 310, 187, 94 Pa, so the cone's strength B I1 is a fraction "
          "of what the friction angle gives (docs/particles/granular.md, records the "
          "remedies tried: contact pressure in the yield test; a contact distance below the "
          "spacing; contact friction, with and without a slip speed; eq. 28 on slow yielded "
          "grains; round v: the column jittered by 0.1 spacings, as the repose test's "
          "packing, seeds 0-2, contact friction 0.1, 0.3, 1 tan(phi): slopes 8-13 unordered "
          "with runouts 1.06-1.31; 11-26 ordered but 13-21 below phi at 30 and 40 with "
          "runouts 0.69-0.91; the column standing: none gives the slopes with Lube's "
          "runout; round aa, on jittered columns: the contacts' Love-Weber pressure in the "
          "cone, 4.7-10.9 unordered, settled packings standing far beyond phi; a one-sided "
          "density constraint holding the grains apart, its pressure in the cone, -2.6 to 4.4 "
          "(docs/particles/granular_pressure.md, granular_incompressible.md))")


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=SLOPES)
def test_the_deposit_slope_grows_with_the_friction_angle():
    """Columns (R = 6 cm, a = 1) of sand with friction angles 20, 30 and 40 degrees: the
    deposit's slope grows with the angle, by more than 4 degrees over the range, as a
    Drucker-Prager continuum's does at this size (Taichi MLS-MPM on the same sites,
    benches/collapse_deposit.py: 6.9, 9.7, 11.9 degrees, +5.0; +9.6 at 0.5 cm). The flank of
    a collapse deposit is not the angle of repose (at a = 1 Lube et al. find the deposit
    independent of the material); the issue's angle of repose is measured by tilting a layer
    (test_the_angle_of_repose_lies_within_10_degrees_of_the_friction_angle). No test asks the
    flank to lie within 10 degrees of the angle: the continuum's lies 13-28 degrees below it
    at this size and 7-18 below at a quarter of the spacing (docs/particles/performance.md,
    "The collapse deposit beside a Drucker-Prager continuum")."""
    slopes = deposit_slopes()
    assert slopes[0] < slopes[1] < slopes[2], slopes
    assert slopes[2] - slopes[0] > 4.0, slopes


def deposit_slopes():
    """The deposit slopes (degrees) of the columns at 20, 30 and 40 degrees."""
    slopes = []
    for angle in (20.0, 30.0, 40.0):
        body = column(0.06, 0.06, sand(angle))
        settle(body, 0.5)
        slopes.append(slope_angle(body))
    return slopes


def layer_moves(tilt, jitter=0.0, seed=0, window=0.3, layers=4, **material):
    """A layer of 12 x 6 x ``layers`` spacings (``material``: the ``Particles`` keywords) on a base
    layer of the same body pinned on the floor (a floor as rough as the material) filling an
    open box of frictionless walls, settled for 0.3 s under vertical gravity, then stepped for
    ``window`` (s) with gravity turned by ``tilt`` degrees about y (the box tilted, +x
    downhill) by a new solver (the grains' contact friction starting from 0); untilted, the
    same solver steps on. With ``jitter`` every site, the base layer's too, is first moved by an offset
    drawn (``seed``) uniform in a ball of ``jitter`` spacings: a disordered packing. Returns the
    surface layer's mean move (m) over the last 0.1 s of the window and the largest move of any
    particle over the whole window (m)."""
    nx, ny, nz = 12, 6, layers
    x, y, z = np.meshgrid((np.arange(nx) + 0.5) * S, (np.arange(ny) + 0.5) * S,
                          (np.arange(nz + 1) + 0.5) * S, indexing="ij")
    p = np.stack([x, y, z], -1).reshape(-1, 3)
    if jitter:
        rng = np.random.default_rng(seed)
        direction = rng.standard_normal(p.shape)
        direction /= np.linalg.norm(direction, axis=1)[:, None]
        p = p + direction * (jitter * S * rng.random(len(p)) ** (1.0 / 3.0))[:, None]
    body = pd.Particles(p, spacing=S, density=RHO, **material)
    body.pin(np.flatnonzero(p[:, 2] < S))
    length, width, t = nx * S, ny * S, 0.01
    walls = [pd.Box(center=(c, width / 2, 0.1), half_extents=(t, width / 2 + 2 * t, 0.1))
             for c in (-t, length + t)]
    walls += [pd.Box(center=(length / 2, c, 0.1), half_extents=(length / 2 + 2 * t, t, 0.1))
              for c in (-t, width + t)]

    def solver(tilt):
        b = np.radians(tilt)
        gravity = (9.81 * np.sin(b), 0.0, -9.81 * np.cos(b))
        s = pd.Solver(dt=DT, max_iters=10, tol=0.0, gravity=gravity)
        s.add_collider(pd.Plane(friction=0.3))
        for wall in walls:
            s.add_collider(wall)
        s.add(body)
        return s

    s = solver(0.0)
    for _ in range(int(round(0.3 / DT))):
        s.step()
    surface = body.positions[:, 2] > body.positions[:, 2].max() - 0.5 * S
    if tilt:
        s = solver(tilt)
    start = body.positions.copy()
    for _ in range(int(round((window - 0.1) / DT))):
        s.step()
    last = body.positions.copy()
    for _ in range(int(round(0.1 / DT))):
        s.step()
    largest = np.linalg.norm(body.positions - start, axis=1).max()
    return np.linalg.norm(body.positions - last, axis=1)[surface].mean(), largest


def tilted_layer(tilt, **kwargs):
    """The angle of repose as it is defined, the steepest slope at which the material stands
    at rest, measured by tilting a box (`layer_moves`, 0.3 s after the tilt): the surface
    layer's mean move (m) over the last 0.1 s."""
    return layer_moves(tilt, **kwargs)[0]


def disordered_sand(angle):
    """The repose tests' sand: friction angle ``angle`` (degrees) and contact friction
    ``0.1 tan(angle)`` (a fifth of what the slab of `test_grain_contact_friction_follows_coulomb`
    shows to follow Coulomb: the grains cannot roll, so frictional contacts hold far more than
    the friction angle)."""
    return sand(angle, contact_friction=0.1 * np.tan(np.radians(angle)))


def test_the_angle_of_repose_lies_within_10_degrees_of_the_friction_angle():
    """Issue 39: sand's angle of repose, the steepest slope at which it stands at rest, lies
    within 10 degrees of its friction angle at 20, 30 and 40 degrees: a disordered packing
    (`layer_moves`, sites jittered by 0.1 spacings, seed 1) of `disordered_sand` tilted 10
    degrees less than its friction angle is at rest (its surface moves less than 0.01 mm in
    the last 0.1 s of 0.3 s), tilted 10 degrees more it flows (more than 0.05 mm), as the
    Drucker-Prager continuum of the next test does; so the angle grows with the friction
    angle (at 30 degrees tilt the 20-degree sand flows and the 40-degree one stands).
    Measured, seeds 0 to 4 (docs/particles/granular.md, round t): at rest 0.0 to 0.0003
    mm, flowing 8 to 17 mm (seed 1: 0.0002, 0.00007, 0.00009 and 9.9, 12.7, 10.8 mm; with
    round u's static friction 0.0 mm at rest and 14.1, 18.9, 13.8 mm flowing). Without
    contact friction the packing fails on seeds 1, 2 and 4 (seed 1: 1.1 mm at 10 degrees for
    the 20-degree sand, 7.4 mm at 30 for the 40-degree one), and the perfect lattice jams
    (0.0 mm at 30, 40 and 50 degrees, static friction holding every grain)."""
    for angle in (20.0, 30.0, 40.0):
        material = dict(material=disordered_sand(angle), jitter=0.1, seed=1)
        assert tilted_layer(angle - 10.0, **material) < 1e-5, angle
        assert tilted_layer(angle + 10.0, **material) > 5e-5, angle


def test_a_disordered_frictional_layer_at_rest_stays_at_rest():
    """The repose test's packing (`layer_moves`, jitter 0.1 spacings, seed 0) of
    `disordered_sand` at 20, 30 and 40 degrees, settled 0.3 s and stepped 0.5 s more by the
    same solver: no particle moves by 1e-3 of a spacing (10 um). Static friction (eq. 28)
    holds a grain whose bonds yield when its contacts can take back its sideways move
    (src/solve/particles/static_friction.rs). Measured: 0.0, 0.0, 0.0 um (seeds 0 to 4: 14
    of 15 below 10 um, the other 10.4 um); holding only the grains that did not yield, 3.8,
    5.1, 24.7 um. With contact friction `tan(angle)`: 0.0, 0.0, 0.0 um (round t's rule, the
    contacts' relative slip: 18, 467, 40 um; docs/particles/granular.md, rounds t, u)."""
    for angle in (20.0, 30.0, 40.0):
        _, largest = layer_moves(0.0, jitter=0.1, seed=0, window=0.5,
                                 material=disordered_sand(angle))
        assert largest < 1e-3 * S, (angle, largest)


def test_a_perfect_lattice_frictional_column_collapses():
    """The hold of a yielded grain by its contacts (the previous test) must not make a column
    stand: a perfect-lattice column (R = 6 cm, a = 1, as in the collapse test) of
    `disordered_sand` at 30 and 40 degrees spreads by more than half its radius in 0.5 s.
    Its stacked grains move together, so a test of their relative slip held every yielded
    grain from the first step (round t: runout 0.01 and 0.00). Measured 0.79 and 0.77
    (holding only the grains that did not yield: 0.84 and 0.74; with its frictionless
    contacts the collapse test's Lube band holds, 1.21; docs/particles/granular.md,
    round u)."""
    radius = 0.06
    for angle in (30.0, 40.0):
        body = column(radius, radius, disordered_sand(angle))
        settle(body, 0.5)
        spread = (runout(body) - radius) / radius
        assert spread > 0.5, (angle, spread)


def test_a_drucker_prager_continuum_stands_within_10_degrees_of_its_friction_angle():
    """The measurement's control: a continuum with the same Drucker-Prager cone and no
    cohesion (`Elastic` E = 100 kPa, nu = 0.35, `DruckerPrager(c = 0)`: no grains, no
    repulsion) in `tilted_layer` is at rest (less than 0.01 mm in the last 0.1 s) tilted 10
    degrees less than its friction angle and still moves (more than 0.05 mm) tilted 10 degrees
    more, at 20 and 40 degrees. Measured: 0.0 mm at 10, 20 and 30 degrees tilt (friction
    angles 20, 30, 40), and 0.134, 0.089 and 27.7 mm at 30, 40 and 50 (at friction angle 20:
    0.0, 0.0001, 0.011, 0.134, 1.1 and 32 mm at 15, 20, 25, 30, 35, 40 degrees): the test tells
    a 20-degree material (0.134 mm at 30) from a 40-degree one (0.0 mm at 30). An infinite slope
    on the inner cone, `tan(beta) = 3 B` under isotropic stress, stands to 19.5, 26.3 and 31.4
    degrees; the box's walls add to that."""
    for angle in (20.0, 40.0):
        material = dict(material=pd.Elastic.from_young(1e5, 0.35),
                        plasticity=pd.DruckerPrager(friction_angle=angle, cohesion=0.0))
        assert tilted_layer(angle - 10.0, **material) < 1e-5, angle
        assert tilted_layer(angle + 10.0, **material) > 5e-5, angle


def test_wet_sand_stands_taller_than_dry():
    """A column (R = 6 cm, a = 1) dry and at water saturations 0.2 and 0.4 (Fig. 11), 0.3 s
    after its release: the wetter, the taller the deposit (the 95th percentile of the
    heights), the wettest more than a spacing taller than the dry one: the capillary cohesion
    holds them. Measured 20.5, 23.7 and 40.1 mm. The defaults' capillary cohesion
    `c = sigma_t tan(phi)` is 21 Pa at 0.2 and 30 Pa at 0.4, cohesion lengths `c / (rho g)` of
    1.3 and 1.9 mm (a vertical cut stands 9 and 13 mm by Rankine), so at 0.2 the deposit
    stands a few millimetres above the dry one, not a spacing. (With the return once after the
    iterations the bonds' within-step viscosity held all three up: 37.4, 54.5, 54.6 mm; both
    wet ones were then asserted a spacing above the dry one.)"""
    heights = []
    for theta in (0.0, 0.2, 0.4):
        body = column(0.06, 0.06, sand(30.0, saturation=theta))
        settle(body, 0.3)
        heights.append(np.percentile(body.positions[:, 2], 95))
    assert heights[0] + 0.2 * S < heights[1] < heights[2], heights
    assert heights[2] > heights[0] + S, heights


def test_a_pile_at_rest_stays_at_rest_with_static_friction():
    """A low column (R = 4 cm, a = 0.5) settled for 0.4 s, then 0.06 s more: with static
    friction (eq. 28) no particle moves by more than a micrometre, and every particle under
    the surface layer is held at every step. The surface layer sits at the apex of the
    friction cone (strengths 0.01 to 2 Pa): how many of its 49 particles keep yielding, and so
    are not held, is set by round-off: 0 to 15, the initial lattice perturbed by 1e-9 m
    turning 0 into 15 and back, with either global iteration of issue 38."""
    body = column(0.04, 0.02, sand(30.0))
    s, _ = settle(body, 0.4)
    before = body.positions.copy()
    surface = before[:, 2] > before[:, 2].max() - 0.5 * S
    moved = np.zeros(body.num_particles, dtype=bool)
    for _ in range(30):
        last = body.positions.copy()
        stats = s.step()
        moved |= np.any(body.positions != last, axis=1)
    assert not moved[~surface].any(), np.flatnonzero(moved & ~surface)
    assert stats.particles["held_static"] >= np.count_nonzero(~surface)
    assert np.linalg.norm(body.positions - before, axis=1).max() < 1e-6


def stepped_pile(eta, seed):
    """The creep test's pile: a low column (R = 4 cm, a = 0.5: two layers on a frictional
    floor) with static friction ``eta`` (None: none), its lattice perturbed by 1e-9 m (normal
    draws of ``seed``), settled for 0.4 s at the default 10 iterations a step, then stepped
    by 4 iterations a step: 0.1 s, and a window of 0.2 s more. Returns each particle's move
    over the window (m), whether it moved at any step of it, and the held count at each."""
    body = column(0.04, 0.02, sand(30.0, static_friction=eta))
    rng = np.random.default_rng(seed)
    body.positions = body.positions + 1e-9 * rng.standard_normal(body.positions.shape)
    settle(body, 0.4)
    s = ground_solver(max_iters=4)
    s.add(body)
    for _ in range(50):
        s.step()
    start = body.positions.copy()
    moved = np.zeros(body.num_particles, dtype=bool)
    held = []
    for _ in range(100):
        last = body.positions.copy()
        held.append(s.step().particles["held_static"])
        moved |= np.any(body.positions != last, axis=1)
    return np.linalg.norm(body.positions - start, axis=1), moved, held


def test_a_pile_creeps_without_static_friction_and_comes_to_rest_with_it():
    """A settled low pile stepped short of convergence (4 iterations, as the paper's few)
    comes to rest with static friction (eq. 28) and creeps on without it. Over the window
    0.1 to 0.3 s after the switch to 4 iterations, with static friction no particle moves at
    any step and every particle is held at every step; without it the largest move exceeds
    2 um. Measured over the unperturbed lattice and 30 draws of a 1e-9 m perturbation (seeds
    0 to 29): with static friction every draw at rest over the window, every particle held
    (before it, the largest move 0 to 16.6 um, draw 2); without, the largest move over the
    window 9.8 um (draw 2, at rest by 0.3 s) to 17.0 mm (draw 9), the mean 0.29 um to 2.8
    mm, 37 to 92 of the 98 particles moving: how far the free pile creeps is chaotic, that it
    creeps over the window is not. The test runs draws 2 (the closest to failing on both
    counts) and 23 (the next smallest free move, 67 um). At 3 iterations the free pile
    flows (largest move 15 to 17 mm over the window, 20 draws) but with static friction one
    draw in ten to thirty flows as well (eta 0.8, 0.65, 0.5); with the gravity tilted 5 or
    10 degrees static friction holds 50 to 98 of the 98 particles; at 4 iterations a taller
    pile (a = 0.75) moves up to 4.8 mm with static friction (docs/particles/granular.md)."""
    for seed in (2, 23):
        window, moved, held = stepped_pile(0.8, seed)
        assert not moved.any(), (seed, np.flatnonzero(moved))
        assert min(held) == len(moved), (seed, held)
        window, moved, held = stepped_pile(None, seed)
        assert window.max() > 2e-6, (seed, window.max())


def test_sand_does_not_pass_through_colliders():
    """A block of sand dropped on a sphere standing on the ground: every particle keeps its
    margin (half a spacing) from the sphere and the plane, to 1 % of it, at every step."""
    g = (np.arange(8) - 3.5) * S
    p = np.stack(np.meshgrid(g, g, np.arange(6) * S + 0.09, indexing="ij"), -1).reshape(-1, 3)
    body = pd.Particles(p, spacing=S, density=RHO, material=sand(30.0))
    s = ground_solver()
    center, radius = np.array([0.0, 0.0, 0.04]), 0.04
    s.add_collider(pd.Sphere(center=tuple(center), radius=radius, friction=0.3))
    s.add(body)
    for _ in range(40):
        s.step()
        y = body.positions
        assert y[:, 2].min() >= 0.5 * S * 0.99
        assert (np.linalg.norm(y - center, axis=1) - radius).min() >= 0.5 * S * 0.99


def slab_on_pinned_sand(mu, tan_theta, steps=20):
    """A sand slab (3 x 3 x 2 spacings) resting on a pinned sand bed (7 x 7 x 2) under gravity
    tilted by `theta` from the vertical, both with the contact friction `mu` and no static
    friction: the slab's mean move along the slope (m) after `steps` steps from rest."""
    mat = sand(30.0, static_friction=None, contact_friction=mu)
    g = np.arange(-3, 4) * S
    bed = np.stack(np.meshgrid(g, g, [-S, 0.0], indexing="ij"), -1).reshape(-1, 3)
    g = np.arange(-1, 2) * S
    top = np.stack(np.meshgrid(g, g, [S, 2 * S], indexing="ij"), -1).reshape(-1, 3)
    bed, slab = (pd.Particles(p, spacing=S, density=RHO, material=mat) for p in (bed, top))
    bed.pin(np.arange(bed.num_particles))
    theta = np.arctan(tan_theta)
    s = pd.Solver(dt=DT, max_iters=10, tol=0.0,
                  gravity=(9.81 * np.sin(theta), 0.0, -9.81 * np.cos(theta)))
    s.add(bed)
    s.add(slab)
    for _ in range(steps):
        s.step()
    return np.mean(slab.positions[:, 0] - top[:, 0])


def test_grain_contact_friction_follows_coulomb():
    """Coulomb friction at the grains' contacts (mu_c = 0.3; src/solve/particles/
    grain_friction.rs): a sand slab on a pinned sand bed under gravity tilted by theta. Beyond
    the friction cone (tan theta = 2 mu_c) it slides with the acceleration
    g (sin theta - mu_c cos theta), half the frictionless one: the ratio of its move to the
    frictionless slab's over 20 steps is 0.5 within 15 % (measured 0.55: the slab runs down
    the bumps of the bed's lattice, which the frictionless slab does too). Inside the cone
    (tan theta = mu_c / 2) it moves less than a tenth of the frictionless slab (measured 6 %,
    92 um against 1.44 mm: the slab shears on its own pair springs, and its lowest layer still
    creeps 2 um a step, at any number of iterations)."""
    mu = 0.3
    sliding = slab_on_pinned_sand(mu, 2.0 * mu) / slab_on_pinned_sand(0.0, 2.0 * mu)
    assert abs(sliding / (1.0 - 0.5) - 1.0) < 0.15, sliding
    free = slab_on_pinned_sand(0.0, 0.5 * mu)
    held = slab_on_pinned_sand(mu, 0.5 * mu)
    assert free > 1e-3 and 0.0 < held < 0.1 * free, (held, free)


def hopper(half_width, opening, bottom, thickness=0.01):
    """A square tube of inner half-width ``half_width`` (m) standing on a bottom at height
    ``bottom`` (m) with a square opening of half-width ``opening`` (m) in its middle: four
    walls and four bottom plates (boxes ``thickness`` thick), friction 0.3."""
    w, t = half_width, thickness
    boxes = []
    for axis in (0, 1):
        for sign in (-1.0, 1.0):
            centre, half = [0.0, 0.0, bottom + 0.1], [w + 2 * t, w + 2 * t, 0.1]
            centre[axis], half[axis] = sign * (w + t), t
            boxes.append(pd.Box(center=tuple(centre), half_extents=tuple(half), friction=0.3))
            centre, half = [0.0, 0.0, bottom - t], [w + 2 * t, w + 2 * t, t]
            centre[axis], half[axis] = sign * (opening + w + 2 * t) / 2, (w + 2 * t - opening) / 2
            boxes.append(pd.Box(center=tuple(centre), half_extents=tuple(half), friction=0.3))
    return boxes


def test_sand_poured_through_an_opening_forms_a_pile_and_keeps_out_of_the_colliders():
    """Sand poured into a pile: a block of sand (7 x 7 x 6 spacings) in a square hopper whose
    bottom, 5 cm above the ground, has an opening 5 spacings wide, released at rest. It
    leaves through the opening as a stream (a growing share below the bottom at 0.1, 0.3
    and 0.5 s, not all at once; measured 41, 60, 69 %), piles up on the ground under the
    opening (the middle of the deposit stands more than two spacings above its edge, which
    spreads beyond the opening; measured 4.1 cm against one grain, 0.5 cm, at the edge 25 cm
    from the axis: single grains run out along the floor), and no grain comes within 99 % of
    its margin (half a spacing) of the ground or the hopper at any step. (With the return
    after the iterations: 15, 45, 70 % out, 5.0 cm against 1.9 cm, the edge 4.8 cm out.)"""
    bottom, opening = 0.05, 0.025
    g = np.arange(-3, 4) * S
    p = np.stack(np.meshgrid(g, g, bottom + (np.arange(6) + 0.5) * S, indexing="ij"), -1)
    body = pd.Particles(p.reshape(-1, 3), spacing=S, density=RHO, material=sand(30.0))
    s = ground_solver()
    boxes = hopper(0.035, opening, bottom)
    for box in boxes:
        s.add_collider(box)
    s.add(body)
    out = []
    for k in range(250):
        s.step()
        y = body.positions
        assert y[:, 2].min() >= 0.5 * S * 0.99, k
        assert min(b.signed_distance(y).min() for b in boxes) >= 0.5 * S * 0.99, k
        if k in (49, 149, 249):
            out.append(np.mean(y[:, 2] < bottom))
    assert 0.0 < out[0] < out[1] < out[2] < 1.0, out
    pile = body.positions[body.positions[:, 2] < bottom]
    r = np.hypot(pile[:, 0], pile[:, 1])
    middle = pile[r < opening, 2].max()
    edge = np.percentile(r, 98)
    rim = pile[r > edge - S, 2].max()
    assert edge > opening + S and middle > rim + 2 * S, (edge, middle, rim)


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_one_and_two_threads_give_the_same_sand_to_the_bit(mu):
    runs = []
    for threads in (1, 2):
        body = column(0.03, 0.04, sand(30.0, saturation=0.2, contact_friction=mu))
        settle(body, 0.15, threads=threads)
        runs.append(body.positions)
    assert np.array_equal(runs[0], runs[1])


def test_the_granular_phases_are_timed():
    body = column(0.03, 0.03, sand(30.0))
    _, stats = settle(body, 0.03)
    t = stats.timings
    assert t["density"] > 0.0 and t["plasticity"] > 0.0 and t["neighbours"] > 0.0
    assert t["density"] + t["plasticity"] + t["neighbours"] <= t["finish"]
    assert isinstance(body.material, pd.Granular) and body.plasticity is not None


def test_the_stiffness_follows_eq_25_to_27():
    g = sand(30.0, saturation=0.4)
    assert g.stiffness(0.99) > 0.0 and sand(30.0).stiffness(0.99) == 0.0
    assert g.stiffness(1.0) == pytest.approx(g.friction_stiffness + g.cohesion_stiffness)
    assert g.stiffness(0.59) == 0.0


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        (dict(friction_angle=0.0), "friction_angle must be an angle in (0, 90) degrees, got 0"),
        (dict(friction_angle=95.0), "friction_angle must be an angle in (0, 90) degrees, got 95"),
        (dict(friction_angle="steep"), "friction_angle must be a real number"),
        (dict(friction_angle=30.0, saturation=1.5), "saturation must be a water saturation in [0, 1], got 1.5"),
        (dict(friction_angle=30.0, saturation=float("nan")), "saturation"),
        (dict(friction_angle=30.0, friction_stiffness=-1.0), "friction_stiffness must be a finite stiffness > 0 Pa, got -1"),
        (dict(friction_angle=30.0, cohesion_stiffness=-5.0), "cohesion_stiffness must be a finite stiffness >= 0 Pa, got -5"),
        (dict(friction_angle=30.0, cohesion_falloff=0.0), "cohesion_falloff must be a finite coefficient > 0, got 0"),
        (dict(friction_angle=30.0, debonding=2.0), "debonding must be a scale in [0, 1], got 2"),
        (dict(friction_angle=30.0, static_friction=1.5), "static_friction must be a coefficient in (0, 1]"),
        (dict(friction_angle=30.0, friction_hardening=-1.0), "friction_hardening must be a finite coefficient >= 0, got -1"),
        (dict(friction_angle=30.0, contact_friction=-0.5), "contact_friction must be a finite coefficient >= 0, got -0.5"),
        (dict(friction_angle=30.0, rolling_resistance=-0.1), "rolling_resistance must be a finite coefficient >= 0 (or None for none), got -0.1"),
        (dict(friction_angle=30.0, rolling_resistance=float("inf")), "rolling_resistance must be a finite coefficient >= 0 (or None for none), got inf"),
        (dict(friction_angle=30.0, rolling_resistance=0.1), "rolling_resistance 0.1 needs contact_friction > 0"),
    ],
)
def test_bad_granular_parameters_are_value_errors_naming_the_value(kwargs, needle):
    with pytest.raises(ValueError) as err:
        pd.Granular(**kwargs)
    assert needle in str(err.value)


def test_granular_bodies_refuse_other_plasticity_and_thin_shapes():
    x = column(0.02, 0.02, sand()).rest_positions
    with pytest.raises(ValueError, match="plasticity must be None for a peridyn.Granular"):
        pd.Particles(x, spacing=S, density=RHO, material=sand(),
                     plasticity=pd.DruckerPrager(friction_angle=30.0, cohesion=1.0))
    with pytest.raises(ValueError, match="material must be a peridyn.Elastic, peridyn.Granular or peridyn.ViscoelasticFluid, got str"):
        pd.Particles(x, spacing=S, density=RHO, material="sand")
    with pytest.raises(ValueError, match="a peridyn.Granular body is made with peridyn.Particles"):
        pd.Particles.rod(x[:3], spacing=S, radius=S, density=RHO, material=sand())


def test_a_grain_whose_bonds_all_lie_beyond_the_horizon_steps_finite():
    """A particle whose bonds all have weight 0 (born beyond the horizon, as eq. 20's inverse
    map can place a new neighbour at a runout's front) made its surface factor infinite and
    the step diverge; it now adds nothing, and the sand steps on."""
    body = column(0.03, 0.03, sand(30.0))
    bonds = body.rest_bonds
    k = int(np.argmax(body.positions[:, 2]))
    row = slice(bonds["offsets"][k], bonds["offsets"][k + 1])
    bonds["born"][row] = 1.5 * body.horizon
    body.rest_bonds = bonds
    s = ground_solver()
    s.add(body)
    for _ in range(5):
        s.step()
    assert np.isfinite(body.positions).all()


def test_the_direct_solver_refactors_sand_as_its_stiffness_changes():
    """A settling column of dry sand with ``global_solver="direct"``, 40 steps: its stiffness
    ``lam`` (eq. 25-27) is set from the density after every step, which changes the global
    matrix's values. After a step whose neighbourhoods changed (its bond pattern), the next
    step analyses the pattern anew (one analysis); after one whose neighbourhoods stayed it
    refactors numerically on the pattern at hand (no analysis, one factorisation or more), so
    that each direct solve is exact for the current stiffness (the Rust test
    ``direct_tests`` measures that residual at rounding; the factor kept until issue 38's
    round z solved a stale matrix, off by up to 0.4 there: docs/particles/granular.md). Both
    kinds of step occur; one and two threads give the same sand to the bit."""
    runs = []
    for threads in (1, 2):
        body = column(0.03, 0.06, sand(30.0))
        s = ground_solver(global_solver="direct", threads=threads)
        s.add(body)
        kinds = {True: 0, False: 0}
        pattern, changed = None, None
        for k in range(40):
            stats = s.step()
            counts = stats.particles["analyses"], stats.particles["factorizations"]
            if k == 0:
                assert counts[0] == 1, counts
            elif changed is not None:
                assert counts[0] == int(changed) and counts[1] >= 1, (k, changed, counts)
            bonds = body.rest_bonds
            now = bonds["offsets"].copy(), bonds["neighbours"].copy()
            if pattern is not None:
                changed = not (np.array_equal(now[0], pattern[0])
                               and np.array_equal(now[1], pattern[1]))
                kinds[changed] += 1
            pattern = now
        assert kinds[True] > 0 and kinds[False] > 0, kinds
        runs.append(body.positions)
    assert np.array_equal(runs[0], runs[1])


@pytest.mark.parametrize("global_solver", ["direct", "chebyshev"])
def test_a_step_after_positions_are_set_takes_the_stiffness_of_the_new_positions(global_solver):
    """A granular body's stiffness ``lam`` follows its SPH density (eq. 25-27), taken at the
    end of every step for the next. Positions set between steps (squeezed to 0.9 of their
    height) change the density, so the next step takes the stiffness there, as a body built
    at those positions does (its twin, whose ``rest_bonds`` set to themselves make the solver
    build its working set anew): both step to the same bits. Before, the step kept the
    stiffness of the positions the last step ended at."""
    bodies = [column(0.02, 0.04, sand()) for _ in range(2)]
    solvers = [ground_solver(global_solver=global_solver) for _ in bodies]
    for s, body in zip(solvers, bodies):
        s.add(body)
        for _ in range(5):
            s.step()
        body.positions = body.positions * [1.0, 1.0, 0.9]
    bodies[1].rest_bonds = bodies[1].rest_bonds
    for s in solvers:
        s.step()
    assert np.array_equal(bodies[0].positions, bodies[1].positions)
    assert np.array_equal(bodies[0].velocities, bodies[1].velocities)


@pytest.mark.parametrize("global_solver", ["direct", "chebyshev"])
def test_positions_set_on_one_body_leave_another_bodys_stiffness(global_solver):
    """Two sand columns 20 cm apart in one f32 solver; after 5 steps the first's positions
    are set (to themselves). Only that body takes its stiffness anew (eq. 25-27, at its own
    positions, as a body built there does): the second keeps the one the last step ended
    with, and steps to the same bits as in a twin where nothing was set. This held before
    too, when every granular body's stiffness was taken anew from its world positions in
    f64 (the particle frame's origin makes them the solver's f32 positions exactly); the
    test keeps it so."""
    runs = []
    for touch in (False, True):
        s = ground_solver(global_solver=global_solver, precision="f32")
        bodies = [column(0.02, 0.04, sand()), column(0.02, 0.04, sand())]
        bodies[1].positions = bodies[1].positions + [0.2, 0.0, 0.0]
        for body in bodies:
            s.add(body)
        for _ in range(5):
            s.step()
        if touch:
            bodies[0].positions = bodies[0].positions
        for _ in range(2):
            s.step()
        runs.append((bodies[1].positions, bodies[1].velocities))
    assert np.array_equal(runs[0][0], runs[1][0])
    assert np.array_equal(runs[0][1], runs[1][1])
