"""An exact restore of a plastic particle body (issue 39): its current reference bonds (the
neighbours after returns and rebuilds, their reference vectors, the hardening state) travel
with ``save_state`` / ``load_state`` and ``Particles.rest_bonds``, so a run continued from a
file equals the run that went on, to the bit."""

import numpy as np
import pytest

import peridyn as pd

S = 0.01  # lattice spacing (m)
N, LENGTH = 3, 8  # bar cross-section and length in particles
STRETCH, STEPS = 0.5, 24  # the top end is pulled by STRETCH of the span over STEPS steps


def bar(friction_angle=20.0):
    x = np.stack(
        np.meshgrid(np.arange(N), np.arange(N), np.arange(LENGTH), indexing="ij"), -1
    ).reshape(-1, 3) * S
    body = pd.Particles(
        x, spacing=S, density=1000.0, material=pd.Elastic.from_young(1e5, 0.3),
        plasticity=pd.DruckerPrager(friction_angle=friction_angle, cohesion=50.0,
                                    hardening=500.0),
    )
    z = x[:, 2]
    body.pin(np.flatnonzero((z < 0.5 * S) | (z > (LENGTH - 1.5) * S)))
    return body


def scene(friction_angle=20.0):
    body = bar(friction_angle)
    s = pd.Solver(dt=0.01, gravity=(0.0, 0.0, -9.81), max_iters=20)
    s.add(body)
    return s, body


def pull(s, body, steps):
    """Steps ``steps`` times, moving the top pins by the pull's share each step (from the
    solver's step count, so a restored solver goes on with the same targets)."""
    rest = body.rest_positions
    pinned = body.pinned
    top = rest[pinned, 2] > (LENGTH - 1.5) * S
    span = (LENGTH - 1) * S
    for _ in range(steps):
        targets = rest[pinned].copy()
        targets[top, 2] += STRETCH * span * min(s.steps_taken + 1, STEPS) / STEPS
        body.pin_targets = targets
        s.step()


def test_a_plastic_body_that_yielded_and_rebuilt_its_neighbours_restores_to_the_bit(tmp_path):
    s, body = scene()
    reference = body.rest_bonds
    pull(s, body, 14)
    bonds = body.rest_bonds
    # The body has yielded (hardening state, moved vectors) and changed neighbourhoods.
    assert bonds["plastic_strain"].max() > 0.01
    assert not np.array_equal(bonds["offsets"], reference["offsets"]) or not np.array_equal(
        bonds["neighbours"], reference["neighbours"])
    path = pd.save_state(tmp_path / "plastic.npz", s)
    pull(s, body, 8)

    fresh, copy = scene()
    pd.load_state(path, fresh)
    for name, value in bonds.items():
        assert np.array_equal(copy.rest_bonds[name], value), name
    pull(fresh, copy, 8)
    assert np.array_equal(copy.positions, body.positions)
    assert np.array_equal(copy.velocities, body.velocities)
    for name, value in body.rest_bonds.items():
        assert np.array_equal(copy.rest_bonds[name], value), name


def test_a_body_whose_return_keeps_its_rest_volume_restores_its_volume_ratios(tmp_path):
    """Without friction the return keeps each particle's rest volume from the volume ratios
    of its reference bonds (docs/particles/plasticity.md), which change as it yields
    and rebuilds: they travel with the file, and the continued run equals the run that went
    on, to the bit. A file written before them (no 'bonds_volume_0') loads them as 1."""
    s, body = scene(friction_angle=0.0)
    pull(s, body, 14)
    bonds = body.rest_bonds
    assert np.abs(bonds["volume"] - 1.0).max() > 1e-3, bonds["volume"]
    path = pd.save_state(tmp_path / "plastic.npz", s)
    pull(s, body, 8)
    fresh, copy = scene(friction_angle=0.0)
    pd.load_state(path, fresh)
    assert np.array_equal(copy.rest_bonds["volume"], bonds["volume"])
    pull(fresh, copy, 8)
    assert np.array_equal(copy.positions, body.positions)
    entries = dict(np.load(path))
    del entries["bonds_volume_0"]
    np.savez(tmp_path / "old.npz", **entries)
    older, copy = scene(friction_angle=0.0)
    pd.load_state(tmp_path / "old.npz", older)
    assert np.array_equal(copy.rest_bonds["volume"], np.ones(len(bonds["volume"])))


