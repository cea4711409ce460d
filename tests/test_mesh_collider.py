"""MeshCollider (a closed mesh as a signed distance grid) and colliders driven by per-step poses."""

import numpy as np
import pytest
import trimesh

import peridyn
from conftest import icosphere, make_grid

MARGIN = 0.5e-3  # half the cloth thickness (m)


def random_points(n, half, seed):
    return np.random.default_rng(seed).uniform(-half, half, size=(n, 3))


def test_grid_of_a_trimesh_box_and_icosphere_matches_the_analytic_distances():
    """A trimesh box: within 3 cells of the surface the grid is within h/2 of the analytic box
    distance (the kinks at edges and corners cost O(h)), with the right sign wherever the
    analytic distance exceeds that error. An icosphere (1280 triangles): within
    chord error + h^2/r of the analytic sphere."""
    box = peridyn.MeshCollider(trimesh.creation.box(extents=(0.6, 0.4, 0.2)), resolution=32)
    exact = peridyn.Box(center=(0, 0, 0), half_extents=(0.3, 0.2, 0.1))
    h = box.cell_size
    assert h == pytest.approx(0.6 / 32)
    x = random_points(20000, 0.45, 1)
    d, e = box.signed_distance(x), exact.signed_distance(x)
    near = np.abs(e) < 3 * h
    assert np.abs(d - e)[near].max() < 0.5 * h
    sure = np.abs(e) > 0.5 * h
    assert np.array_equal(np.sign(d[sure]), np.sign(e[sure]))

    r = 0.3
    v, t = icosphere(3, r)
    ball = peridyn.MeshCollider(v, t, resolution=48)
    h = ball.cell_size
    centroids = v[t].mean(axis=1)
    chord = r - np.linalg.norm(centroids, axis=1).min()
    x = random_points(20000, 0.4, 2)
    e = np.linalg.norm(x, axis=1) - r
    d = ball.signed_distance(x)
    near = np.abs(e) < 3 * h
    assert np.abs(d - e)[near].max() < chord + h * h / r
    sure = np.abs(e) > chord + h * h / r
    assert np.array_equal(np.sign(d[sure]), np.sign(e[sure]))


def test_inside_out_mesh_and_trimesh_input_give_the_same_field():
    v, t = icosphere(2, 0.2)
    a = peridyn.MeshCollider(v, t, resolution=16)
    b = peridyn.MeshCollider(v, t[:, ::-1], resolution=16)
    c = peridyn.MeshCollider(trimesh.Trimesh(v, t, process=False), resolution=16)
    x = random_points(500, 0.3, 3)
    # Reversed corners change the closest-point arithmetic in the last bits only.
    assert np.allclose(a.signed_distance(x), b.signed_distance(x), rtol=0, atol=1e-14)
    assert np.array_equal(a.signed_distance(x), c.signed_distance(x))
    assert np.array_equal(np.roll(b.triangles, -1, axis=1), t)  # turned outward
    assert a.grid_shape == (a.grid_shape[0],) * 3
    lo, hi = a.bounds
    assert np.all(lo < v.min(axis=0)) and np.all(hi > v.max(axis=0))


def drop(collider, steps=120, n=12, size=0.5, height=0.15):
    """A cloth dropped from ``height`` onto ``collider``; returns the membrane and the smallest
    clearance from the collider over every step."""
    v, t = make_grid(n, n, size, size)
    v[:, :2] -= size / 2
    v[:, 2] = height
    m = peridyn.Membrane(v, t, thickness=2 * MARGIN, density=300.0,
                         material=peridyn.StretchA3(s0=2e4), bending=1e-5)
    s = peridyn.Solver(dt=2e-3, tol=1e-5, max_iters=200)
    s.add(m)
    s.add_collider(collider)
    clearance = np.inf
    for _ in range(steps):
        s.step()
        clearance = min(clearance, collider.signed_distance(m.positions).min())
    return m, clearance


