"""Liquid with wet sand (He et al. 2017, section 8, Fig. 16; issue 40): the liquid's density
constraints see the sand's grains (incompressibility over both), so liquid poured on a sand
bed stays on it; the grains it reaches get wet (their saturation rises, and with it their
cohesion: docs/model.md, "Liquid with wet sand")."""

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


def pour_on_bed(steps=100, threads=None):
    """A 4 x 4 x 4 block of water released 1 cm above the middle of a 10 x 10 x 3 bed of dry
    sand (friction angle 30 degrees) on the ground. Returns the sand, the water and the bed's
    top (m, the highest layer's centre)."""
    bed = pd.Particles(lattice((10, 10, 3), (-4.5 * S, -4.5 * S, 0.5 * S)), spacing=S,
                       density=RHO, material=pd.Granular(friction_angle=30.0))
    top = 2.5 * S
    water = pd.Particles(lattice((4, 4, 4), (-1.5 * S, -1.5 * S, top + 2 * S)), spacing=S,
                         density=1000.0, material=WATER)
    s = solver(threads=threads)
    s.add(bed)
    s.add(water)
    for _ in range(steps):
        s.step()
    return bed, water, top


@pytest.mark.xfail(strict=True, reason="open (issue 40): since the fluids' viscosity moved before "
                   "the prediction (fluids40c) and met the sand partners (couple40c), one water "
                   "particle over the bed's middle ends inside it (z 1.32 cm under a grain at 2.17 "
                   "cm); each branch alone passed")
def test_liquid_poured_on_a_sand_bed_stays_on_it_and_wets_the_grains_it_reaches():
    """The bed spreads under the water (three layers to about two) but no water particle
    over its middle (7 x 7 spacings; the rest runs off its edges to the ground) has a grain
    above it within 0.7 spacings horizontally: the water stays on the sand. The grains of
    the bed's surface under the water are wet (theta > 0.5), those of its bottom layer
    there, a layer deeper, less (theta < 0.4; measured 0.21 to 0.26: the kernel is peaked,
    docs/model.md)."""
    bed, water, _ = pour_on_bed()
    y, x = water.positions, bed.positions
    over = (np.abs(y[:, 0]) < 3.5 * S) & (np.abs(y[:, 1]) < 3.5 * S)
    assert over.sum() >= 16, over.sum()
    for p in y[over]:
        column = np.hypot(x[:, 0] - p[0], x[:, 1] - p[1]) < 0.7 * S
        assert (x[column, 2] < p[2]).all(), (p, x[column])
    theta = bed.saturation
    assert theta.shape == (bed.num_particles,)
    middle = (np.abs(x[:, 0]) < 1.5 * S) & (np.abs(x[:, 1]) < 1.5 * S)
    surface = middle & (x[:, 2] > x[middle, 2].max() - 0.5 * S)
    bottom = middle & (x[:, 2] < 0.75 * S)
    assert surface.any() and bottom.any()
    assert theta[surface].min() > 0.5, theta[surface]
    assert theta[bottom].max() < 0.4, theta[bottom]


def test_threads_are_bit_identical_for_liquid_on_sand():
    runs = [pour_on_bed(steps=10, threads=t) for t in (1, 2)]
    for a, b in zip(runs[0][:2], runs[1][:2]):
        assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(runs[0][0].saturation, runs[1][0].saturation)


def column(radius, height):
    n = int(round(radius / S))
    g = np.arange(-n, n + 1) * S
    x, y, z = np.meshgrid(g, g, (np.arange(int(round(height / S))) + 0.5) * S, indexing="ij")
    p = np.stack([x, y, z], -1).reshape(-1, 3)
    p = p[np.hypot(p[:, 0], p[:, 1]) <= radius + 1e-9]
    return pd.Particles(p, spacing=S, density=RHO, material=pd.Granular(friction_angle=30.0))


@pytest.mark.xfail(strict=True, reason="the wetted column stood lower: 95th percentile "
                   "height 2.00 cm against the dry column's 2.05 cm (0.3 s; 3.15 against 3.70 "
                   "with the return after the iterations; the water wets the top layer only, "
                   "the kernel being peaked: docs/model.md)")
def test_a_column_wetted_by_poured_liquid_stands_taller_than_a_dry_one():
    """A column of dry sand (R = 6 cm, a = 1), held by pins while water (7 x 7 x 4) is poured
    on its top, then released without the water in a new solver, next to a dry control:
    the wetted column's 95th percentile height stands above the dry one's."""
    wet = column(0.06, 0.06)
    wet.pin(np.arange(wet.num_particles))
    water = pd.Particles(lattice((7, 7, 4), (-3 * S, -3 * S, 0.07)), spacing=S, density=1000.0,
                         material=WATER)
    s = solver()
    s.add(wet)
    s.add(water)
    for _ in range(60):
        s.step()
    assert (wet.saturation > 0.5).sum() > 20, (wet.saturation > 0.5).sum()
    wet.unpin()
    heights = []
    for body in (wet, column(0.06, 0.06)):
        s = solver()
        s.add(body)
        for _ in range(150):
            s.step()
        heights.append(np.percentile(body.positions[:, 2], 95))
    assert heights[0] > heights[1] + 0.5 * S, heights
