"""State files (``save_state`` / ``load_state``): the path written is the path returned, a
malformed file of any kind is refused with a ``ValueError`` that says why, loading is all or
nothing, the format carries a version, and a restored run continues bit for bit (with contact:
tests/test_restore_with_contact.py)."""

import zipfile

import numpy as np
import pytest

import peridyn
from peridyn.state import STATE_FORMAT_VERSION
from conftest import make_grid
from test_gpu import gpu, gpu_precision  # noqa: F401  (the fixture and its f64 check)

INVALID = "not a valid peridyn state"


def scene(precision="f64", backend="cpu"):
    """Two sheets (the first pinned along an edge, the second at two corners), a sphere, Chebyshev
    acceleration: everything but contact that a step depends on."""
    s = peridyn.Solver(dt=2e-3, tol=1e-5, max_iters=200, precision=precision,
                       acceleration="chebyshev", backend=backend)
    v, t = make_grid(10, 10, 0.5, 0.5)
    a = peridyn.Membrane(v, t, thickness=1e-3, density=300.0,
                         material=peridyn.NeoHookean(s0=4e3, s1=1e3), bending=1e-5)
    a.pin(np.flatnonzero(np.isclose(v[:, 1], 0.5)))
    v, t = make_grid(6, 6, 0.3, 0.3)
    b = peridyn.Membrane(v + [1.0, 0.0, 0.0], t, thickness=1e-3, density=200.0,
                         material=peridyn.StretchA3(s0=2e3))
    b.pin([0, 5])
    s.add(a)
    s.add(b)
    s.add_collider(peridyn.Sphere(center=(0.25, 0.2, -0.15), radius=0.1))
    return s


def turned(k):
    c, s = np.cos(0.02 * k), np.sin(0.02 * k)
    return dict(rotation=[[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], translation=(0.0, 0.0, 0.004 * k))


def advance(s, steps, moves=True):
    for k in range(steps):
        if moves and s.backend == "cpu":
            s.set_collider_pose(0, **turned(s.steps_taken + 1))
        s.step()


def stepped(precision="f64", steps=10):
    """A scene after `steps` steps, with a state off its defaults: a pending collider target,
    moved pins, a changed dt and self contact switched off on one body."""
    s = scene(precision)
    advance(s, steps)
    s.set_collider_pose(0, **turned(steps + 1))
    s.bodies[0].pin_targets = s.bodies[0].pin_targets + [0.0, 0.0, 0.01]
    s.bodies[1].unpin([5])
    s.dt = 1.5e-3
    s.bodies[1].self_contact = False
    return s


def snapshot(s):
    """Everything the Python API shows of the state, as arrays to compare bit for bit."""
    out = {"time": np.float64(s.time), "steps": np.uint64(s.steps_taken), "dt": np.float64(s.dt)}
    for b, body in enumerate(s.bodies):
        out[f"x{b}"] = body.positions
        out[f"v{b}"] = body.velocities
        out[f"p{b}"] = body.pinned
        out[f"t{b}"] = body.pin_targets
        out[f"c{b}"] = np.bool_(body.self_contact)
    for c in range(len(s.colliders)):
        (r, t), target = s.collider_motion(c)
        out[f"r{c}"], out[f"q{c}"] = r, t
        out[f"target{c}"] = np.array([]) if target is None else np.concatenate([np.ravel(target[0]), target[1]])
        out[f"pose{c}"] = np.concatenate([np.ravel(a) for a in s.collider_pose(c)])
    return out


def assert_same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
        assert a[k].tobytes() == b[k].tobytes(), k


def entries(path):
    with np.load(path) as data:
        return {k: data[k] for k in data.files}


def write(path, arrays, **kw):
    np.savez(path, **arrays, **kw)
    return path


@pytest.fixture
def saved(tmp_path):
    """(solver, file): a stepped scene and its state file, the solver then stepped on (so that
    its state differs from the file's)."""
    s = stepped()
    path = peridyn.save_state(tmp_path / "state.npz", s)
    advance(s, 3)
    s.set_collider_pose(0, **turned(100))
    return s, path


# ---------------------------------------------------------------------------------------------
# the path written is the path returned


@pytest.mark.parametrize("name", ["state.bin", "state", "state.npz", "sub/dir/state.npz"])
def test_the_path_written_is_the_path_returned(tmp_path, name):
    s = stepped()
    path = peridyn.save_state(tmp_path / name, s)
    assert path == tmp_path / name and path.is_file()
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]  # no temporary left
    s2 = scene()
    peridyn.load_state(str(path), s2)
    assert_same(snapshot(s2), snapshot(s))