def test_cloth_rests_on_a_mesh_box_as_on_the_analytic_box():
    """A cloth dropped on a trimesh box (MeshCollider) ends where it ends on pd.Box: every
    vertex within 2 mm (the grid has h = 4.7 mm and rounds the box's edges by less than h/2),
    the part over the top face at the same height (1e-6 m: the field is exact there) and within
    0.5 mm sideways; no vertex ever comes closer than the margin."""
    mesh = trimesh.creation.box(extents=(0.3, 0.3, 0.2))
    mesh.apply_translation((0.0, 0.0, -0.1))
    on_mesh, clearance = drop(peridyn.MeshCollider(mesh, resolution=64))
    on_box, _ = drop(peridyn.Box(center=(0, 0, -0.1), half_extents=(0.15, 0.15, 0.1)))
    assert clearance >= MARGIN - 1e-9
    gap = np.linalg.norm(on_mesh.positions - on_box.positions, axis=1)
    top = np.all(np.abs(on_box.positions[:, :2]) < 0.1, axis=1)
    assert top.sum() > 10
    assert gap.max() < 2e-3
    assert gap[top].max() < 0.5e-3
    assert on_box.positions[top, 2] == pytest.approx(MARGIN, abs=1e-6)
    assert on_mesh.positions[top, 2] == pytest.approx(MARGIN, abs=1e-6)


def test_cloth_drapes_over_a_mesh_sphere_as_over_the_analytic_sphere():
    """A drape over an icosphere MeshCollider (1280 triangles, chord error 0.54 mm, grid
    h = 5 mm) matches the drape over pd.Sphere of the same radius: the vertex over the pole
    within 1 mm, the vertices within 1.5 mm on average and 6 mm at most (folds amplify the
    facets; measured 0.63, 0.95 and 4.75 mm); the cloth never comes closer than the margin to
    the mesh field."""
    r = 0.12
    v, t = icosphere(3, r)
    field = peridyn.MeshCollider(v, t, resolution=48)
    on_mesh, clearance = drop(field)
    on_ball, _ = drop(peridyn.Sphere(center=(0, 0, 0), radius=r))
    assert clearance >= MARGIN - 1e-9
    gap = np.linalg.norm(on_mesh.positions - on_ball.positions, axis=1)
    pole = np.argmax(on_ball.positions[:, 2])
    assert gap[pole] < 1e-3
    assert gap.mean() < 1.5e-3
    assert gap.max() < 6e-3
    assert on_ball.positions[:, 2].min() < -0.05  # it did drape


def resting_cloth(n=8, size=0.2, center=(0.0, 0.0)):
    v, t = make_grid(n, n, size, size)
    v[:, :2] += np.asarray(center) - size / 2
    v[:, 2] = MARGIN
    return peridyn.Membrane(v, t, thickness=2 * MARGIN, density=300.0,
                            material=peridyn.StretchA3(s0=2e4), bending=1e-5)


def test_a_lifted_plane_and_mesh_box_push_a_resting_cloth_up_by_the_lift():
    """Colliders lifted 10 mm over 20 steps by set_collider_pose carry a cloth resting on them
    (frictionless): after 40 more steps the cloth rests 10 mm higher (1e-6 m); at every step it
    keeps the margin from the collider where the collider is then."""
    for make in (lambda: peridyn.Plane(),
                 lambda: peridyn.MeshCollider(trimesh.creation.box(extents=(0.4, 0.4, 0.1)).
                                              apply_translation((0, 0, -0.05)), resolution=40)):
        collider = make()
        m = resting_cloth()
        s = peridyn.Solver(dt=5e-3, tol=1e-7, max_iters=300)
        s.add(m)
        s.add_collider(collider)
        z0 = m.positions[:, 2].copy()
        for k in range(60):
            if k < 20:
                s.set_collider_pose(0, translation=(0.0, 0.0, 0.5e-3 * (k + 1)))
            s.step()
            rotation, translation = s.collider_pose(0)
            local = (m.positions - translation) @ np.asarray(rotation)
            assert collider.signed_distance(local).min() >= MARGIN - 1e-9
        assert np.asarray(s.collider_pose(0)[1]) == pytest.approx([0, 0, 0.01], abs=1e-15)
        assert m.positions[:, 2] - z0 == pytest.approx(0.01, abs=1e-6)


