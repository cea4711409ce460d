"""A particle body's material as a run left it travels with ``save_state`` / ``load_state``
(``Particles.material_state``): a body that solidified or melted whole, a region that changed
material, sand a liquid wetted. A run continued from the file equals the run that went on, to
the bit; before the material was saved the same continuations differed by millimetres (the
fresh bodies kept their set-up materials and dry grains)."""

import numpy as np
import pytest

import peridyn as pd

S = 0.01  # lattice spacing (m)
SAVE, MORE = 10, 10  # steps before the save and after it


def lattice(n, origin):
    g = np.stack(np.meshgrid(*[np.arange(k) for k in n], indexing="ij"), -1).reshape(-1, 3)
    return g * S + np.asarray(origin)


def solver():
    s = pd.Solver(dt=0.005, gravity=(0.0, 0.0, -9.81), max_iters=20)
    s.add_collider(pd.Plane())
    return s


def liquid_on_sand():
    s = solver()
    sand = pd.Particles(lattice((6, 6, 3), (0, 0, 0.006)), spacing=S, density=1600.0,
                        material=pd.Granular(friction_angle=30.0, saturation=0.0))
    water = pd.Particles(lattice((3, 3, 3), (0.015, 0.015, 0.04)), spacing=S,
                         density=1000.0, material=pd.ViscoelasticFluid(viscosity=1e-3))
    s.add(sand)
    s.add(water)
    return s, [sand, water]


SOLID = pd.Elastic.from_young(1e4, 0.3)
HONEY = pd.ViscoelasticFluid(viscosity=1.0, shear_modulus=50.0)


def block(material, density):
    """A 5^3 block of ``material`` (kg/m^3) just above the floor, alone in a solver."""
    s = solver()
    body = pd.Particles(lattice((5, 5, 5), (0, 0, 0.006)), spacing=S, density=density,
                        material=material)
    s.add(body)
    return s, [body]


def melt():
    return block(pd.ViscoelasticFluid(viscosity=1.0), 1000.0)


def honey():
    return block(HONEY, 1400.0)


def jelly():
    return block(SOLID, 1000.0)


def cg_water():
    """Water whose density constraints the conjugate gradients solve, landing on the floor
    plane: its members slide along the floor in the linear solves (walls found within each
    step; kept across steps, unsaved, they parted the continuation from the run)."""
    return block(pd.ViscoelasticFluid(viscosity=1e-3, density_solver="cg"), 1000.0)


def viscoplastic_honey():
    """Honey whose return relaxes its overstress over `plastic_viscosity / G` = 0.1 s,
    flowing on the floor beyond its yield stress (50 Pa against its weight's 690 Pa): the
    stress beyond its cone is elastic strain kept in its reference bonds, which the file
    holds."""
    return block(pd.ViscoelasticFluid(viscosity=1.0, shear_modulus=50.0, plastic_viscosity=5.0),
                 1400.0)


def rough_sand():
    """Sand whose grains' contacts have friction (per-pair multipliers carried from step to
    step, unsaved before format version 3: the continuation parted from the run) settling on
    the floor; its lattice offset so that the grains land on each other unevenly."""
    s = solver()
    rng = np.random.default_rng(3)
    x = lattice((5, 5, 4), (0, 0, 0.006)) + rng.uniform(-0.1, 0.1, (100, 3)) * S
    sand = pd.Particles(x, spacing=S, density=1600.0,
                        material=pd.Granular(friction_angle=30.0, contact_friction=0.5))
    s.add(sand)
    return s, [sand]


def melts_to_honey(s, bodies):
    bodies[0].set_material(HONEY)


def region_solidifies(s, bodies):
    bodies[0].set_material(SOLID, np.arange(60))


def whole_solidifies(s, bodies):
    bodies[0].set_material(SOLID)


def nothing(s, bodies):
    pass


CASES = {
    "wetted sand": (liquid_on_sand, nothing),
    "a region solidified": (melt, region_solidifies),
    "the whole body solidified": (melt, whole_solidifies),
    # plastic after the change (a viscoelastic fluid: its bonds follow the material)
    "a solid melted into honey": (jelly, melts_to_honey),
    # plastic before it, elastic after
    "honey solidified": (honey, whole_solidifies),
}

#: Continuations whose material stays as set up: nothing else a step keeps may go unsaved.
UNCHANGED = {
    "water by conjugate gradients on a floor": (cg_water, nothing),
    "sand with contact friction": (rough_sand, nothing),
    "honey with a plastic viscosity": (viscoplastic_honey, nothing),
}


def run(s, bodies, event, steps):
    """``steps`` steps; ``event`` at step 5 (from the solver's count, so a restored solver
    does not repeat it)."""
    for _ in range(steps):
        if s.steps_taken == 5:
            event(s, bodies)
        s.step()


