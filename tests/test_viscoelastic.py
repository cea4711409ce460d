"""Viscoelastic fluids (He et al. 2017, section 6, Fig. 8, 10, 17; issue 40): a fluid body with
``shear_modulus > 0`` is also elastic, with bonds whose rest shape follows the flow beyond its
yield stress. An imposed shear partly springs back where a Newtonian liquid keeps it; honey
under a ceiling of ghost particles keeps a film on it with adhesion (that the blob should neck
before it parts, as a reference MPM's does, is a strict xfail); without adhesion a blob hangs on
exactly when its yield stress carries its weight; threads agree. A bar pulled apart keeps its
volume only with a stiff bulk modulus, and then flows at its yield stress (the return keeps the
particles' rest volume, not their mean bond strain); with a plastic (Bingham) viscosity its flow
stress grows with the rate as Trouton's, and a slowly pulled bar no longer necks."""

import numpy as np
import pytest
from scipy.linalg import polar

import peridyn as pd
from fluid_scenes import blob_under_a_ceiling, hanging_slabs, neck_slabs

S = 0.01  # lattice spacing (m)


def lattice(lo, hi):
    """Cell centres ``(k + 0.5) S`` of the integer box ``lo <= k < hi`` (per axis)."""
    axes = [np.arange(a, b) for a, b in zip(lo, hi)]
    return (np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + 0.5) * S


def shear_strain(x, x0):
    """Engineering shear ``2 U_xz`` of the stretch ``U`` of the best affine map (least
    squares) from ``x0`` to ``x``: rotations of the blob do not count."""
    a, b = x0 - x0.mean(0), x - x.mean(0)
    f = np.linalg.lstsq(a, b, rcond=None)[0].T
    return 2.0 * polar(f)[1][0, 2]


def sheared_blob(gamma, threads=None, **fluid):
    """A free 6 x 6 x 6 blob (no gravity) of density 1000 kg/m^3 and viscosity 1 Pa s whose
    positions are sheared by ``x += gamma z`` from its reference, at rest."""
    x0 = lattice((0, 0, 0), (6, 6, 6))
    body = pd.Particles(x0, spacing=S, density=1000.0,
                        material=pd.ViscoelasticFluid(viscosity=1.0, **fluid))
    x = x0.copy()
    x[:, 0] += gamma * (x0[:, 2] - x0[:, 2].mean())
    body.positions = x
    solver = pd.Solver(dt=0.005, gravity=(0, 0, 0), global_solver="jacobi", threads=threads)
    solver.add(body)
    return body, solver, x0


def shear_history(gamma, steps=100, **fluid):
    body, solver, x0 = sheared_blob(gamma, **fluid)
    out = []
    for _ in range(steps):
        solver.step()
        out.append(shear_strain(body.positions, x0))
    return np.array(out)


def test_a_viscoelastic_blob_springs_back_from_part_of_an_imposed_shear():
    """Over 0.5 s (the mean of the last 0.2 s, across the elastic oscillation): a Newtonian
    blob keeps an imposed shear of 0.5 within 1 % (no restoring force); with G = 500 Pa and
    the default yield stress (= G: a shear of 0.5 stays below yield) the shear springs back to
    within 0.15 of zero; a shear of 1.5, beyond yield, springs back by a part (the final mean
    between 20 % and 80 % of the imposed 2 U_xz) and keeps the rest."""
    x0 = lattice((0, 0, 0), (6, 6, 6))
    imposed = {g: shear_strain(x0 @ np.array([[1, 0, 0], [0, 1, 0], [g, 0, 1]]), x0)
               for g in (0.5, 1.5)}
    newtonian = shear_history(0.5)
    assert abs(newtonian[-40:].mean() / imposed[0.5] - 1.0) < 0.01, newtonian[::10]
    elastic = shear_history(0.5, shear_modulus=500.0)
    assert abs(elastic[-40:].mean()) < 0.15 * imposed[0.5], elastic[::10]
    plastic = shear_history(1.5, shear_modulus=500.0)
    kept = plastic[-40:].mean() / imposed[1.5]
    assert 0.2 < kept < 0.8, (kept, plastic[::10])


