"""Box and capsule colliders: exact distances, clearance during a drape, and bad input."""

import numpy as np
import pytest

import peridyn
from conftest import coulomb_slide, make_grid, plate_scene, slope_scene


def test_box_and_capsule_distances_are_exact():
    """Signed distances against hand-computed values (1e-12 m)."""
    turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # 90 degrees about z
    box = peridyn.Box(center=(1.0, 0.0, 0.0), half_extents=(0.5, 0.2, 0.1), rotation=turn)
    points = [[1.0, 0.0, 0.0], [1.0, 0.9, 0.0], [1.3, 0.0, 0.0], [1.0, 0.5, 0.4]]
    # local x axis is world y: half extent 0.5 along world y, 0.2 along world x
    expected = [-0.1, 0.4, 0.1, np.hypot(0.0, 0.3)]
    assert np.allclose(box.signed_distance(points), expected, atol=1e-12)
    cap = peridyn.Capsule(a=(0.0, 0.0, 0.0), b=(1.0, 0.0, 0.0), radius=0.1)
    points = [[0.5, 0.3, 0.0], [-0.4, 0.0, 0.3], [0.5, 0.0, 0.0]]
    assert np.allclose(cap.signed_distance(points), [0.2, 0.4, -0.1], atol=1e-12)


def test_cloth_draped_over_a_box_and_a_capsule_keeps_its_half_thickness():
    """A cloth falling onto a box (table) and a capsule (rail): after every step every vertex
    keeps at least half the thickness (0.5 mm) from both surfaces (to 1e-9 m)."""
    v, t = make_grid(16, 16, 0.8, 0.8)
    v[:, :2] -= 0.4
    v[:, 2] = 0.3
    m = peridyn.Membrane(v, t, thickness=1e-3, density=300.0,
                         material=peridyn.StretchA3(s0=2e4), bending=1e-6)
    s = peridyn.Solver(dt=2e-3, tol=1e-4, max_iters=200)
    s.add(m)
    box = peridyn.Box(center=(0.0, 0.0, 0.0), half_extents=(0.2, 0.2, 0.1))
    cap = peridyn.Capsule(a=(-0.3, -0.25, 0.15), b=(0.3, -0.25, 0.15), radius=0.05)
    s.add_collider(box)
    s.add_collider(cap)
    touched = False
    for _ in range(150):
        s.step()
        d_box, d_cap = box.signed_distance(m.positions), cap.signed_distance(m.positions)
        assert d_box.min() >= 0.5e-3 - 1e-9 and d_cap.min() >= 0.5e-3 - 1e-9
        touched |= bool((d_box < 0.6e-3).any() and (d_cap < 0.6e-3).any())
    assert touched, "the cloth never reached both colliders"


@pytest.mark.parametrize("make, match", [
    (lambda: peridyn.Box(center=(0, 0, 0), half_extents=(1, 0, 1)), r"half_extents\[1\]"),
    (lambda: peridyn.Box(center=(0, 0, 0), half_extents=(1, 1, 1),
                         rotation=[[1, 0.2, 0], [0, 1, 0], [0, 0, 1]]), "rotation"),
    (lambda: peridyn.Box(center=(0, np.nan, 0), half_extents=(1, 1, 1)), "center"),
    (lambda: peridyn.Capsule(a=(0, 0, 0), b=(1, 0, 0), radius=-1.0), "radius"),
    (lambda: peridyn.Capsule(a=(0, 0, np.inf), b=(1, 0, 0), radius=1.0), "end a"),
])
def test_bad_colliders_raise_value_errors_naming_the_value(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_cloth_dropped_on_a_table_with_friction_comes_to_rest():
    """A cloth dropped onto a table tilted by 0.2 rad, friction 0.8 (> tan 0.2): it settles,
    its kinetic energy falling below 1e-7 J within 0.6 s (from about 1e-3 J at impact) without
    jitter (no step in the last 0.1 s gains more than 1e-9 J). Frictionless, it slides down
    the tilt instead."""
    c, s_ = np.cos(0.2), np.sin(0.2)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s_], [0.0, s_, c]])  # about x

    def drop(friction):
        v, t = make_grid(10, 10, 0.3, 0.3)
        v[:, :2] -= 0.15
        v[:, 2] = 0.2
        m = peridyn.Membrane(v, t, thickness=1e-3, density=300.0,
                             material=peridyn.StretchA3(s0=2e4), bending=1e-5)
        s = peridyn.Solver(dt=2e-3, tol=1e-6, max_iters=300)
        s.add(m)
        s.add_collider(peridyn.Box(center=(0.0, 0.0, 0.0), half_extents=(0.5, 0.5, 0.1),
                                   rotation=turn, friction=friction))
        energies = []
        for _ in range(300):
            s.step()
            energies.append(m.kinetic_energy())
        return m, np.array(energies)

    m, ke = drop(0.8)
    assert ke.max() > 1e-4  # it did fall and hit
    assert ke[-1] < 1e-7
    assert np.diff(ke[-50:]).max() < 1e-9
    slid, _ = drop(0.0)
    assert slid.positions[:, 1].mean() < m.positions[:, 1].mean() - 0.02