@pytest.mark.parametrize("case", {**CASES, **UNCHANGED})
def test_a_run_continued_from_a_file_equals_the_run_that_went_on(case, tmp_path):
    scene, event = {**CASES, **UNCHANGED}[case]
    s, bodies = scene()
    run(s, bodies, event, SAVE)
    path = pd.save_state(tmp_path / "state.npz", s)
    run(s, bodies, event, MORE)

    fresh, copies = scene()
    pd.load_state(path, fresh)
    run(fresh, copies, event, MORE)
    for body, copy in zip(bodies, copies):
        assert np.array_equal(copy.positions, body.positions)
        assert np.array_equal(copy.velocities, body.velocities)
        assert np.array_equal(copy.fluid_particles, body.fluid_particles)
        for name, value in body.material_state.items():
            assert np.array_equal(copy.material_state[name], value), name
    if case == "wetted sand":
        assert bodies[0].saturation.max() > 0.1  # the liquid did wet the grains
    if case == "water by conjugate gradients on a floor":  # the water reached the floor
        assert bodies[0].positions[:, 2].min() < 0.0051  # and its constraints were solved
        assert s.step().particles["density_passes"] > 0
    if case == "sand with contact friction":  # contacts carried friction into the next step
        assert len(s.internal_state()["grain_contact_pairs"]) > 0


def test_the_restore_matters():
    """Without the material the continuations part: the saved state is not what the set-up
    makes (so the test above tests something)."""
    for scene, event in CASES.values():
        s, bodies = scene()
        run(s, bodies, event, SAVE)
        _, fresh = scene()
        assert any(not np.array_equal(b.material_state[k], f.material_state[k])
                   for b, f in zip(bodies, fresh) for k in b.material_state)


def test_a_state_loaded_back_into_a_body_that_changed_since(tmp_path):
    """Loading into a solver that went on (and melted the region back) restores the saved
    material: loading repeats the continuation."""
    s, bodies = melt()
    run(s, bodies, region_solidifies, SAVE)
    path = pd.save_state(tmp_path / "state.npz", s)
    run(s, bodies, region_solidifies, MORE)
    expected = bodies[0].positions.copy()
    bodies[0].set_material(pd.ViscoelasticFluid(viscosity=1.0), np.arange(60))
    pd.load_state(path, s)
    run(s, bodies, region_solidifies, MORE)
    assert np.array_equal(bodies[0].positions, expected)


def test_a_version_1_file_leaves_the_material_as_it_is(tmp_path):
    """A file written before the material was saved (format version 1: no material entries)
    still loads; the bodies keep the materials they have; a material entry in it is refused."""
    s, bodies = liquid_on_sand()
    run(s, bodies, nothing, SAVE)
    path = pd.save_state(tmp_path / "state.npz", s)
    with np.load(path) as data:
        e = {k: data[k] for k in data.files}
    material = [k for k in e if k.startswith("material_")]
    assert material
    old = {k: v for k, v in e.items() if k not in material}
    old["format_version"] = np.array(1)
    np.savez(tmp_path / "v1.npz", **old)
    fresh, copies = liquid_on_sand()
    pd.load_state(tmp_path / "v1.npz", fresh)
    assert np.array_equal(copies[0].positions, bodies[0].positions)
    assert np.array_equal(copies[0].saturation, np.zeros(copies[0].num_particles))
    old[material[0]] = e[material[0]]
    np.savez(tmp_path / "mixed.npz", **old)
    with pytest.raises(ValueError, match="unexpected entries"):
        pd.load_state(tmp_path / "mixed.npz", liquid_on_sand()[0])


def entries(path):
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def snapshot(bodies):
    return [(b.positions.copy(), b.velocities.copy(), b.material_state) for b in bodies]


def same(a, b):
    return all(np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1])
               and all(np.array_equal(x[2][k], y[2][k]) for k in x[2]) for x, y in zip(a, b))


def test_a_refused_material_leaves_the_solver_as_it_was(tmp_path):
    """A file whose material entry is malformed is refused before anything changes; one whose
    material the body refuses (saturations for a liquid) is undone; either error names the
    entry and the body."""
    s, bodies = liquid_on_sand()
    run(s, bodies, nothing, SAVE)
    path = pd.save_state(tmp_path / "state.npz", s)
    target, targets = liquid_on_sand()
    run(target, targets, nothing, 3)
    before = snapshot(targets)
    e = entries(path)
    bad = dict(e, material_reference_1=e["material_reference_1"][:-1])
    np.savez(tmp_path / "short.npz", **bad)
    with pytest.raises(ValueError, match="material_reference_1"):
        pd.load_state(tmp_path / "short.npz", target)
    assert same(snapshot(targets), before)
    wet = dict(e, material_wetted_1=np.full(len(e["positions_1"]), 0.5))
    np.savez(tmp_path / "wet.npz", **wet)
    with pytest.raises(ValueError, match=r"body 1's material .*not sand"):
        pd.load_state(tmp_path / "wet.npz", target)
    assert same(snapshot(targets), before)


def test_a_plastic_body_without_its_bonds_in_the_file_is_refused(tmp_path):
    s, bodies = honey()
    run(s, bodies, nothing, SAVE)
    path = pd.save_state(tmp_path / "state.npz", s)
    e = {k: v for k, v in entries(path).items() if not k.startswith("bonds_")}
    np.savez(tmp_path / "bare.npz", **e)
    target, _ = honey()
    with pytest.raises(ValueError, match="body 0 is plastic but the file holds no entries"):
        pd.load_state(tmp_path / "bare.npz", target)


