"""A simulation saved with `save_state` and restored with `load_state` continues bit for bit."""

import numpy as np
import pytest

import peridyn
from conftest import make_grid


def scene(precision):
    v, t = make_grid(10, 10, 0.5, 0.5)
    m = peridyn.Membrane(v, t, thickness=1e-3, density=300.0,
                         material=peridyn.NeoHookean(s0=4e3, s1=1e3), bending=1e-5)
    m.pin(np.flatnonzero(np.isclose(v[:, 1], 0.5)))
    s = peridyn.Solver(dt=2e-3, tol=1e-5, max_iters=200, precision=precision,
                       acceleration="chebyshev")
    s.add(m)
    s.add_collider(peridyn.Sphere(center=(0.25, 0.2, -0.15), radius=0.1))
    return s, m


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_restored_simulation_continues_bit_for_bit(tmp_path, precision):
    s, m = scene(precision)
    for _ in range(20):
        s.step()
    m.pin_targets = m.pin_targets + [0.0, 0.0, 0.01]  # scripted motion is part of the state
    path = peridyn.save_state(tmp_path / "state.npz", s)
    for _ in range(15):
        s.step()
    expected = (m.positions, m.velocities, s.time, s.steps_taken)

    s2, m2 = scene(precision)
    peridyn.load_state(path, s2)
    for _ in range(15):
        s2.step()
    assert np.array_equal(m2.positions, expected[0])
    assert np.array_equal(m2.velocities, expected[1])
    assert (s2.time, s2.steps_taken) == (expected[2], expected[3])


def test_loading_into_a_different_scene_is_refused(tmp_path):
    s, _ = scene("f64")
    path = peridyn.save_state(tmp_path / "state.npz", s)
    v, t = make_grid(5, 5)
    other = peridyn.Solver(dt=1e-3)
    other.add(peridyn.Membrane(v, t, thickness=1e-3, density=100.0,
                               material=peridyn.StretchA3(s0=1e3)))
    with pytest.raises(ValueError, match="body 0 has 25 vertices"):
        peridyn.load_state(path, other)


def lifted_and_turned(k):
    """The collider's pose after k scripted steps: turned about z by 0.02 k rad (which moves
    the sphere's centre, off the axis) and lifted by 4 mm per step, into the hanging cloth."""
    c, s = np.cos(0.02 * k), np.sin(0.02 * k)
    return dict(rotation=[[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], translation=(0.0, 0.0, 0.004 * k))


@pytest.mark.parametrize("precision", ["f32", "f64"])
def test_restored_simulation_with_a_moved_collider_continues_bit_for_bit(tmp_path, precision):
    s, m = scene(precision)
    for k in range(1, 21):
        s.set_collider_pose(0, **lifted_and_turned(k))
        s.step()
    s.set_collider_pose(0, **lifted_and_turned(21))  # a pending target is part of the state
    path = peridyn.save_state(tmp_path / "state.npz", s)
    pose = s.collider_pose(0)
    for _ in range(15):
        s.step()
    expected = (m.positions, m.velocities, s.collider_pose(0))
    assert m.positions[:, 2].max() > 0.0  # the lifted sphere pushed the cloth up

    s2, m2 = scene(precision)
    peridyn.load_state(path, s2)
    assert np.array_equal(s2.collider_pose(0)[0], pose[0])
    assert np.array_equal(s2.collider_pose(0)[1], pose[1])
    for _ in range(15):
        s2.step()
    assert np.array_equal(m2.positions, expected[0])
    assert np.array_equal(m2.velocities, expected[1])
    assert np.array_equal(s2.collider_pose(0)[1], expected[2][1])


def test_collider_motion_arguments_are_checked():
    s, _ = scene("f64")
    (rotation, translation), target = s.collider_motion(0)
    assert np.array_equal(rotation, np.eye(3)) and np.array_equal(translation, [0.0, 0.0, 0.0])
    assert target is None
    with pytest.raises(ValueError, match="both target_rotation and target_translation"):
        s.set_collider_motion(0, base_rotation=np.eye(3), base_translation=(0, 0, 0),
                              target_rotation=np.eye(3))
    with pytest.raises(ValueError, match="collider index 1 is out of range"):
        s.collider_motion(1)
    with pytest.raises(ValueError, match="rotation"):
        s.set_collider_motion(0, base_rotation=2.0 * np.eye(3), base_translation=(0, 0, 0))