def test_threads_are_bit_identical_for_a_viscoelastic_fluid_with_redistribution():
    """1 and 2 threads give the same bits after 20 steps of the sheared blob with
    G = 500 Pa and redistribution (strength 0.5): the elastic kernel, the return and
    neighbour rebuild, the density projection, redistribution and viscosity together."""
    runs = []
    for threads in (1, 2):
        body, solver, _ = sheared_blob(1.5, threads=threads, shear_modulus=500.0,
                                       redistribution=0.5)
        for _ in range(20):
            solver.step()
        runs.append((body.positions.copy(), body.velocities.copy()))
    assert np.array_equal(runs[0][0], runs[1][0])
    assert np.array_equal(runs[0][1], runs[1][1])


def test_the_material_reports_its_parameters():
    honey = pd.ViscoelasticFluid(viscosity=10.0, shear_modulus=50.0, redistribution=0.5)
    assert honey.shear_modulus == 50.0 and honey.yield_stress is None
    assert pd.ViscoelasticFluid(shear_modulus=50.0, yield_stress=20.0).yield_stress == 20.0
    assert "shear_modulus=50" in repr(honey) and "adhesion=False" in repr(honey)
    assert honey.bulk_modulus is None and "bulk_modulus=None" in repr(honey)
    assert pd.ViscoelasticFluid(shear_modulus=50.0, bulk_modulus=400.0).bulk_modulus == 400.0
    assert pd.ViscoelasticFluid(adhesion=True).adhesion
    assert pd.ViscoelasticFluid().shear_modulus == 0.0


def test_the_plastic_viscosity_is_reported_saved_and_checked():
    """``plastic_viscosity`` (Pa s, default 0) is a parameter of the material: reported, in
    the repr, carried by a body's material state (a state written before it loads as 0), and
    a negative or non-finite value is a ValueError naming it."""
    honey = pd.ViscoelasticFluid(shear_modulus=500.0, plastic_viscosity=50.0)
    assert honey.plastic_viscosity == 50.0 and "plastic_viscosity=50" in repr(honey)
    assert pd.ViscoelasticFluid().plastic_viscosity == 0.0
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="plastic_viscosity"):
            pd.ViscoelasticFluid(shear_modulus=500.0, plastic_viscosity=bad)
    x = lattice((0, 0, 0), (3, 3, 3))
    body = pd.Particles(x, spacing=S, density=1400.0, material=honey)
    other = pd.Particles(x, spacing=S, density=1400.0,
                         material=pd.ViscoelasticFluid(shear_modulus=500.0))
    state = body.material_state
    other.material_state = state
    assert other.material.plastic_viscosity == 50.0
    other.material_state = dict(state, fluid=state["fluid"][:12])  # written before it
    assert other.material.plastic_viscosity == 0.0


def layer_area(p, p0):
    """Area (m^2) of a layer of particles ``p`` that started as the lattice layer ``p0`` (S^2
    per particle): its start's times ``sqrt(det C / det C0)``, ``C`` the covariance of the
    particles' horizontal positions, exact for any affine map of the layer. (The hull of the
    centres grown by a fixed half spacing, used until issue 40's round t, reads a 4 x 4 layer
    contracted uniformly to 0.714 of its area as 0.777.)"""
    cov = lambda q: np.linalg.det(np.cov(q[:, :2].T))
    return len(p0) * S * S * np.sqrt(cov(p) / cov(p0))