def test_a_material_state_without_region_volume_ratios_gives_every_particle_1():
    """A material state written before the volume ratios (no 'region_volume') sets the
    region bonds it holds with every particle at its rest volume (ratio 1)."""
    s, bodies = melt()
    run(s, bodies, region_solidifies, 8)
    state = bodies[0].material_state
    assert len(state["region_volume"]) == bodies[0].num_particles
    older = {k: v for k, v in state.items() if k != "region_volume"}
    bodies[0].material_state = older
    for name, value in older.items():
        assert np.array_equal(bodies[0].material_state[name], value), name
    assert np.array_equal(bodies[0].material_state["region_volume"],
                          np.ones(bodies[0].num_particles))


def test_bad_material_states_are_refused_by_name():
    s, (sand, water) = liquid_on_sand()
    state = sand.material_state
    wet = dict(state, wetted=np.full(sand.num_particles, 0.5))
    wet["wetted"][7] = 1.5
    with pytest.raises(ValueError, match=r"saturation 7 is 1\.5"):
        sand.material_state = wet
    with pytest.raises(ValueError, match="not sand"):
        water.material_state = dict(water.material_state,
                                    wetted=np.full(water.num_particles, 0.5))
    with pytest.raises(ValueError, match="reference positions"):
        water.material_state = dict(water.material_state,
                                    reference=water.material_state["reference"][:-1])
    with pytest.raises(ValueError, match="elastic"):
        water.material_state = dict(water.material_state, elastic=np.array([3.0, 1.0, 1.0]))
    missing = dict(water.material_state)
    del missing["wetted"]
    with pytest.raises(ValueError, match="wetted"):
        water.material_state = missing
    assert np.array_equal(sand.saturation, np.zeros(sand.num_particles))


def test_a_moved_body_or_an_old_file_starts_the_grains_contact_friction_from_0(tmp_path):
    """The grains' contact friction belongs to their contacts at the positions the run left:
    positions set from outside start it from 0 (even the same positions: the solver cannot
    tell), as a file of format version 2 (saved without it) does; both continuations agree to
    the bit, and differ from the run that kept it."""
    s, bodies = rough_sand()
    run(s, bodies, nothing, SAVE)
    path = pd.save_state(tmp_path / "state.npz", s)
    old = {k: v for k, v in entries(path).items() if not k.startswith("internal_grain_contact_")}
    old["format_version"] = np.array(2)
    np.savez(tmp_path / "v2.npz", **old)
    kept, kept_bodies = rough_sand()
    pd.load_state(path, kept)
    assert len(kept.internal_state()["grain_contact_pairs"]) > 0
    fresh, copies = rough_sand()
    pd.load_state(tmp_path / "v2.npz", fresh)
    assert len(fresh.internal_state()["grain_contact_pairs"]) == 0
    bodies[0].positions = bodies[0].positions
    for solver, b in [(s, bodies), (fresh, copies), (kept, kept_bodies)]:
        run(solver, b, nothing, MORE)
    assert np.array_equal(copies[0].positions, bodies[0].positions)
    assert np.array_equal(copies[0].velocities, bodies[0].velocities)
    assert not np.array_equal(kept_bodies[0].positions, bodies[0].positions)


def test_bad_grain_contacts_are_refused_by_name():
    s, bodies = rough_sand()
    run(s, bodies, nothing, SAVE)
    good = s.internal_state()
    pairs, multipliers = good["grain_contact_pairs"], good["grain_contact_multipliers"]

    def refused(match, **changes):
        with pytest.raises(ValueError, match=match):
            s.set_internal_state(dict(good, **changes))
        assert all(np.array_equal(s.internal_state()[k], v) for k, v in good.items())

    beyond = pairs.copy()
    beyond[2] = [7, 100]
    refused(r"grain contact 2 joins particles \[7, 100\], but the particle bodies have 100",
            grain_contact_pairs=beyond)
    itself = pairs.copy()
    itself[1] = [4, 4]
    refused("grain contact 1 joins particle 4 to itself", grain_contact_pairs=itself)
    twice = pairs.copy()
    twice[3] = twice[0]
    refused(r"grain contacts 0 and 3 both join particles", grain_contact_pairs=twice)
    nan = multipliers.copy()
    nan[5, 1] = np.nan
    refused("multiplier of grain contact 5 .* not finite", grain_contact_multipliers=nan)
    refused("must describe the same contacts", grain_contact_multipliers=multipliers[:-1])
    refused("-1, not a particle index", grain_contact_pairs=np.where(beyond == 100, -1, beyond))
    one = dict(good)
    del one["grain_contact_multipliers"]
    with pytest.raises(ValueError, match=r"missing \[\"grain_contact_multipliers\"\]"):
        s.set_internal_state(one)
    water, _ = block(pd.ViscoelasticFluid(viscosity=1e-3), 1000.0)
    with pytest.raises(ValueError, match="no particle body has contact friction"):
        water.set_internal_state(good)  # its 125 particles would hold the pairs