def test_a_solver_passed_where_the_path_belongs_is_refused_by_name(tmp_path):
    s = stepped()
    with pytest.raises(TypeError, match=r"save_state\(path, solver\)"):
        peridyn.save_state(s, tmp_path / "state.npz")
    assert not list(tmp_path.iterdir())
    path = peridyn.save_state(tmp_path / "state.npz", s)
    with pytest.raises(TypeError, match=r"load_state\(path, solver\)"):
        peridyn.load_state(s, path)


def test_saving_over_a_file_replaces_it(tmp_path):
    s = stepped()
    path = peridyn.save_state(tmp_path / "state.npz", s)
    advance(s, 1)
    assert peridyn.save_state(path, s) == path
    s2 = scene()
    peridyn.load_state(path, s2)
    assert_same(snapshot(s2), snapshot(s))


# ---------------------------------------------------------------------------------------------
# restore and continue: bit for bit


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_save_continue_and_restore_into_a_fresh_solver_is_bit_exact(tmp_path, precision):
    s = stepped(precision)
    path = peridyn.save_state(tmp_path / "state.npz", s)
    at_save = snapshot(s)
    advance(s, 12)
    expected = snapshot(s)

    fresh = scene(precision)
    peridyn.load_state(path, fresh)
    assert_same(snapshot(fresh), at_save)
    advance(fresh, 12)
    assert_same(snapshot(fresh), expected)

    # rewinding the solver that went on works the same way
    peridyn.load_state(path, s)
    assert_same(snapshot(s), at_save)
    advance(s, 12)
    assert_same(snapshot(s), expected)


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_gpu_save_continue_and_restore_is_bit_exact(tmp_path, gpu, precision):  # noqa: F811
    gpu_precision(gpu, precision)
    s = scene(precision, backend="gpu")
    advance(s, 5)
    s.bodies[0].pin_targets = s.bodies[0].pin_targets + [0.0, 0.0, 0.01]
    s.dt = 1.5e-3
    path = peridyn.save_state(tmp_path / "state.npz", s)
    advance(s, 5)
    expected = snapshot(s)
    fresh = scene(precision, backend="gpu")
    peridyn.load_state(path, fresh)
    advance(fresh, 5)
    assert_same(snapshot(fresh), expected)


# ---------------------------------------------------------------------------------------------
# all or nothing


def non_rotation(e):
    e["collider_base_rotation_0"] = 2.0 * e["collider_base_rotation_0"]  # checked by the core


def bad_last_target(e):
    e["pin_targets_1"] = e["pin_targets_1"].copy()
    e["pin_targets_1"][-1, 2] = np.nan


def bad_time(e):
    e["time"] = np.array(np.inf)


def bad_velocity(e):
    e["velocities_1"] = e["velocities_1"].copy()
    e["velocities_1"][3, 0] = np.inf


def pin_out_of_range(e):
    e["pinned_1"] = np.array([0, 36])


def missing_target_half(e):
    del e["collider_target_translation_0"]


@pytest.mark.parametrize("spoil", [non_rotation, bad_last_target, bad_time, bad_velocity,
                                   pin_out_of_range, missing_target_half])
def test_a_bad_entry_leaves_the_solver_exactly_as_it_was(saved, tmp_path, spoil):
    s, path = saved
    e = entries(path)
    spoil(e)
    bad = write(tmp_path / "bad.npz", e)
    before = snapshot(s)
    with pytest.raises(ValueError, match=INVALID):
        peridyn.load_state(bad, s)
    assert_same(snapshot(s), before)
    # and the solver steps on as if nothing had happened
    twin = stepped()
    peridyn.load_state(path, twin)
    advance(twin, 3)
    twin.set_collider_pose(0, **turned(100))
    assert_same(snapshot(twin), before)


# ---------------------------------------------------------------------------------------------
# every malformed file is a ValueError that says why


def refused(path, s, *needles):
    with pytest.raises(ValueError) as info:
        peridyn.load_state(path, s)
    message = str(info.value)
    assert INVALID in message and str(path) in message, message
    for needle in needles:
        assert needle in message, message
    return message


def test_truncated_files_are_refused(saved, tmp_path):
    s, path = saved
    data = path.read_bytes()
    before = snapshot(s)
    for cut in [0, 1, 3, 4, 30, 100, len(data) // 3, len(data) // 2, len(data) - 100,
                len(data) - 22, len(data) - 1]:
        bad = tmp_path / f"cut{cut}.npz"
        bad.write_bytes(data[:cut])
        refused(bad, s)
    assert_same(snapshot(s), before)