def pulled_bar(times=(0.1, 0.15, 0.2), rate=2.0, threads=None, precision="f64", **fluid):
    """A bar of 4 x 4 x 16 particles of the honey's material (1400 kg/m^3, 10 Pa s, G = 500 Pa,
    yield stress 500 Pa) between two pinned blocks of two layers pulled apart at
    ``rate`` * 0.08 m/s each (an extension rate of ``rate``, 1/s, at the start; 2/s by
    default), no gravity, dt = 5 ms.
    Returns per time in ``times`` (s) the bar's length over its start's, its free part's volume
    over its start's (layer by layer: ``layer_area`` times the gap to the next layer), its
    narrowest layer's area over its start's, the bonds' axial stress across its middle
    (Pa: the internal forces on the half below over the middle layer's area), and the
    extension rate of its middle over the last five steps (1/s: of the distance between the
    mean heights of layers 6 and 9)."""
    n, length = 4, 16
    k = np.stack(np.meshgrid(np.arange(n), np.arange(n), np.arange(-2, length + 2),
                             indexing="ij"), -1).reshape(-1, 3)
    x = (k + 0.5) * S
    bottom, top = k[:, 2] < 0, k[:, 2] >= length
    bar = pd.Particles(x, spacing=S, density=1400.0,
                       material=pd.ViscoelasticFluid(viscosity=10.0, shear_modulus=500.0,
                                                     yield_stress=500.0, **fluid))
    pins = np.flatnonzero(bottom | top)
    bar.pin(pins)
    solver = pd.Solver(dt=0.005, gravity=(0, 0, 0), global_solver="jacobi", threads=threads,
                       precision=precision)
    solver.add(bar)
    speed = np.where(top[pins], 0.5, -0.5) * rate * length * S
    layers = [k[:, 2] == j for j in range(length)]

    def measure():
        y = bar.positions
        area = np.array([layer_area(y[m], x[m]) for m in layers])
        z = np.array([y[m, 2].mean() for m in layers])
        volume = (0.5 * (area[1:] + area[:-1]) * np.diff(z)).sum()
        force = bar.internal_forces()[k[:, 2] < length // 2, 2].sum()
        stretch = (y[top, 2].min() - y[bottom, 2].max()) / S - 1.0
        return stretch, volume, area.min(), force / area[length // 2], z[9] - z[6]

    start = measure()
    middle = [start[4]]
    out = []
    for step in range(1, int(round(max(times) / 0.005)) + 1):
        bar.pin_targets = x[pins] + np.outer(speed * step * 0.005, [0.0, 0.0, 1.0])
        solver.step()
        middle.append(bar.positions[layers[9], 2].mean() - bar.positions[layers[6], 2].mean())
        if any(abs(step * 0.005 - t) < 1e-9 for t in times):
            now = measure()
            mid_rate = np.log(middle[-1] / middle[-6]) / (5 * 0.005)
            out.append((now[0] / start[0], now[1] / start[1], now[2] / start[2], now[3],
                        mid_rate))
    return np.array(out)


STIFF_BULK = 29.0 / 3.0 * 500.0  # Pa: the largest bulk modulus at G = 500 Pa (nu = 0.45)


def test_a_pulled_viscoelastic_bar_keeps_its_volume_only_with_a_stiff_bulk():
    """Nothing else holds a viscoelastic fluid's volume in tension (its density constraints are
    one-sided, its viscosity a Laplacian): pulled to 1.2, 1.3 and 1.4 times its length, the
    bar with the bulk modulus K = 29 G / 3 keeps its volume within 5 % (measured 0.973, 0.995,
    1.041) and its narrowest layer contracts as a constant volume needs (area within 5 % of the
    inverse stretch or below; measured 0.79, 0.76, 0.71 at 0.83, 0.77, 0.71), while with the
    default, 5 G / 3 = 833 Pa, it dilates by more than 8 % by 1.3 (measured 10.6 %). Why 5 %:
    the return keeps each particle's rest volume (docs/particles/fluids.md, round t), so what
    is left is the elastic dilatation of the bar's mean stress, a third of its axial stress
    (680-720 Pa, `test_..._flows_at_its_yield_stress`) over K: 4.7-5.0 %; the particles'
    own volumes `R det F` mid-bar are 1.04 at 1.4 and 1.5. (With the areas of the hull
    grown by half a spacing, which overstate a contracted layer's, the volumes read 1.020,
    1.093, 1.130; until round t, whose return ratcheted the reference short and resisted the
    flow with a pressure, 1.020-1.022 by that measure.)"""
    stiff = pulled_bar(bulk_modulus=STIFF_BULK)
    assert np.all(np.abs(stiff[:, 1] - 1.0) < 0.05), stiff
    assert np.all(stiff[:, 2] < 1.05 / stiff[:, 0]), stiff
    soft = pulled_bar(times=(0.15,))
    assert soft[0, 1] > 1.08, soft


def test_a_pulled_viscoelastic_bar_with_a_stiff_bulk_flows_at_its_yield_stress():
    """A perfectly plastic bar (no hardening) flows at its yield stress: the bonds' axial
    stress across the middle of the bar with the stiff bulk stays below 1.6 times the yield
    stress (500 Pa) at 1.3 and 1.4 times its length (allowing 1.31 for a bar four particles
    across, whose surface correction stiffens it, and the elastic strain's area change).
    Measured 677 and 688 Pa (719 at 1.2). Until issue 40's round t the return kept each
    particle's mean bond strain, which a large deviatoric strain and an anisotropic
    neighbourhood raise without a change of volume: the excess ratcheted into the reference
    and the bulk modulus resisted the flow as if it hardened (about 2 and 3 times the yield
    stress, by the hull areas then used); until round y the bonds kept the weights and
    springs of their birth lengths while the flow stretched them (748, 791 Pa)."""
    stiff = pulled_bar(bulk_modulus=STIFF_BULK, times=(0.15, 0.2))
    assert np.all(stiff[:, 3] < 1.6 * 500.0), stiff


def test_a_pulled_viscoelastic_bar_with_a_stiff_bulk_flows_at_a_plateau():
    """A perfectly plastic bar flowing at its yield stress keeps its stress: the axial stress
    across the middle of the bar with the stiff bulk at 1.5 times its length is within 10 %
    of that at 1.3 (the elastic strain's area change and the thinning surface allow a few
    per cent). Measured 677 and 679 Pa (688 at 1.4). Until issue 40's round y it hardened,
    748, 791, 933 Pa at 1.3, 1.4, 1.5: the bonds kept since the start kept the weight and
    springs of the length they were born at, so that a bond the flow had stretched from its
    birth length `b` to `L` resisted strain as `w(b) L^2 / b^2` where a fresh bond resists
    as `w(L)` (a nearest neighbour at `L = 1.17 b`, the mid-bar axial bonds' weighted mean
    at 1.5: 1.59 times), and the mid-bar particles' axial stiffness grew to 1.57 times a
    fresh neighbourhood's of the same shape; a flowing body's bonds are now born again at
    their reference lengths after every step (docs/particles/fluids.md, round y)."""
    stiff = pulled_bar(bulk_modulus=STIFF_BULK, times=(0.15, 0.25))
    assert abs(stiff[1, 3] / stiff[0, 3] - 1.0) < 0.1, stiff


def test_a_plastic_viscosity_keeps_a_slowly_pulled_bar_from_necking():
    """Trouton's stress `3 eta_p eps_dot` stabilises a neck: where the bar thins faster it
    carries more. Pulled at 0.5/s (stiff bulk) to 1.6 times its length, the perfectly plastic
    bar necks (its middle's extension rate 1.2 and 1.5/s at 1.35 and 1.4 against the pull's
    0.37 and 0.36) and parts by 1.5 (measured: no stress across the middle at 1.6, volume
    1.27, as Considere's criterion says a perfectly plastic bar in tension must); with
    ``plastic_viscosity`` = 50 Pa s (a relaxation time `eta_p / G` of 0.1 s) it stays whole:
    its middle flows at 0.42/s, its narrowest layer within 10 % of the inverse stretch
    (measured 0.631 at 0.625) and the stress across its middle above the plateau of the bar
    pulled at 2/s (measured 1015 Pa against 646-679 at 1.5-1.6)."""
    plain = pulled_bar(times=(1.2,), rate=0.5, bulk_modulus=STIFF_BULK)
    viscous = pulled_bar(times=(1.2,), rate=0.5, bulk_modulus=STIFF_BULK,
                         plastic_viscosity=50.0)
    assert plain[0, 3] < 50.0, plain
    stretch, _, narrowest, stress, _ = viscous[0]
    assert abs(narrowest * stretch - 1.0) < 0.1 and stress > 700.0, viscous


def test_with_a_plastic_viscosity_the_flow_stress_grows_with_the_rate_as_troutons():
    """A Bingham fluid flows in tension at `sigma_y + 3 eta_p eps_dot` (the return relaxes the
    stress beyond the cone over `eta_p / G`: docs/particles/fluids.md, round z). The bar with
    ``plastic_viscosity`` = 50 Pa s pulled at 0.5 and 2/s, at 1.5 times its length: the stress
    across its middle grows with its middle's extension rate (measured 897 and 1108 Pa at 0.467
    and 1.381/s) by `3 eta_p` times the bonds' stress per cone stress, within 15 %. That ratio
    is the perfectly plastic bar's plateau over its yield stress, 679 / 500 = 1.36 at 2/s (the
    plastic bodies' length-based surface factors stiffen a bar four particles across:
    docs/particles/fluids.md, round y); measured slope 231 Pa s against 3 * 50 * 1.36 = 204,
    1.13 times. (The level is above `1.36 (sigma_y + 3 eta_p eps_dot)` by 15-16 % at both
    rates, 660 and 816 Pa of cone stress against 570 and 707: not asserted. The slope holds
    two departures that partly cancel: the middle's particles carry, by their own measure
    (``yield_state``: `sqrt(J2)` minus the strength), 57 Pa at 0.5/s, 1.41 times Trouton's
    `sqrt(3) eta_p eps_dot` = 40 of the middle's rate, in a steady flow; and at 2/s the bar
    is still within two relaxation times of its yield at 1.5, its overstress rising, 73,
    103, 120, 130, 141 Pa at 1.4-1.6 (1.00 times Trouton's at 1.5). Between 0.5 and 1/s,
    both settled, the slope is 264 Pa s, 1.29 times.) The law itself holds to 1 % in a pinned
    block (`test_a_pinned_block_..._keeps_the_overstress_of_the_law`): the settled excess is
    its measure's, the bonds' RMS strain rate `d`, which in the middle of a bar 4 particles
    across stretched to 1.5 is 1.34 times an isotropic neighbourhood's `sqrt(2/15) |D|` that
    Trouton's stress assumes (lattice and surface). So the settled slope is expected at
    1.3 times Trouton's, and the tested pair's 1.13 is that less the 2/s bar's unsettled
    overstress: the 15 % holds the pair's measured cancellation (a regression of the return
    moves it), not the agreement with Trouton's, which the pinned block tests."""
    plateau = pulled_bar(times=(0.25,), bulk_modulus=STIFF_BULK)[0, 3]
    slow = pulled_bar(times=(1.0,), rate=0.5, bulk_modulus=STIFF_BULK, plastic_viscosity=50.0)
    fast = pulled_bar(times=(0.25,), rate=2.0, bulk_modulus=STIFF_BULK, plastic_viscosity=50.0)
    slope = (fast[0, 3] - slow[0, 3]) / (fast[0, 4] - slow[0, 4])
    expected = 3.0 * 50.0 * plateau / 500.0
    assert abs(slope / expected - 1.0) < 0.15, (slope, expected, slow, fast, plateau)


def bond_rate_rms(y, i, rate, delta):
    """The RMS deviation (1/s) of the strain rates `n^T D n` of particle ``i``'s bonds (at the
    positions ``y``, m, within the horizon ``delta``, weighted by the influence function
    `1 - r / delta`) in the isochoric extension `D = rate diag(-1/2, -1/2, 1)`: the `d` of the
    rate-dependent return's steady overstress `sqrt(15) eta_p d`."""
    v = y - y[i]
    r = np.linalg.norm(v, axis=1)
    m = (r > 0.0) & (r < delta)
    n, w = v[m] / r[m, None], 1.0 - r[m] / delta
    e = rate * (n[:, 2] ** 2 - 0.5 * (n[:, 0] ** 2 + n[:, 1] ** 2))
    mean = (w * e).sum() / w.sum()
    return np.sqrt((w * (e - mean) ** 2).sum() / w.sum())


def pinned_extension(plastic_viscosity, n=8, rate=0.5, steps=120):
    """A block of n^3 particles (G = 5000 Pa, stiff bulk 29 G / 3, yield stress 500 Pa,
    ``plastic_viscosity`` Pa s), every particle pinned and the pins moved affinely by
    `F = exp(D t)`, `D = rate diag(-1/2, -1/2, 1)` (1/s, isochoric) for ``steps`` steps of 5 ms.
    Returns the overstress `sqrt(J2)` minus the strength (Pa), the strength and the bonds' `d`
    (:func:`bond_rate_rms`) of the particles with whole neighbourhoods (two layers in)."""
    k = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), -1).reshape(-1, 3)
    x0 = (k + 0.5) * S
    centre = x0.mean(0)
    block = pd.Particles(x0, spacing=S, density=1000.0, material=pd.ViscoelasticFluid(
        viscosity=1.0, shear_modulus=5000.0, yield_stress=500.0,
        bulk_modulus=29.0 / 3.0 * 5000.0, plastic_viscosity=plastic_viscosity))
    block.pin(np.arange(len(x0)))
    solver = pd.Solver(dt=0.005, gravity=(0, 0, 0), global_solver="jacobi")
    solver.add(block)
    stretch = np.array([-0.5, -0.5, 1.0]) * rate
    for step in range(1, steps + 1):
        block.pin_targets = (x0 - centre) * np.exp(stretch * step * 0.005) + centre
        solver.step()
    y = block.positions
    assert np.array_equal(y, block.pin_targets)
    inner = np.flatnonzero(np.all((k >= 2) & (k <= n - 3), axis=1))
    sqrt_j2, strength = block.yield_state()
    d = np.array([bond_rate_rms(y, i, rate, block.horizon) for i in inner])
    return (sqrt_j2 - strength)[inner], strength[inner], d