def test_collider_pose_and_motion_read_back_as_arrays_in_the_given_row_order():
    """A pose set for the next step is the collider's pose after it, as a (3, 3) rotation
    whose rows are the ones given and a (3,) translation; `collider_motion` returns arrays
    too, with no target pending once the step has taken it."""
    s = peridyn.Solver(dt=1e-3)
    s.add(resting_cloth())
    s.add_collider(peridyn.Plane())
    c, sn = np.cos(0.3), np.sin(0.3)
    rotation = [[c, -sn, 0.0], [sn, c, 0.0], [0.0, 0.0, 1.0]]
    s.set_collider_pose(0, rotation=rotation, translation=(0.1, -0.2, 0.3))
    (base_r, base_t), target = s.collider_motion(0)
    assert isinstance(target[0], np.ndarray) and target[0].shape == (3, 3)
    np.testing.assert_allclose(target[0], rotation, atol=1e-15)
    np.testing.assert_array_equal(base_t, [0.0, 0.0, 0.0])
    s.step()
    r, t = s.collider_pose(0)
    assert isinstance(r, np.ndarray) and r.shape == (3, 3) and r.dtype == np.float64
    assert isinstance(t, np.ndarray) and t.shape == (3,)
    np.testing.assert_allclose(r, rotation, atol=1e-15)
    np.testing.assert_allclose(t, [0.1, -0.2, 0.3], atol=1e-15)
    assert s.collider_motion(0)[1] is None


def test_a_turning_table_with_friction_carries_the_cloth_around():
    """A box table spun up about z to 1 rad/s over 0.1 s (angular acceleration 10 rad/s^2, so the
    cloth needs at most 2.5 m/s^2 tangentially, well within mu g) and turning on (pose set
    every step), friction 1: a cloth lying off-centre on it turns with it. After 0.45 rad
    every vertex's angle about z has grown by the table's within 1% and its radius is
    unchanged within 0.2 mm; without friction the cloth stays put (within 1 mm). A sudden
    start would make the cloth slip by (omega r)^2 / (2 mu g) first, about 1.5% here."""
    def table_angle(t, omega=1.0, ramp=0.1):
        return omega * t * t / (2 * ramp) if t < ramp else omega * (t - ramp / 2)

    def spin(friction, steps=100, dt=5e-3):
        m = resting_cloth(center=(0.15, 0.0))
        s = peridyn.Solver(dt=dt, tol=1e-7, max_iters=300)
        s.add(m)
        s.add_collider(peridyn.Box(center=(0, 0, -0.05), half_extents=(0.4, 0.4, 0.05),
                                   friction=friction))
        start = m.positions.copy()
        for k in range(steps):
            a = table_angle(dt * (k + 1))
            c, sn = np.cos(a), np.sin(a)
            s.set_collider_pose(0, rotation=[[c, -sn, 0], [sn, c, 0], [0, 0, 1]])
            s.step()
        return start, m.positions, table_angle(dt * steps)

    start, end, turned = spin(1.0)
    angle = np.arctan2(end[:, 1], end[:, 0]) - np.arctan2(start[:, 1], start[:, 0])
    assert angle == pytest.approx(turned, rel=1e-2)
    radius = np.linalg.norm(end[:, :2], axis=1) - np.linalg.norm(start[:, :2], axis=1)
    assert np.abs(radius).max() < 2e-4
    start, end, _ = spin(0.0)
    assert np.abs(end - start).max() < 1e-3
