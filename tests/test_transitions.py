"""Material transitions of a region (He et al. 2017, section 8, Fig. 19; issue 40): the
particles given to ``Particles.set_material(material, indices)`` change between a Newtonian
fluid and an elastic solid; the rest of the body keeps its material."""

import numpy as np
import pytest

import peridyn as pd

S = 0.01  # particle spacing (m)
WATER = pd.ViscoelasticFluid(viscosity=1e-3)
SOLID = pd.Elastic.from_young(1e4, 0.3)


def lattice(n, spacing, origin):
    """An n[0] x n[1] x n[2] cubic lattice of `spacing` (m) from `origin` (m)."""
    axes = [np.arange(k) * spacing for k in n]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) + np.asarray(origin)


def shape_change(x, x0):
    """RMS distance (m) between two shapes of the same particles, each about its centroid."""
    a, b = x - x.mean(0), x0 - x0.mean(0)
    return np.sqrt(((a - b) ** 2).sum(1).mean())


def half_solid_blob(threads=None, steps=60):
    """An 8 x 4 x 4 water blob in zero gravity whose half x < 4 spacings is turned elastic
    after 3 steps, then pushed outwards about each half's centroid (5 /s times the offset: no
    net momentum). Returns the blob, both halves' masks, their shapes when pushed and the
    smallest fluid-solid distance (m) over the run."""
    blob = pd.Particles(lattice((8, 4, 4), S, (0, 0, 0)), spacing=S, density=1000.0,
                        material=WATER)
    solver = pd.Solver(dt=0.005, gravity=(0, 0, 0), global_solver="jacobi", threads=threads)
    solver.add(blob)
    for _ in range(3):
        solver.step()
    solid = blob.rest_positions[:, 0] < 3.5 * S
    x, v = blob.positions.copy(), blob.velocities.copy()
    blob.set_material(SOLID, np.flatnonzero(solid))
    assert np.array_equal(blob.positions, x) and np.array_equal(blob.velocities, v)
    assert np.array_equal(blob.fluid_particles, ~solid)
    x0 = blob.positions.copy()
    for half in (solid, ~solid):
        v[half] += 5.0 * (x0[half] - x0[half].mean(0))
    blob.velocities = v
    closest = np.inf
    for _ in range(steps):
        solver.step()
        y = blob.positions
        gaps = np.linalg.norm(y[solid][:, None] - y[~solid][None], axis=2)
        closest = min(closest, gaps.min())
    return blob, solid, x0, closest


def test_half_a_fluid_blob_turned_elastic_keeps_its_shape_while_the_other_half_flows():
    """The solid half springs back to within a fifth of a spacing of its shape when pushed;
    the fluid half, pushed alike, spreads by more than a spacing; the fluid never comes
    closer than half a spacing to a solid particle (its density constraints see them)."""
    blob, solid, x0, closest = half_solid_blob()
    x = blob.positions
    kept, spread = shape_change(x[solid], x0[solid]), shape_change(x[~solid], x0[~solid])
    assert kept < 0.2 * S, kept
    assert spread > S, spread
    assert closest > 0.5 * S, closest
    # Bonds only between solid particles: none reaches into the fluid half.
    offsets, neighbours = blob.neighborhood()
    owners = np.repeat(np.arange(len(solid)), np.diff(offsets))
    assert len(neighbours) > 0
    assert solid[owners].all() and solid[neighbours].all()


def test_threads_are_bit_identical_for_a_mixed_body():
    runs = [half_solid_blob(threads=t, steps=10)[0].positions for t in (1, 2)]
    assert np.array_equal(runs[0], runs[1])


def sheet_on_sphere(solidify_at, steps=120, threads=None):
    """A fluid sheet 12 x 12 x 2 particles (spacing 1 cm) dropped on a sphere collider of
    radius 5 cm (Fig. 19 in small: the dress's skirt as a fluid, then a shell); after
    `solidify_at` steps (None: never) every particle is turned elastic. Returns the sheet's
    mean height (m) above the sphere's centre at the end and its highest particle's speed."""
    n = 12
    X = lattice((n, n, 2), S, (-(n - 1) * S / 2, -(n - 1) * S / 2, 0.06))
    sheet = pd.Particles(X, spacing=S, density=1000.0, material=WATER)
    solver = pd.Solver(dt=0.005, gravity=(0, 0, -9.81), global_solver="jacobi",
                       threads=threads)
    solver.add(sheet)
    solver.add_collider(pd.Sphere(center=(0, 0, 0), radius=0.05))
    for k in range(steps):
        if k == solidify_at:
            sheet.set_material(pd.Elastic.from_young(2e4, 0.3), np.arange(len(X)))
        solver.step()
    return sheet.positions[:, 2].mean(), np.linalg.norm(sheet.velocities, axis=1).max()


def test_a_fluid_sheet_turned_elastic_over_a_sphere_holds():
    """The sheet left fluid runs off the sphere (its mean height falls below the centre);
    turned elastic once it has landed, it stays draped over it (mean height above 3 cm)."""
    fluid_height, _ = sheet_on_sphere(None)
    shell_height, _ = sheet_on_sphere(solidify_at=10)
    assert fluid_height < 0.0, fluid_height
    assert shell_height > 0.03, shell_height


def test_region_transitions_refuse_bad_input_by_name():
    blob = pd.Particles(lattice((4, 3, 3), S, (0, 0, 0)), spacing=S, density=1000.0,
                        material=WATER)
    with pytest.raises(ValueError, match=r"indices\[1\] = 36"):
        blob.set_material(SOLID, [0, 36])
    with pytest.raises(ValueError, match=r"indices\[0\] = -1"):
        blob.set_material(SOLID, [-1])
    with pytest.raises(ValueError, match="no particle given"):
        blob.set_material(SOLID, [])
    with pytest.raises(ValueError, match="shear_modulus = 5"):
        blob.set_material(pd.ViscoelasticFluid(shear_modulus=5.0), [0])
    with pytest.raises(ValueError, match="one fluid material"):
        blob.set_material(pd.ViscoelasticFluid(viscosity=2.0), [0])
    with pytest.raises(ValueError, match="particle 0 has no three-dimensional"):
        blob.set_material(SOLID, [0])  # a lone solid particle
    assert blob.fluid_particles.all()  # nothing changed
    blob.set_material(SOLID, np.arange(18))
    assert np.array_equal(blob.fluid_particles, np.arange(36) >= 18)
    with pytest.raises(ValueError, match="one elastic material"):
        blob.set_material(pd.Elastic.from_young(2e4, 0.3), np.arange(18, 36))
    # The whole body's transition still works and makes it uniform again.
    blob.set_material(WATER)
    assert blob.fluid_particles.all()