def test_a_pinned_block_flowing_at_a_constant_rate_keeps_the_overstress_of_the_law():
    """The rate-dependent return's steady state, without a free surface or a flow of its own:
    a block pinned whole and moved affinely in an isochoric extension at 0.5/s for 0.6 s (6
    relaxation times `tau = eta_p / G` = 0.1 s, to the stretch 1.35). With ``plastic_viscosity``
    = 500 Pa s its 64 inner particles carry the overstress `sqrt(15) eta_p d` of their bonds'
    RMS deviatoric strain rate `d` within 2 % (measured 0.993 of it, 524 Pa; 0.984 at 5
    `tau`: the overstress lags `d`, which grows 2 % per `tau` as the bonds turn toward the
    pull); without, they sit on the cone within 1e-3 of the strength (measured 5.5e-4
    inside, 289 Pa).
    `d` is not `sqrt(2/15) |D|`, an isotropic neighbourhood's: on the lattice an extension
    along an axis gives 1.117 times that at the start (a shear in a lattice plane 0.914), 1.22
    at the stretch 1.35; the middle of a bar 4 particles across pinned likewise, 1.21 at the
    start, 1.30 at 1.35 and 1.34 at 1.5 (the surface adds), where it carries 1.35 times
    Trouton's `sqrt(3) eta_p eps_dot`: the excess of the pulled bar's middle (1.41 times) and
    of its settled slope (1.29 times;
    `test_with_a_plastic_viscosity_the_flow_stress_grows_with_the_rate_as_troutons`)."""
    over, strength, d = pinned_extension(500.0)
    ratio = over / (np.sqrt(15.0) * 500.0 * d)
    assert np.all(np.abs(ratio - 1.0) < 0.02), ratio
    over, strength, _ = pinned_extension(0.0)
    assert np.all(np.abs(over) < 1e-3 * strength), over / strength


