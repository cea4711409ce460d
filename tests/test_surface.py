"""The surface mesh of particle bodies (peridyn.particle_surface): closed, outward, enclosing
the particles' volume, per frame from FrameRecorder and drawn by the renderer."""

import numpy as np
import pytest
import trimesh

import peridyn


def _lattice_ball(radius, spacing, center=(0.0, 0.0, 0.0)):
    m = int(np.ceil(radius / spacing)) + 1
    k = np.arange(-m, m + 1) * spacing
    X = np.stack(np.meshgrid(k, k, k, indexing="ij"), -1).reshape(-1, 3)
    return X[np.linalg.norm(X, axis=1) < radius] + np.asarray(center)


def _winding_numbers(V, F, points):
    """Generalised winding numbers of ``points`` about the closed mesh (V, F): 1 inside, 0
    outside (solid angles by Van Oosterom and Strackee 1983)."""
    out = []
    for p in points:
        a, b, c = (V[F[:, k]] - p for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        num = np.einsum("ij,ij->i", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
               + np.einsum("ij,ij->i", c, a) * lb)
        out.append(2.0 * np.arctan2(num, den).sum() / (4.0 * np.pi))
    return np.array(out)


def test_ball_surface_is_closed_outward_and_encloses_the_particles_volume():
    s, R = 0.01, 0.06
    X = _lattice_ball(R, s)
    V, F = peridyn.particle_surface(X, s)
    mesh = trimesh.Trimesh(V, F, process=True)
    assert mesh.is_watertight
    assert mesh.volume > 0.0  # counter-clockwise from outside
    # Each particle stands for a cube of side s: the level 0.5 encloses N s^3 within 4 %.
    assert mesh.volume == pytest.approx(len(X) * s**3, rel=0.04)
    # Every outermost particle lies inside, and the surface within a spacing of a particle.
    outer = X[np.linalg.norm(X, axis=1) > R - 1.5 * s][::3]
    assert np.allclose(_winding_numbers(V, F, outer), 1.0, atol=1e-6)
    beyond = outer * (1.0 + 1.5 * s / np.linalg.norm(outer, axis=1))[:, None]
    assert np.allclose(_winding_numbers(V, F, beyond), 0.0, atol=1e-6)
    nearest = np.min(np.linalg.norm(V[:, None, :] - X[None, ::1, :], axis=2), axis=1)
    assert nearest.max() < s


def test_surface_follows_a_rigid_motion_of_the_particles():
    s = 0.01
    X = _lattice_ball(0.05, s)
    rot = trimesh.transformations.rotation_matrix(0.7, [1.0, 2.0, 0.5])[:3, :3]
    shift = np.array([0.3, -0.2, 1.1])
    V0, F0 = peridyn.particle_surface(X, s)
    V1, F1 = peridyn.particle_surface(X @ rot.T + shift, s)
    m0, m1 = trimesh.Trimesh(V0, F0), trimesh.Trimesh(V1, F1)
    # The grid does not turn with the body: equal up to the grid's resolution.
    assert m1.volume == pytest.approx(m0.volume, rel=0.02)
    assert np.allclose(m1.center_mass, m0.center_mass @ rot.T + shift, atol=0.1 * s)


def test_separate_blobs_give_separate_components_and_spray_has_no_surface():
    s = 0.01
    a = _lattice_ball(0.03, s)
    b = _lattice_ball(0.03, s, center=(0.2, 0.0, 0.0))
    lone = np.array([[0.0, 0.3, 0.0]])  # a single particle far from both
    V, F = peridyn.particle_surface(np.vstack([a, b, lone]), s)
    parts = trimesh.Trimesh(V, F, process=True).split(only_watertight=True)
    assert len(parts) == 2
    assert sorted(round(float(p.center_mass[0]), 2) for p in parts) == [0.0, 0.2]
    V, F = peridyn.particle_surface(lone, s)
    assert V.shape == (0, 3) and F.shape == (0, 3)


def test_a_particle_body_gives_its_own_spacing_and_the_recorder_writes_surfaces(tmp_path):
    s = 0.02
    X = _lattice_ball(0.06, s, center=(0.0, 0.0, 0.2))
    water = peridyn.Particles(X, spacing=s, density=1000.0,
                              material=peridyn.ViscoelasticFluid(viscosity=1e-3))
    V, F = peridyn.particle_surface(water)
    assert np.array_equal(V, peridyn.particle_surface(X, s)[0])
    solver = peridyn.Solver(dt=1e-3)
    solver.add(water)
    rec = peridyn.FrameRecorder(tmp_path, surfaces=True)
    rec.record(solver)
    rec.close()
    surface = trimesh.load(tmp_path / "frame_00000_surface.ply")
    points = trimesh.load(tmp_path / "frame_00000.ply")
    assert len(surface.faces) > 0 and surface.is_watertight
    assert len(points.vertices) == len(X)
    png = peridyn.render_png(tmp_path / "water.png", water, particles="surface")
    assert png.stat().st_size > 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(spacing=0.0), "spacing"),
        (dict(spacing=0.01, radius=0.4), "radius"),
        (dict(spacing=0.01, cell=-1.0), "cell"),
        (dict(spacing=0.01, level=1.0), "level"),
        (dict(spacing=1e-6), "max_cells"),
    ],
)
def test_bad_input_is_refused_by_name(kwargs, match):
    X = _lattice_ball(0.03, 0.01)
    spacing = kwargs.pop("spacing")
    with pytest.raises(ValueError, match=match):
        peridyn.particle_surface(X, spacing, **kwargs)


def test_bad_positions_name_the_particle():
    X = _lattice_ball(0.03, 0.01)
    X[7, 1] = np.nan
    with pytest.raises(ValueError, match="particle 7"):
        peridyn.particle_surface(X, 0.01)
    with pytest.raises(ValueError, match="spacing"):
        peridyn.particle_surface(X[:5])
    with pytest.raises(ValueError, match="surfaces"):
        peridyn.FrameRecorder("unused", fmt=None, surfaces=True)
