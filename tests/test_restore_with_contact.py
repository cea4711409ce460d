"""Save, restore and continue with contact: three layers of cloth on a ball, saved mid-fall,
restored into a fresh solver set up the same way, continue bit for bit (issue 43)."""

import os

import numpy as np
import pytest

import peridyn
from conftest import make_grid

SAVED_AT, AFTER = 30, 10


def scene(precision, acceleration=None, **options):
    """Three 12 x 12 layers 5 mm apart over a ball; `options` replace the solver's threads and
    contact (e.g. ``backend="gpu", contact=None``)."""
    settings = {"threads": 2, "contact": peridyn.Contact(thickness=1.5e-3), **options}
    solver = peridyn.Solver(dt=2e-3, max_iters=30, precision=precision,
                            acceleration=acceleration, **settings)
    layers = []
    for k in range(3):
        v, t = make_grid(12, 12, 0.3, 0.3)
        v = v + np.array([-0.15 + 0.004 * k, -0.15 + 0.003 * k, 0.104 + 0.005 * k])
        m = peridyn.Membrane(v, t, thickness=1e-3, density=300.0,
                             material=peridyn.StretchA3(s0=1e4), bending=1e-5)
        solver.add(m)
        layers.append(m)
    solver.add_collider(peridyn.Sphere(center=(0.0, 0.0, 0.0), radius=0.1))
    return solver, layers


def state(layers):
    return [(m.positions, m.velocities) for m in layers]


def assert_same(a, b):
    for (pa, va), (pb, vb) in zip(a, b):
        assert np.array_equal(pa, pb), f"positions differ by up to {np.abs(pa - pb).max():.3g} m"
        assert np.array_equal(va, vb), f"velocities differ by up to {np.abs(va - vb).max():.3g} m/s"


#: save_state does not yet carry what a contact step depends on across steps: the contact
#: local step's warm start (Solver.contact_warm_start exists, io's internal_state hook does not
#: call it yet) and the rest gaps of the pairs that started within the barrier's reach (issue
#: 41, not exposed). Issue 43 stays open until these pass; strict, so a fix shows.
UNSAVED_CONTACT_STATE = pytest.mark.xfail(
    strict=True, reason="contact warm start and rest gaps are not in the state file yet (issue 43)")


@UNSAVED_CONTACT_STATE
@pytest.mark.parametrize("precision,acceleration",
                         [("f64", None), ("f32", None), ("f64", "chebyshev")])
def test_restored_layers_on_a_ball_continue_bit_for_bit(tmp_path, precision, acceleration):
    solver, layers = scene(precision, acceleration)
    for _ in range(SAVED_AT):
        solver.step()
    path = peridyn.save_state(tmp_path / "state.npz", solver)
    active = min(solver.step().contact["active_pairs"] for _ in range(AFTER))
    assert active > 0, "the layers should be in contact after the save"
    expected = state(layers)

    restored, restored_layers = scene(precision, acceleration)
    peridyn.load_state(path, restored)
    for _ in range(AFTER):
        restored.step()
    assert_same(state(restored_layers), expected)
    assert (restored.time, restored.steps_taken) == (solver.time, solver.steps_taken)


@UNSAVED_CONTACT_STATE
def test_the_warm_start_is_saved_and_checked(tmp_path):
    solver, _ = scene("f64")
    assert solver.contact_warm_start().shape == (0, 3)  # none before the first step
    for _ in range(SAVED_AT):
        solver.step()
    warm = solver.contact_warm_start()
    assert warm.shape == (3 * 144, 3) and np.abs(warm).max() > 0.0
    with np.load(peridyn.save_state(tmp_path / "state.npz", solver)) as data:
        assert np.array_equal(data["contact_warm_start"], warm)
    fresh, _ = scene("f64")
    fresh.set_contact_warm_start(warm)
    assert np.array_equal(fresh.contact_warm_start(), warm)  # held for the next step
    for bad in (warm[:10], np.full_like(warm, np.nan)):
        with pytest.raises(ValueError, match="warm start"):
            fresh.set_contact_warm_start(bad)


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_restored_gpu_layers_continue_bit_for_bit(tmp_path, precision):
    """The GPU backend has no contact (its warm start is empty): three layers falling onto the
    ball (passing through each other), saved, restored and continued, bit for bit."""
    try:
        info = peridyn.gpu_info()
    except RuntimeError as e:
        if os.environ.get("PERIDYN_REQUIRE_GPU") == "1":
            pytest.fail(f"PERIDYN_REQUIRE_GPU=1 but no GPU adapter: {e}")
        pytest.skip(f"no GPU adapter: {e}")
    if precision == "f64" and not info["f64"]:
        pytest.skip(f"{info['name']} lacks SHADER_F64")

    def gpu_scene():
        return scene(precision, "chebyshev", backend="gpu", threads=None, contact=None)

    solver, layers = gpu_scene()
    for _ in range(SAVED_AT):
        solver.step()
    assert solver.contact_warm_start().shape == (0, 3)
    path = peridyn.save_state(tmp_path / "state.npz", solver)
    for _ in range(AFTER):
        solver.step()
    restored, restored_layers = gpu_scene()
    peridyn.load_state(path, restored)
    for _ in range(AFTER):
        restored.step()
    assert_same(state(restored_layers), state(layers))