def test_a_rate_dependent_return_is_bit_identical_for_threads_and_f32_follows_f64():
    """The bar with ``plastic_viscosity`` = 50 Pa s pulled at 2/s for 30 steps (beyond
    yield from about the 20th): 1 and 2 threads give the same bits; in f32 the stress across
    the middle is within 2 % of f64's (measured 716.3 Pa against 715.5)."""
    runs = [pulled_bar(times=(0.15,), bulk_modulus=STIFF_BULK, plastic_viscosity=50.0,
                       threads=t, precision=p) for t, p in ((1, "f64"), (2, "f64"), (2, "f32"))]
    assert np.array_equal(runs[0], runs[1])
    assert abs(runs[2][0, 3] / runs[0][0, 3] - 1.0) < 0.02, runs


def honey_under_a_ceiling(adhesion, steps=80, yield_stress=500.0):
    """A honey-like blob (5 x 5 x 6 particles, 1400 kg/m^3, 10 Pa s, G = 500 Pa, yield stress
    500 Pa by default: its weight's stress at the top, 1400 * 9.81 * 0.06 = 824 Pa, is beyond
    yield) under a ceiling of two layers of pinned ghost particles of its body, dt = 5 ms.
    Returns the fluid particles' positions after ``steps`` steps and the ceiling's lowest
    layer height (m)."""
    x, ceiling = blob_under_a_ceiling(5, 6, S)
    honey = pd.Particles(x, spacing=S, density=1400.0,
                         material=pd.ViscoelasticFluid(viscosity=10.0, shear_modulus=500.0,
                                                       yield_stress=yield_stress,
                                                       adhesion=adhesion))
    honey.pin(np.flatnonzero(ceiling))
    solver = pd.Solver(dt=0.005, gravity=(0, 0, -9.81), global_solver="jacobi")
    solver.add(honey)
    for _ in range(steps):
        solver.step()
    return honey.positions[~ceiling], x[ceiling, 2].min()


