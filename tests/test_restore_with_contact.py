"""Save, restore and continue with contact: three layers of cloth on a ball, saved mid-fall,
restored into a fresh solver set up the same way, continue bit for bit (issue 43)."""

import os

import numpy as np
import pytest

import peridyn
from conftest import make_grid

SAVED_AT, AFTER = 30, 10


def scene(precision, acceleration=None, **options):
    """Three 12 x 12 layers 5 mm apart over a ball, within the barrier's reach (Table 1's
    ``d_hat = 4 xi``: 7.5 mm), so that they start with rest gaps; `options` replace the
    solver's threads and contact (e.g. ``backend="gpu", contact=None``)."""
    contact = peridyn.Contact(thickness=1.5e-3, d_hat=6e-3)
    settings = {"threads": 2, "contact": contact, **options}
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


def test_the_internal_state_is_saved_and_checked(tmp_path):
    """The warm start and the rest gaps (the layers start inside the barrier's reach) are in the
    state file; a fresh solver takes them back exactly and refuses bad ones, naming the entry."""
    solver, _ = scene("f64")
    before = solver.internal_state()
    assert before["contact_warm_start"].shape == (0, 3)  # nothing before the first step
    assert not before["contact_rest_gaps_seeded"]
    for _ in range(SAVED_AT):
        solver.step()
    internal = solver.internal_state()
    assert internal["contact_warm_start"].shape == (3 * 144, 3)
    assert np.abs(internal["contact_warm_start"]).max() > 0.0
    assert internal["contact_rest_gaps_seeded"]
    gaps = internal["contact_rest_gap_vertices"]
    assert gaps.shape[1] == 4 and len(gaps) > 0, "the layers start within the reach"
    distances = internal["contact_rest_gap_distances"]
    assert 0.0 < distances.min() and distances.max() < internal["contact_rest_gap_reach"]
    with np.load(peridyn.save_state(tmp_path / "state.npz", solver)) as data:
        for name, value in internal.items():
            assert np.array_equal(data["internal_" + name], value), name
    fresh, _ = scene("f64")
    fresh.set_internal_state(internal)
    for name, value in fresh.internal_state().items():  # held for the next step
        assert np.array_equal(value, internal[name]), name

    def bad(name, value, needle):
        with pytest.raises(ValueError, match=needle):
            fresh.set_internal_state({**internal, name: value})

    warm = internal["contact_warm_start"]
    bad("contact_warm_start", warm[:10], "warm start holds 10 vertices")
    bad("contact_warm_start", np.full_like(warm, np.nan), "warm start of vertex 0")
    bad("contact_warm_start", warm.astype(complex), "complex")
    out_of_range = gaps.copy()
    out_of_range[3, 1] = 3 * 144
    bad("contact_rest_gap_vertices", out_of_range, r"contact_rest_gap_vertices\[3\]")
    bad("contact_rest_gap_distances", distances[:-1], "same gaps")
    bad("contact_rest_gap_distances", -distances, "gap 0")
    bad("contact_rest_gaps_seeded", np.array(0.5), "boolean")
    with pytest.raises(ValueError, match="missing.*contact_rest_gap_reach"):
        fresh.set_internal_state({k: v for k, v in internal.items() if k != "contact_rest_gap_reach"})
    for name, value in fresh.internal_state().items():  # the refusals changed nothing
        assert np.array_equal(value, internal[name]), name


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
    assert solver.internal_state()["contact_warm_start"].shape == (0, 3)
    path = peridyn.save_state(tmp_path / "state.npz", solver)
    for _ in range(AFTER):
        solver.step()
    restored, restored_layers = gpu_scene()
    peridyn.load_state(path, restored)
    for _ in range(AFTER):
        restored.step()
    assert_same(state(restored_layers), state(layers))