@pytest.mark.parametrize("shape", ["plane", "box", "capsule", "mesh"])
@pytest.mark.parametrize("mu", [1.0, 0.1])
def test_friction_on_a_slope_follows_coulomb_for_every_shape(shape, mu):
    """Each collider's `friction=` is Coulomb's law on a slope of tan 0.5 (f64, 0.2 s): with
    mu = 1 the cloth stays put (within 0.2 mm, where frictionless it would slide 88 mm), with
    mu = 0.1 it slides as a block under implicit Euler (71 mm) within 1 %."""
    m, sol, downhill, x0 = slope_scene("cpu", "f64", shape, mu)
    for _ in range(100):
        sol.step()
    slide = ((m.positions - x0) @ downhill).mean()
    expected = coulomb_slide(mu, steps=100)
    if expected == 0.0:
        assert abs(slide) < 2e-4, slide
    else:
        assert slide == pytest.approx(expected, rel=0.01)


def test_moving_collider_carries_the_cloth_and_keeps_it_outside():
    """A plate moving at 0.2 m/s under a resting cloth (friction 1) carries it along, and the
    distance is checked at the collider's time."""
    v, t = make_grid(8, 8, 0.3, 0.3)
    v[:, 2] = 0.0005
    m = peridyn.Membrane(v, t, thickness=1e-3, density=300.0, material=peridyn.StretchA3(s0=2e4))
    s = peridyn.Solver(dt=5e-3, tol=1e-7, max_iters=500)
    s.add(m)
    plate = peridyn.Box(center=(0.15, 0.15, -0.05), half_extents=(1.0, 1.0, 0.05),
                        friction=1.0, velocity=(0.2, 0.0, 0.0))
    s.add_collider(plate)
    for _ in range(40):
        s.step()
        assert plate.signed_distance(m.positions, time=s.time).min() >= 0.5e-3 - 1e-9
    assert np.allclose(m.velocities[:, 0], 0.2, atol=1e-4)


@pytest.mark.parametrize("contact", [False, True], ids=["no-contact", "contact"])
@pytest.mark.parametrize("speed, half", [(5.0, 1e-3), (50.0, 1e-3), (50.0, 0.02)])
def test_a_fast_cloth_stops_on_a_thin_plate_instead_of_passing_through(speed, half, contact):
    """A cloth shot at 5 or 50 m/s at a plate 2 mm or 4 cm thick moves 5-50 cm in its first
    step of 10 ms, past the plate: nearest-surface projection alone would put it under the
    plate. It lands on the top face instead: after every step every vertex is half the
    thickness (0.5 mm) above it, to 1 um, with or without the contact local step."""
    s, m, plate = plate_scene(half, speed=speed, contact=contact)
    for _ in range(5):
        s.step()
        z = m.positions[:, 2]
        assert z.min() >= half + 0.5e-3 - 1e-9, z.min()
        assert z.max() <= half + 0.5e-3 + 1e-6, z.max()


def test_a_fast_plate_lifts_a_cloth_instead_of_passing_through_it():
    """A plate 2 mm thick moving up at 20 m/s (0.2 m per step of 10 ms) under a cloth hanging
    still in the air: the cloth ends on the plate's top face where the plate is at the end of
    every step, not below the plate."""
    s, m, plate = plate_scene(1e-3, lift=20.0)
    for _ in range(5):
        s.step()
        d = plate.signed_distance(m.positions, time=s.time)
        assert d.min() >= 0.5e-3 - 1e-9
        assert d.max() <= 0.5e-3 + 1e-6
        assert (m.positions[:, 2] > 20.0 * s.time).all()


def test_a_slanted_fast_cloth_lands_on_a_thin_plate_and_slides_along_it():
    """Shot at 20 m/s, 20 degrees from the normal, at a plate 2 mm thick (0.2 m per step of 10
    ms, through the plate): it lands on the top face, half the thickness above it, and keeps
    the move's part along the face (6.8 cm per step, the slide along the tangent plane where
    the path meets the plate) to 1 %."""
    slant = np.radians(20.0)
    s, m, plate = plate_scene(1e-3, speed=20.0, slant=slant)
    x0 = m.positions[:, 0].mean()
    s.step()
    z = m.positions[:, 2]
    assert z.min() >= 1e-3 + 0.5e-3 - 1e-9 and z.max() <= 1e-3 + 0.5e-3 + 1e-6
    slid = m.positions[:, 0].mean() - x0
    assert slid == pytest.approx(20.0 * np.sin(slant) * 1e-2, rel=0.01)