def test_adhesion_holds_a_liquid_film_at_its_ghost_ceiling():
    """After 0.4 s with adhesion, the liquid layer next to the ceiling (its 25 particles)
    stays within 1.3 spacings of the ghosts' lowest layer (its rest distance: 1; measured
    at most 1.04): the ghosts' two-sided density constraints hold it, while the rest of the
    blob, beyond yield, drips off (measured 65 spacings down; it parts from the film along a plane
    before it necks: the strict xfail below)."""
    fluid, ceiling = honey_under_a_ceiling(adhesion=True)
    assert ((ceiling - fluid[:, 2]) < 1.3 * S).sum() == 25


def test_without_adhesion_a_blob_hangs_on_below_its_weights_stress_at_800_pa_and_parts_at_700():
    """Without adhesion the ghosts hold the blob by its bonds alone. With a yield stress of
    800 Pa, below its weight's stress at the top (824 Pa), it hangs on whole: after 0.4 s its
    top layer is within 2 spacings of the ceiling (measured 1.51; 1.45 at 790 Pa, 1.51 at 810)
    and its lowest particle less than 5 spacings below where it started (measured 1.93; 2.01
    at 790 Pa, 1.87 at 810). (Above 824 Pa the blob hangs whatever the model: the yield
    stress must lie below the weight's stress for the hanging to test the flow.) With 700 Pa the top yields and the blob parts from the ceiling: its
    lowest particle more than 10 spacings down (measured 41; 30 at 760 Pa, 49 at 600 Pa).
    At dt = 5 ms the blob parts between 760 and 780 Pa (780 Pa hangs 2.08 spacings down), at
    0.92-0.95 of its weight's stress at the top, 824 Pa. (Until issue 40's round y the bonds
    kept the weights and springs of their birth lengths while the flow stretched them, a
    hardening that held the blob down to 610 Pa, 0.74 of the weight's stress; until round t
    the return kept the mean
    bond strain, whose ratchet hardened the blob: it parted between 500 and 520 Pa at 5 ms
    and between 520 and 600 Pa at 2.5 ms, 0.61-0.73 of the weight's stress. The plastic
    return at the step's end alone, as the paper has it, hung the 500 Pa blob at dt = 5 ms,
    2.2 spacings down, by the elastic overshoot of each step's bonds, and let it fall at
    2.5 and 1.25 ms: docs/particles/plasticity.md.)"""
    low0 = lambda ceiling: ceiling - 6.5 * S
    fluid, ceiling = honey_under_a_ceiling(adhesion=False, yield_stress=800.0)
    assert 0.0 < low0(ceiling) - fluid[:, 2].min() < 5 * S, low0(ceiling) - fluid[:, 2].min()
    assert ceiling - fluid[:, 2].max() < 2 * S
    fluid, ceiling = honey_under_a_ceiling(adhesion=False, yield_stress=700.0)
    assert low0(ceiling) - fluid[:, 2].min() > 10 * S, low0(ceiling) - fluid[:, 2].min()