def test_corrupt_bytes_are_refused_or_harmless(saved, tmp_path):
    """A flipped byte either makes the file invalid (ValueError) or lands where it changes
    nothing that is read (a zip timestamp): never another exception, never a different state."""
    s, path = saved
    data = path.read_bytes()
    reference = scene()
    peridyn.load_state(path, reference)
    expected = snapshot(reference)
    refusals = 0
    for at in range(0, len(data), max(1, len(data) // 150)):
        flipped = bytearray(data)
        flipped[at] ^= 0xFF
        bad = tmp_path / "flipped.npz"
        bad.write_bytes(bytes(flipped))
        fresh = scene()
        before = snapshot(fresh)
        try:
            peridyn.load_state(bad, fresh)
        except ValueError as e:
            assert INVALID in str(e), str(e)
            assert_same(snapshot(fresh), before)
            refusals += 1
        else:
            assert_same(snapshot(fresh), expected)
    assert refusals > 100


def test_other_files_are_refused(saved, tmp_path):
    s, _ = saved
    npy = tmp_path / "one.npy"
    np.save(npy, np.zeros(3))
    refused(npy, s, "not an .npz")
    text = tmp_path / "text.npz"
    text.write_text("time = 0\n")
    refused(text, s, "not an .npz")
    empty = tmp_path / "empty.npz"
    empty.write_bytes(b"")
    refused(empty, s)
    import pickle

    pickled = tmp_path / "pickled.npz"
    pickled.write_bytes(pickle.dumps({"time": 0.0}))
    refused(pickled, s)
    with pytest.raises(FileNotFoundError):
        peridyn.load_state(tmp_path / "missing.npz", s)


def test_a_zip_with_something_else_than_arrays_is_refused(saved, tmp_path):
    s, path = saved
    bad = tmp_path / "extra.npz"
    bad.write_bytes(path.read_bytes())
    with zipfile.ZipFile(bad, "a") as z:
        z.writestr("notes.txt", "hello")
    refused(bad, s, "'notes.txt'")
    bad = tmp_path / "fake.npz"
    bad.write_bytes(path.read_bytes())
    with zipfile.ZipFile(bad, "a") as z:
        z.writestr("extra.npy", b"\x93NUMPY garbage")
    refused(bad, s, "'extra'")


def test_every_missing_entry_is_named(saved, tmp_path):
    s, path = saved
    e = entries(path)
    before = snapshot(s)
    for key in e:
        spoilt = {k: v for k, v in e.items() if k != key}
        # the solver names its internal entries without the file's prefix
        needle = "" if key == "format_version" else repr(key)
        if key.startswith("internal_"):
            needle = f'missing ["{key[len("internal_"):]}"]'
        refused(write(tmp_path / "missing.npz", spoilt), s, needle)
    assert_same(snapshot(s), before)


def test_an_unexpected_entry_is_refused(saved, tmp_path):
    s, path = saved
    e = entries(path)
    e["positions_2"] = e["positions_1"]
    refused(write(tmp_path / "bad.npz", e), s, "positions_2")


@pytest.mark.parametrize("key, value, needle", [
    ("positions_0", lambda v: v.astype(np.complex128), "complex128"),
    ("positions_0", lambda v: v.astype(np.int64), "int64"),
    ("velocities_1", lambda v: v.astype(str), "<U"),
    ("pinned_0", lambda v: v.astype(np.float64), "float64"),
    ("time", lambda v: np.array(str(v)), "<U"),
    ("steps_taken", lambda v: v.astype(np.float64), "float64"),
    ("bodies", lambda v: np.array(2.0), "float64"),
    ("self_contact_1", lambda v: v.astype(np.int64), "int64"),
    ("format_version", lambda v: np.array(1.0), "float64"),
])
def test_a_wrong_dtype_is_refused(saved, tmp_path, key, value, needle):
    s, path = saved
    e = entries(path)
    e[key] = value(e[key])
    message = refused(write(tmp_path / "bad.npz", e), s, repr(key), needle)
    assert "dtype" in message


def test_object_arrays_are_refused_without_unpickling(saved, tmp_path):
    s, path = saved
    e = entries(path)
    e["time"] = np.array([{"evil": 1}], dtype=object)
    refused(write(tmp_path / "bad.npz", e, allow_pickle=True), s, "'time'", "object")


@pytest.mark.parametrize("key, value, needle", [
    ("steps_taken", np.array(-1), "-1"),
    ("bodies", np.array(2**63 - 1), "9223372036854775807 bodies"),
    ("bodies", np.array(-2), "-2"),
    ("colliders", np.array(2**40), "1099511627776 colliders"),
    ("time", np.array(np.inf), "inf"),
    ("time", np.array(np.nan), "nan"),
    ("dt", np.array(-1e-3), "-0.001"),
    ("dt", np.array(np.nan), "nan"),
    ("format_version", np.array(-1), "-1"),
])
def test_out_of_range_values_are_refused(saved, tmp_path, key, value, needle):
    s, path = saved
    e = entries(path)
    e[key] = value
    refused(write(tmp_path / "bad.npz", e), s, needle)


def test_a_value_beyond_the_solvers_precision_is_refused(tmp_path):
    s = stepped("f32")
    path = peridyn.save_state(tmp_path / "state.npz", s)
    e = entries(path)
    e["positions_0"] = e["positions_0"].copy()
    e["positions_0"][7, 1] = 1e39  # finite in f64, inf in f32
    before = snapshot(s)
    refused(write(tmp_path / "bad.npz", e), s, "'positions_0'", "1e+39", "precision")
    assert_same(snapshot(s), before)
    s64 = stepped("f64")
    e["positions_0"][7, 1] = 1e300
    peridyn.load_state(write(tmp_path / "far.npz", e), s64)  # f64 holds it
    assert s64.bodies[0].positions[7, 1] == 1e300


def test_a_shape_mismatch_names_two_different_counts(saved, tmp_path):
    s, path = saved
    e = entries(path)
    e2 = dict(e, positions_0=e["positions_0"][:, :2])
    message = refused(write(tmp_path / "bad.npz", e2), s, "'positions_0'", "(100, 2)", "(100, 3)")
    e2 = dict(e, velocities_1=e["velocities_1"][:30])
    message = refused(write(tmp_path / "bad.npz", e2), s, "body 1 has 36 vertices", "has 30")
    e2 = dict(e, pin_targets_0=e["pin_targets_0"][:4])
    message = refused(write(tmp_path / "bad.npz", e2), s, "'pinned_0' has 10", "has 4")
    e2 = dict(e, collider_base_translation_0=np.zeros(2))
    message = refused(write(tmp_path / "bad.npz", e2), s, "shape (2,), expected (3,)")
    e2 = dict(e, time=np.zeros(1))
    message = refused(write(tmp_path / "bad.npz", e2), s, "'time'", "scalar")
    del message


def test_loading_into_a_different_scene_names_both_counts(tmp_path):
    s = stepped()
    path = peridyn.save_state(tmp_path / "state.npz", s)
    v, t = make_grid(5, 5)
    other = peridyn.Solver(dt=1e-3)
    other.add(peridyn.Membrane(v, t, thickness=1e-3, density=100.0,
                               material=peridyn.StretchA3(s0=1e3)))
    refused(path, other, "2 bodies", "the solver has 1")
    other.add(peridyn.Membrane(v + [2.0, 0, 0], t, thickness=1e-3, density=100.0,
                               material=peridyn.StretchA3(s0=1e3)))
    refused(path, other, "body 0 has 25 vertices", "'positions_0' has 100")
    single = scene()
    single.add_collider(peridyn.Plane(point=(0, 0, -1)))
    refused(path, single, "1 colliders", "the solver has 2")


# ---------------------------------------------------------------------------------------------
# the format version


def test_a_newer_format_version_is_refused_naming_both(saved, tmp_path):
    s, path = saved
    e = entries(path)
    assert int(e["format_version"]) == STATE_FORMAT_VERSION == 3
    e["format_version"] = np.array(STATE_FORMAT_VERSION + 1)
    before = snapshot(s)
    with pytest.raises(ValueError, match=r"format version 4, newer than .*\(0 to 3\)"):
        peridyn.load_state(write(tmp_path / "new.npz", e), s)
    assert_same(snapshot(s), before)


def test_a_version_0_file_still_loads(tmp_path):
    """Files of the format before versions (no format_version, dt or self_contact) load; dt and
    self_contact keep the solver's values."""
    s = stepped()
    path = peridyn.save_state(tmp_path / "state.npz", s)
    e = entries(path)
    for key in ["format_version", "dt", "self_contact_0", "self_contact_1"]:
        del e[key]
    e["steps_taken"] = e["steps_taken"].astype(np.int64)
    old = write(tmp_path / "old.npz", e)
    fresh = scene()
    fresh.dt = s.dt
    fresh.bodies[1].self_contact = False
    peridyn.load_state(old, fresh)
    assert_same(snapshot(fresh), snapshot(s))
    # without its colliders too (the format before collider motion was saved)
    for key in [k for k in e if k.startswith("collider")]:
        del e[key]
    peridyn.load_state(write(tmp_path / "older.npz", e), scene())
    # but not with an entry of version 1 mixed in
    e["dt"] = np.array(1e-3)
    refused(write(tmp_path / "mixed.npz", e), scene(), "'dt'")


def test_the_file_is_a_plain_npz(tmp_path):
    """numpy reads a state file without pickle: the documented entries, nothing else."""
    s = stepped()
    path = peridyn.save_state(tmp_path / "state.npz", s)
    with np.load(path, allow_pickle=False) as data:
        keys = set(data.files)
        assert data["steps_taken"] == s.steps_taken and data["time"] == s.time
    expected = {"format_version", "time", "steps_taken", "dt", "bodies", "colliders"}
    for b in range(2):
        expected |= {f"{k}_{b}" for k in ["positions", "velocities", "pinned", "pin_targets", "self_contact"]}
    expected |= {f"collider_{p}_{k}_0" for p in ["base", "target"] for k in ["rotation", "translation"]}
    expected |= {f"internal_{name}" for name in s.internal_state()}
    assert keys == expected


# ---------------------------------------------------------------------------------------------
# internal state a solver exposes (the hook for what the core keeps between steps: contact warm
# starts and rest gaps, tests/test_restore_with_contact.py): saved, checked and restored with
# the rest, all or nothing


class WithInternalState(peridyn.Solver):
    """A solver that exposes internal state of its own kind (io's hook is generic)."""

    refuse = False

    def internal_state(self):
        return dict(getattr(self, "_internal", {}))

    def set_internal_state(self, state):
        if self.refuse and len(state.get("warm", ())) == 7:  # not its own current state
            raise ValueError("set_internal_state: warm start of the wrong size")
        self._internal = {k: np.array(v) for k, v in state.items()}


def with_internal_state():
    s = WithInternalState(dt=2e-3)
    v, t = make_grid(5, 5)
    s.add(peridyn.Membrane(v, t, thickness=1e-3, density=100.0, material=peridyn.StretchA3(s0=1e3)))
    s._internal = {"warm": np.linspace(0.0, 1.0, 7), "active": np.array([True, False])}
    return s


def test_internal_state_is_saved_checked_and_restored_all_or_nothing(tmp_path):
    s = with_internal_state()
    s.step()
    path = peridyn.save_state(tmp_path / "state.npz", s)
    assert {"internal_warm", "internal_active"} <= set(entries(path))
    fresh = with_internal_state()
    fresh._internal = {}
    peridyn.load_state(path, fresh)
    assert fresh._internal.keys() == s._internal.keys()
    assert all(np.array_equal(fresh._internal[k], s._internal[k]) for k in s._internal)
    assert_same(snapshot(fresh), snapshot(s))

    # a bad internal entry is refused before anything changes
    s.step()
    s._internal = {"warm": np.zeros(3)}
    before, internal = snapshot(s), s.internal_state()
    e = entries(path)
    e["internal_warm"] = e["internal_warm"].copy()
    e["internal_warm"][2] = np.nan
    refused(write(tmp_path / "nan.npz", e), s, "'internal_warm'", "nan")
    e["internal_warm"] = np.array([{"x": 1}], dtype=object)
    refused(write(tmp_path / "object.npz", e, allow_pickle=True), s, "'internal_warm'", "object")
    assert_same(snapshot(s), before)
    # the solver refusing it undoes everything
    s.refuse = True
    refused(path, s, "wrong size")
    assert_same(snapshot(s), before)
    assert s.internal_state().keys() == internal.keys()
    assert np.array_equal(s.internal_state()["warm"], internal["warm"])

    # the core solver refuses internal state that is not its own, naming the entries; a file
    # without internal state resets it
    plain = peridyn.Solver(dt=2e-3)
    v, t = make_grid(5, 5)
    plain.add(peridyn.Membrane(v, t, thickness=1e-3, density=100.0, material=peridyn.StretchA3(s0=1e3)))
    refused(path, plain, 'unknown ["active", "warm"]', 'missing ["contact_warm_start"')
    e = entries(path)
    for key in [k for k in e if k.startswith("internal_")]:
        del e[key]
    s.refuse = False
    peridyn.load_state(write(tmp_path / "none.npz", e), s)
    assert s.internal_state() == {}


def test_the_state_functions_still_answer_from_peridyn_io():
    """save_state, load_state and STATE_FORMAT_VERSION moved to peridyn.state; code that took
    them from peridyn.io (their home before) still finds the same objects there."""
    import peridyn.io
    import peridyn.state

    for name in ("save_state", "load_state", "STATE_FORMAT_VERSION"):
        assert getattr(peridyn.io, name) is getattr(peridyn.state, name)
    with pytest.raises(AttributeError):
        peridyn.io.no_such_name