def test_rest_bonds_without_volume_ratios_give_every_particle_1():
    """A ``rest_bonds`` dict written before the volume ratios (no 'volume') sets the bonds
    it holds, each particle's reference bonds at its rest volume (ratio 1), as a file
    without them loads."""
    s, body = scene(friction_angle=0.0)
    pull(s, body, 14)
    bonds = body.rest_bonds
    assert np.abs(bonds["volume"] - 1.0).max() > 1e-3, bonds["volume"]
    older = {k: v for k, v in bonds.items() if k != "volume"}
    body.rest_bonds = older
    for name, value in older.items():
        assert np.array_equal(body.rest_bonds[name], value), name
    assert np.array_equal(body.rest_bonds["volume"], np.ones(body.num_particles))


def test_bonds_loaded_into_a_solver_that_has_stepped_replace_its_own(tmp_path):
    """A solver that stepped on (its working set built from the later bonds) takes the
    loaded bonds on its next step: loading the file back into it repeats the continuation."""
    s, body = scene()
    pull(s, body, 14)
    path = pd.save_state(tmp_path / "plastic.npz", s)
    pull(s, body, 6)
    first = body.positions.copy()
    pd.load_state(path, s)
    pull(s, body, 6)
    assert np.array_equal(body.positions, first)


def test_without_its_bonds_the_restore_of_a_plastic_body_is_refused(tmp_path):
    s, body = scene()
    pull(s, body, 2)
    path = pd.save_state(tmp_path / "plastic.npz", s)
    entries = dict(np.load(path))
    del entries["bonds_born_0"]
    np.savez(tmp_path / "cut.npz", **entries)
    fresh, _ = scene()
    with pytest.raises(ValueError, match="'bonds_born_0' is missing"):
        pd.load_state(tmp_path / "cut.npz", fresh)


def elastic_bar():
    return pd.Particles(bar().rest_positions, spacing=S,
                        density=1000.0, material=pd.Elastic.from_young(1e5, 0.3))


@pytest.mark.parametrize(
    "change, needle",
    [
        (lambda b: b.update(offsets=b["offsets"][:-1]), "bond offsets must hold 73 entries"),
        (lambda b: b["neighbours"].__setitem__(0, 999), "goes to 999"),
        (lambda b: b["neighbours"].__setitem__(0, 0), "goes to 0, not another particle"),
        (lambda b: b["vectors"].__setitem__((3, 1), np.nan), "vector of bond 3 must be finite"),
        (lambda b: b["born"].__setitem__(5, -1.0), "birth length of bond 5 must be finite and > 0"),
        (lambda b: b["plastic_strain"].__setitem__(7, -0.5), "plastic strain of particle 7"),
        (lambda b: b["volume"].__setitem__(4, 0.0), "volume ratio of particle 4"),
        (lambda b: b["volume"].__setitem__(6, 2e3), "volume ratio of particle 6 must lie within"),
        (lambda b: b.pop("born"), 'missing ["born"]'),
        (lambda b: b.update(extra=np.zeros(3)), 'unknown ["extra"]'),
        (lambda b: b.update(vectors=b["vectors"][:, :2]), "vectors must have shape (N, 3)"),
    ],
)
def test_bad_bonds_are_value_errors_naming_the_culprit(change, needle):
    body = bar()
    bonds = body.rest_bonds
    before = {k: v.copy() for k, v in bonds.items()}
    change(bonds)
    with pytest.raises(ValueError) as err:
        body.rest_bonds = bonds
    assert needle in str(err.value)
    for name, value in body.rest_bonds.items():
        assert np.array_equal(value, before[name]), name


def test_an_elastic_body_has_no_bonds_to_set():
    body = elastic_bar()
    assert body.rest_bonds is None
    with pytest.raises(ValueError, match="only a plastic body takes bonds"):
        body.rest_bonds = bar().rest_bonds