def hanging_blob_necks_and_parts(material, n=9, seconds=0.2):
    """The blob of `honey_under_a_ceiling` at ``n`` particles across (its 5 x 5 x 6 cm sampled
    at spacing 5 cm / n, round(1.2 n) tall; adhesion, Jacobi, dt 5 ms) of the liquid
    ``material`` (`ViscoelasticFluid` keywords), stepped until it parts from its film or for
    ``seconds``. Returns when it parts (s; None if it hangs on: `fluid_scenes.hanging_slabs`'
    gap of 2.2 spacings) and the longest neck it drew before that (`neck_slabs`, at every
    step)."""
    spacing = 0.05 / n
    x, ceiling = blob_under_a_ceiling(n, round(1.2 * n), spacing)
    honey = pd.Particles(x, spacing=spacing, density=1400.0,
                         material=pd.ViscoelasticFluid(adhesion=True, **material))
    honey.pin(np.flatnonzero(ceiling))
    solver = pd.Solver(dt=0.005, gravity=(0, 0, -9.81), global_solver="jacobi")
    solver.add(honey)
    top, neck = x[ceiling, 2].min(), 0
    for k in range(1, round(seconds / 0.005) + 1):
        solver.step()
        depth = (top - honey.positions[~ceiling, 2]) / spacing
        keep, slab = hanging_slabs(depth)
        if keep.size < depth.size:
            return 0.005 * k, neck
        neck = max(neck, neck_slabs(np.bincount(slab), n * n))
    return None, neck


