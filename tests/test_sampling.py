"""peridyn.sample_volume and peridyn.sample_surface: particles from meshes (issue 38, item 1)."""

import numpy as np
import pytest

import peridyn


def box(h=0.5):
    """Closed cube of half side ``h`` (m) at the origin, outward triangles."""
    v = np.array([[x, y, z] for z in (-h, h) for y in (-h, h) for x in (-h, h)], dtype=float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    f = np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])
    return v, f


def min_pair_distance(x):
    from scipy.spatial import cKDTree

    d, _ = cKDTree(x).query(x, k=2)
    return d[:, 1].min()


def convex_gap(mesh, x):
    """max over faces of n . (x - v): the signed distance to a convex mesh's plane set
    (negative strictly inside, zero on the surface)."""
    n = mesh.face_normals
    v0 = mesh.vertices[mesh.faces[:, 0]]
    return (x @ n.T - np.einsum("ij,ij->i", n, v0)).max(axis=1)


def test_a_unit_cube_gives_its_lattice():
    x = peridyn.sample_volume(box(), spacing=0.1)
    assert isinstance(x, np.ndarray) and x.dtype == np.float64 and x.shape == (1000, 3)
    assert np.all(np.abs(x) < 0.5)
    assert min_pair_distance(x) == pytest.approx(0.1, rel=1e-9)
    # Lattice sites at the cell centres.
    np.testing.assert_allclose(np.sort(np.unique(np.round(x[:, 0], 9))),
                               np.arange(-0.45, 0.5, 0.1), atol=1e-12)


def test_a_trimesh_sphere_count_matches_its_volume_and_seeds_repeat():
    trimesh = pytest.importorskip("trimesh")
    ball = trimesh.creation.icosphere(subdivisions=3, radius=0.1)
    s = 0.01
    x = peridyn.sample_volume(ball, spacing=s)
    # |N s^3 - V| <= A s / 2 (a half-spacing surface layer)
    assert abs(len(x) * s**3 - ball.volume) <= 0.5 * ball.area * s
    assert np.all(convex_gap(ball, x) < 0)
    y = peridyn.sample_volume((ball.vertices, ball.faces), s, jitter=0.25, seed=3)
    np.testing.assert_array_equal(y, peridyn.sample_volume(ball, s, jitter=0.25, seed=3))
    assert not np.array_equal(y, peridyn.sample_volume(ball, s, jitter=0.25, seed=4))
    assert min_pair_distance(y) >= 0.5 * s * (1 - 1e-9)
    assert np.all(convex_gap(ball, y) < 0)


def test_a_surface_layer_is_spaced_and_on_the_surface():
    trimesh = pytest.importorskip("trimesh")
    ball = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
    s = 0.1
    x = peridyn.sample_surface(ball, spacing=s, seed=1)
    assert x.shape[1] == 3 and x.dtype == np.float64
    assert min_pair_distance(x) >= s * (1 - 1e-12)
    assert np.abs(convex_gap(ball, x)).max() < 1e-12
    assert 0.55 < len(x) * s**2 / ball.area < 0.85
    np.testing.assert_array_equal(x, peridyn.sample_surface(ball, s, seed=1))
    # open surfaces too
    v, f = peridyn.grid(5, 5, size=(1.0, 1.0))
    y = peridyn.sample_surface((v, f), 0.05)
    assert np.all(y[:, 2] == 0) and min_pair_distance(y) >= 0.05 * (1 - 1e-12)


@pytest.mark.parametrize("fdt", [np.float32, np.int64])
@pytest.mark.parametrize("idt", [np.int32, np.uint16, np.int64])
def test_any_real_and_integer_dtypes(fdt, idt):
    v, f = box(1)
    x = peridyn.sample_volume((v.astype(fdt), f.astype(idt)), 0.5)
    assert x.shape == (64, 3)


def test_bad_input_raises_value_error_naming_the_culprit():
    v, f = box()
    cases = [
        ((v, f), dict(spacing=0.0), "spacing"),
        ((v, f), dict(spacing=float("nan")), "spacing"),
        ((v, f), dict(spacing=0.1, jitter=0.5), "jitter"),
        ((v, f), dict(spacing=0.1, seed=-1), "seed"),
        ((v[:, :2], f), dict(spacing=0.1), "vertices"),
        ((v.astype(complex), f), dict(spacing=0.1), "vertices"),
        ((v > 0, f), dict(spacing=0.1), "vertices"),
        ((v, f.astype(float)), dict(spacing=0.1), "triangles"),
        ((v, f[:, :2]), dict(spacing=0.1), "triangles"),
        ((np.where(np.arange(8)[:, None] == 3, np.nan, v), f), dict(spacing=0.1), "vertex 3"),
        ((v, f[:-1]), dict(spacing=0.1), "edge"),
        ((v, f + 1), dict(spacing=0.1), "triangle"),
        ((v, f), dict(spacing=1e-4), "particles"),
    ]
    for mesh, kwargs, culprit in cases:
        with pytest.raises(ValueError, match=culprit):
            peridyn.sample_volume(mesh, **kwargs)
    with pytest.raises(ValueError, match="Trimesh or a"):
        peridyn.sample_volume(v, spacing=0.1)
    with pytest.raises(ValueError, match="spacing"):
        peridyn.sample_surface((v, f), spacing=-1.0)
    with pytest.raises(ValueError, match="candidate points"):
        peridyn.sample_surface((v, f), spacing=1e-5)
    with pytest.raises(ValueError, match="vertex 3"):
        peridyn.sample_surface((np.where(np.arange(8)[:, None] == 3, np.inf, v), f), 0.1)