NECK = ("open (issue 40): the blob parts along a plane under its film before it necks: "
        "Newtonian at 0.04 s with no neck, the honey at 0.065 s with a neck of 1 slab (at 5-17 "
        "across: 0.035-0.055 and 0.065-0.09 s, sooner as the spacing shrinks, where MPM's "
        "parting keeps its time). DFSPH parts as we do; MPM's pressure pulls on a Lagrangian "
        "volume J, which a plane's opening changes and the SPH sum beside it does not; an "
        "interior held from below (probe honey-j-ab) parts at MPM's times but breaks resting "
        "columns under Jacobi (docs/particles/honey.md, round ab; earlier remedies there and "
        "in fluids.md)")


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=NECK)
def test_a_hanging_honey_blob_necks_before_it_parts():
    """The 2017 paper's honey draws threads that thin out and drip (Fig. 8, 10, 17); what the
    drip's first instants ask, at a size a test affords: the blob hanging from its film (13
    across, 2704 particles of 3.8 mm) necks, two or more slabs under the film holding liquid but
    at most a quarter of a layer, before it parts, and it parts no sooner than 0.09 s, for a
    Newtonian honey (10 Pa s) and the viscoelastic one of these tests (G 500 Pa, yield 500 Pa).
    The neck closes in 3 mu A / W = 0.036 s under the whole weight W (0.056 s with the yield
    stress), later as the drop's acceleration unloads it. A reference method meets this: Taichi
    MLS-MPM (weakly compressible, two-sided pressure, the same sites, a sticky ceiling; profiles
    every 0.01 s) parts at 0.107 and 0.107 s with necks of 4 and 4 slabs on a grid of one
    spacing, at 0.102 and 0.136 s with 3 and 2 on a grid of two (benches/honey_peers.py). The
    thread the paper draws to its drop is not asked: no method tried (MPM to 33 across, DFSPH,
    ours) keeps one to 0.4 s at 5-33 across; at 5 across it would hold two fifths of the
    blob."""
    for material in (dict(viscosity=10.0),
                     dict(viscosity=10.0, shear_modulus=500.0, yield_stress=500.0)):
        parts, neck = hanging_blob_necks_and_parts(material, n=13)
        assert parts is None or parts >= 0.09, (material, parts, neck)
        assert neck >= 2, (material, parts, neck)
