"""Tests of the Python layer: mesh building and loading, output, pictures, the run loop,
the default scene and the ``python -m peridyn`` job."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

import peridyn
from peridyn import _core
from peridyn.io import FrameRecorder, write_mesh
from peridyn.mesh import grid, load_mesh

G = 9.81


def small_cloth(n=6, size=0.5, pin=True, **kw):
    V, F = grid(n, n, size=(size, size))
    cloth = peridyn.Membrane(V, F, thickness=1e-3, density=300.0,
                             material=peridyn.StretchA3(s0=2e4), **kw)
    if pin:
        cloth.pin(np.flatnonzero(np.isclose(V[:, 1], size)))
    return cloth


def sorted_centroids(V, F):
    c = np.round(V[F].mean(axis=1), 9)
    return c[np.lexsort(c.T[::-1])]


# --------------------------------------------------------------------------------------------
# mesh.grid


@pytest.mark.parametrize("diagonal", ["alternate", "uniform"])
@pytest.mark.parametrize("nx,ny,a,b", [(2, 2, 1.0, 1.0), (5, 3, 2.0, 0.5), (7, 9, 0.3, 1.7)])
def test_grid_contract(nx, ny, a, b, diagonal):
    V, F = grid(nx, ny, size=(a, b), diagonal=diagonal)
    assert V.dtype == np.float64 and V.shape == (nx * ny, 3)
    assert F.dtype == np.int64 and F.shape == (2 * (nx - 1) * (ny - 1), 3)
    assert np.all(V[:, 2] == 0.0)
    np.testing.assert_allclose(V[:, :2].min(axis=0), [0.0, 0.0])
    np.testing.assert_allclose(V[:, :2].max(axis=0), [a, b])
    # vertex (i, j) has index j * nx + i
    for j in range(ny):
        for i in range(nx):
            np.testing.assert_allclose(V[j * nx + i], [i * a / (nx - 1), j * b / (ny - 1), 0.0])
    # every triangle counter-clockwise seen from +z, and they tile the rectangle exactly
    e1 = V[F[:, 1]] - V[F[:, 0]]
    e2 = V[F[:, 2]] - V[F[:, 0]]
    n = np.cross(e1, e2)
    assert np.all(n[:, 2] > 0.0)
    np.testing.assert_allclose(n[:, :2], 0.0)
    np.testing.assert_allclose(0.5 * n[:, 2].sum(), a * b)
    # a manifold sheet: no repeated triangle, each edge used by one or two triangles
    assert len({tuple(sorted(t)) for t in F.tolist()}) == len(F)
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert counts.max() == 2
    boundary_edges = 2 * (nx - 1) + 2 * (ny - 1)
    assert np.sum(counts == 1) == boundary_edges
    assert F.min() == 0 and F.max() == nx * ny - 1


def test_grid_uniform_triangles_are_the_documented_ones():
    nx, ny = 4, 3
    _, F = grid(nx, ny)
    expected = []
    for j in range(ny - 1):
        for i in range(nx - 1):
            v = j * nx + i
            expected += [[v, v + 1, v + nx + 1], [v, v + nx + 1, v + nx]]
    np.testing.assert_array_equal(F, expected)


def test_grid_default_size_is_unit_square():
    V, _ = grid(3, 4)
    np.testing.assert_allclose(V.max(axis=0), [1.0, 1.0, 0.0])


@pytest.mark.parametrize(
    "args,kwargs,needle",
    [
        ((1, 5), {}, "nx"),
        ((5, 0), {}, "ny"),
        ((2.5, 3), {}, "2.5"),
        ((3, 3), {"size": (-1.0, 1.0)}, "-1.0"),
        ((3, 3), {"size": (1.0, 0.0)}, "size[1]"),
        ((3, 3), {"size": (1.0, float("nan"))}, "nan"),
        ((3, 3), {"diagonal": "zigzag"}, "zigzag"),
    ],
)
def test_grid_rejects_bad_input(args, kwargs, needle):
    with pytest.raises(ValueError) as info:
        grid(*args, **kwargs)
    assert needle in str(info.value)


# --------------------------------------------------------------------------------------------
# mesh.load_mesh and io.write_mesh


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_load_mesh_round_trip_exact(tmp_path, suffix):
    V, F = grid(5, 4, size=(0.4, 0.3))
    V = V + np.array([0.1, -0.2, 0.05])  # away from the origin, non-trivial z
    path = tmp_path / f"sheet{suffix}"
    trimesh.Trimesh(V, F, process=False).export(path)
    V2, F2 = load_mesh(path, merge_vertices=False)
    assert V2.dtype == np.float64 and F2.dtype == np.int64
    np.testing.assert_allclose(V2, V, atol=1e-7)
    np.testing.assert_array_equal(F2, F)


@pytest.mark.parametrize("suffix", [".obj", ".ply"])
def test_load_mesh_merges_seams(tmp_path, suffix):
    # Every triangle with its own three vertices (a "triangle soup"): merging must weld them
    # back into one sheet with the original vertex count and the same triangles geometrically.
    V, F = grid(4, 4, size=(1.0, 1.0))
    soup_V = V[F.ravel()]
    soup_F = np.arange(len(soup_V)).reshape(-1, 3)
    path = tmp_path / f"soup{suffix}"
    trimesh.Trimesh(soup_V, soup_F, process=False).export(path)
    V2, F2 = load_mesh(path)
    assert V2.shape == V.shape and F2.shape == F.shape
    np.testing.assert_allclose(sorted_centroids(V2, F2), sorted_centroids(V, F), atol=1e-9)
    V3, _ = load_mesh(path, merge_vertices=False)
    assert len(V3) == len(soup_V)


def test_load_mesh_concatenates_a_scene(tmp_path):
    a = trimesh.creation.box(extents=(1, 1, 1))
    b = trimesh.creation.icosphere(subdivisions=1)
    b.apply_translation([3.0, 0.0, 0.0])
    path = tmp_path / "two.glb"
    trimesh.Scene([a, b]).export(path)
    V, F = load_mesh(path)
    assert len(F) == len(a.faces) + len(b.faces)
    assert len(V) == len(a.vertices) + len(b.vertices)
    assert V[:, 0].max() > 3.5  # the translated sphere is there


def test_load_mesh_without_triangles_names_the_path(tmp_path):
    path = tmp_path / "points.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((10, 3))).export(path)
    with pytest.raises(ValueError) as info:
        load_mesh(path)
    assert str(path) in str(info.value)
    with pytest.raises(FileNotFoundError):
        load_mesh(tmp_path / "missing.obj")


@pytest.mark.parametrize("suffix", [".ply", ".obj"])
def test_write_mesh_is_read_back_by_trimesh(tmp_path, suffix):
    V, F = grid(3, 3)
    out = write_mesh(tmp_path / f"m{suffix}", V, F)
    assert out.exists()
    m = trimesh.load(out, process=False, maintain_order=True)
    np.testing.assert_allclose(m.vertices, V)
    np.testing.assert_array_equal(m.faces, F)
    with pytest.raises(ValueError, match="stl"):
        write_mesh(tmp_path / "m.stl", V, F)


# --------------------------------------------------------------------------------------------
# Solver.run and RunSummary


def test_the_package_exports_every_public_name_of_the_core():
    """``peridyn`` names its exports; a class the core gains must be added to the list."""
    core = {name for name in dir(_core) if not name.startswith("_")}
    assert core <= set(peridyn.__all__), sorted(core - set(peridyn.__all__))
    assert all(hasattr(peridyn, name) for name in peridyn.__all__)
    assert len(set(peridyn.__all__)) == len(peridyn.__all__)


def test_solver_subclass_passes_keyword_arguments():
    s = peridyn.Solver(dt=2.5e-3, gravity=(0.0, -1.0, 0.0), tol=1e-5, max_iters=7, threads=1)
    assert isinstance(s, _core.Solver) and isinstance(s, peridyn.Solver)
    assert s.dt == 2.5e-3 and s.tol == 1e-5 and s.max_iters == 7 and s.threads == 1
    np.testing.assert_allclose(s.gravity, [0.0, -1.0, 0.0])
    assert s.time == 0.0 and s.steps_taken == 0
    with pytest.raises(TypeError):
        peridyn.Solver(1e-3)  # keyword-only
    with pytest.raises(ValueError):
        peridyn.Solver(dt=-1.0)


def test_run_free_fall_matches_implicit_euler():
    # An unpinned sheet without colliders falls rigidly: implicit Euler from rest gives
    # v_n = n h g and z_n = h^2 g n (n + 1) / 2 exactly (no elastic force on a translation).
    h, n = 1e-3, 20
    cloth = small_cloth(pin=False)
    z0 = cloth.positions[:, 2].copy()
    s = peridyn.Solver(dt=h, threads=1)
    s.add(cloth)
    summary = s.run(n)
    dz = cloth.positions[:, 2] - z0
    np.testing.assert_allclose(dz, -h * h * G * n * (n + 1) / 2, rtol=1e-6)
    np.testing.assert_allclose(cloth.velocities[:, 2], -n * h * G, rtol=1e-6)
    assert summary.steps == summary.steps_requested == n and not summary.stopped_early
    assert summary.time == pytest.approx(n * h) and s.time == pytest.approx(n * h)
    assert s.steps_taken == n


def test_run_summary_fields_agree_with_step_stats():
    s = peridyn.Solver(dt=2e-3, tol=1e-5, max_iters=50, threads=1)
    cloth = small_cloth()
    s.add(cloth)
    seen = []
    summary = s.run(12, callback=lambda solver, st: seen.append((st.step, st.iterations, st.last_move, st.converged)))
    assert [k for k, *_ in seen] == list(range(12))
    its = np.array([it for _, it, _, _ in seen])
    np.testing.assert_array_equal(summary.iterations, its)
    np.testing.assert_array_equal(summary.moves, [r for *_, r, _ in seen])
    assert summary.mean_iterations == pytest.approx(its.mean())
    assert summary.max_iterations == its.max() and 1 <= summary.max_iterations <= 50
    assert summary.converged_fraction == pytest.approx(np.mean([c for *_, c in seen]))
    assert summary.final_move == seen[-1][2]
    # The summary's statistics are computed from its own per-step record (no timing is judged).
    per_step, median, mean = summary.ms_per_step, summary.ms_per_step_median, summary.ms_per_step_mean
    assert per_step.shape == (12,)
    assert median == pytest.approx(np.median(per_step)) and mean == pytest.approx(per_step.mean())
    text = str(summary)
    for word in ("steps", "ms per step", "iterations", "converged", "move"):
        assert word in text


def test_run_callback_stops_early():
    s = peridyn.Solver(dt=1e-3, threads=1)
    s.add(small_cloth())
    calls = []

    def cb(solver, stats):
        calls.append(stats.step)
        assert solver is s
        return stats.step < 2  # False after the third step

    summary = s.run(10, callback=cb)
    assert calls == [0, 1, 2]
    assert summary.steps == 3 and summary.steps_requested == 10 and summary.stopped_early
    assert s.steps_taken == 3 and s.time == pytest.approx(3e-3)
    assert "stopped" in str(summary)


def test_run_with_progress_bar_and_zero_steps(capsys):
    s = peridyn.Solver(dt=1e-3, threads=1)
    s.add(small_cloth())
    summary = s.run(3, progress=True)
    assert summary.steps == 3
    err = capsys.readouterr().err
    assert "3/3" in err and "it=" in err
    empty = s.run(0)
    no_median = empty.ms_per_step_median  # NaN: no step was taken
    assert empty.steps == 0 and np.isnan(no_median) and empty.time == pytest.approx(3e-3)
    with pytest.raises(ValueError):
        s.run(-1)


# --------------------------------------------------------------------------------------------
# FrameRecorder and render_png


def test_frame_recorder_writes_frames_and_npz(tmp_path):
    s = peridyn.Solver(dt=1e-3, threads=1)
    cloth = small_cloth(n=6)
    s.add(cloth)
    rec = FrameRecorder(tmp_path / "rec", every=2)
    assert rec.record(s) == 0
    s.run(6, callback=rec)
    npz = rec.close()
    names = sorted(p.name for p in (tmp_path / "rec").glob("*.ply"))
    assert names == [f"frame_{k:05d}.ply" for k in range(4)]
    data = np.load(npz)
    assert data["positions_0"].shape == (4, 36, 3)
    np.testing.assert_array_equal(data["steps"], [0, 2, 4, 6])
    np.testing.assert_allclose(data["times"], [0.0, 2e-3, 4e-3, 6e-3])
    np.testing.assert_array_equal(data["triangles_0"], cloth.triangles)
    np.testing.assert_allclose(data["positions_0"][0], cloth.rest_positions)
    np.testing.assert_allclose(data["positions_0"][-1], cloth.positions)
    last = trimesh.load(tmp_path / "rec" / "frame_00003.ply", process=False)
    np.testing.assert_allclose(last.vertices, cloth.positions, atol=1e-6)  # PLY stores float32
    assert rec.close() == npz  # idempotent
    with pytest.raises(RuntimeError):
        rec.record(s)


def test_frame_recorder_two_bodies_obj(tmp_path):
    s = peridyn.Solver(dt=1e-3, threads=1)
    s.add(small_cloth(n=4))
    s.add(small_cloth(n=5))
    with FrameRecorder(tmp_path, fmt="obj") as rec:
        rec.record(s)
        s.step()
        rec.record(s)
    assert sorted(p.name for p in tmp_path.glob("*.obj")) == [
        "body0_frame_00000.obj", "body0_frame_00001.obj", "body1_frame_00000.obj", "body1_frame_00001.obj",
    ]
    data = np.load(tmp_path / "frames.npz")
    assert data["positions_0"].shape == (2, 16, 3) and data["positions_1"].shape == (2, 25, 3)
    with pytest.raises(ValueError):
        FrameRecorder(tmp_path, fmt="stl")
    with pytest.raises(ValueError):
        FrameRecorder(tmp_path, every=0)


def test_render_png_writes_a_png(tmp_path):
    V, F = grid(10, 10)
    colliders = [peridyn.Sphere(center=(0.5, 0.5, -0.3), radius=0.25), peridyn.Plane(point=(0, 0, -0.6))]
    out = peridyn.render_png(tmp_path / "a.png", [(V, F), small_cloth()], colliders=colliders, title="test")
    data = out.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    single = peridyn.render_png(tmp_path / "b.png", (V, F))
    assert single.read_bytes()[:4] == b"\x89PNG"


def test_render_draws_a_mesh_collider_where_it_is():
    """A mesh box between two strips of cloth changes the picture inside the box's projected
    outline (its triangles are drawn) and nowhere else (it lies within the strips' bounds, so
    the view is unchanged)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from mpl_toolkits.mplot3d import proj3d

    V, F = grid(10, 3, size=(1.0, 0.1))
    strips = [(V, F), (V + [0.0, 0.9, 0.0], F)]  # spanning the unit square at z = 0
    box = trimesh.creation.box(extents=(0.3, 0.3, 0.3))
    box.apply_translation((0.5, 0.5, 0.0))
    collider = peridyn.MeshCollider(box.vertices, box.faces, resolution=8)

    def picture(colliders):
        fig = Figure(figsize=(4.0, 4.0), dpi=80)
        canvas = FigureCanvasAgg(fig)
        ax = fig.add_subplot(projection="3d")
        peridyn.draw_scene(ax, strips, colliders=colliders)
        canvas.draw()
        image = np.asarray(canvas.buffer_rgba())[:, :, :3].astype(float)
        # the box's corners in image pixels (row 0 at the top)
        x, y, _ = proj3d.proj_transform(*box.vertices.T, ax.get_proj())
        px = ax.transData.transform(np.column_stack([x, y]))
        return image, px[:, 0], image.shape[0] - px[:, 1]

    plain, _, _ = picture([])
    drawn, cols, rows = picture([collider])
    changed = np.abs(drawn - plain).sum(axis=2) > 30.0
    r, c = np.nonzero(changed)
    assert len(r) > 300, f"only {len(r)} pixels changed: the mesh collider was not drawn"
    pad = 3.0
    assert rows.min() - pad <= r.min() and r.max() <= rows.max() + pad, (r.min(), r.max(), rows)
    assert cols.min() - pad <= c.min() and c.max() <= cols.max() + pad, (c.min(), c.max(), cols)


# --------------------------------------------------------------------------------------------
# Scenes, helpers and the package


def test_plate_bending_stiffness():
    assert peridyn.plate_bending_stiffness(1.2e6, 0.0, 1e-3) == pytest.approx(1e-4)
    assert peridyn.plate_bending_stiffness(1e6, 0.5, 1e-3) == pytest.approx(1e6 * 1e-9 / 9.0)
    for bad in [(-1.0, 0.0, 1e-3), (1e6, 0.6, 1e-3), (1e6, 0.3, 0.0)]:
        with pytest.raises(ValueError):
            peridyn.plate_bending_stiffness(*bad)


def test_default_scene_setup_and_drape():
    scene = peridyn.default_scene(n=16, dt=2e-3, duration=0.4, threads=1)
    s, cloth, sphere = scene.solver, scene.cloth, scene.sphere
    assert isinstance(s, peridyn.Solver) and scene.steps == 200
    assert len(s.bodies) == 1 and len(s.colliders) == 1
    assert cloth.num_vertices == 256
    V0 = cloth.rest_positions
    np.testing.assert_array_equal(cloth.pinned, np.arange(15 * 16, 256))  # the edge y = size
    # the sphere is under the cloth's free part, below z = 0, and does not touch the flat cloth
    assert sphere.center[2] + sphere.radius < 0.0
    assert 0.0 < sphere.center[1] < 1.0 and 0.0 < sphere.center[0] < 1.0
    summary = s.run(scene.steps)
    P = cloth.positions
    np.testing.assert_allclose(P[cloth.pinned], V0[cloth.pinned])
    assert P[:, 2].min() < -0.1  # it swung down
    assert sphere.signed_distance(P).min() > -0.01  # and did not go through the sphere
    assert np.all(np.isfinite(P)) and summary.steps == 200


def test_package_exports():
    for name in peridyn.__all__:
        assert hasattr(peridyn, name), name
    assert peridyn.Solver is not _core.Solver and issubclass(peridyn.Solver, _core.Solver)
    assert isinstance(peridyn.__version__, str) and peridyn.__version__
    assert (Path(peridyn.__file__).parent / "py.typed").exists()


def test_main_job_runs(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "peridyn", "--n", "12", "--steps", "5", "--out", str(out), "--threads", "1"],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "vertices           144" in text
    assert "steps              5" in text
    assert "ms per step" in text and "iterations/step" in text and "converged" in text
    assert str(out.resolve()) in text
    assert (out / "frame_00000.ply").exists() and (out / "frame_00001.ply").exists()
    assert (out / "final.png").read_bytes()[:4] == b"\x89PNG"
    data = np.load(out / "frames.npz")
    assert data["positions_0"].shape == (2, 144, 3)
    np.testing.assert_array_equal(data["steps"], [0, 5])
    assert "5/5" in proc.stderr  # the progress bar


def test_main_job_runs_the_particle_scene(tmp_path):
    """``--scene torus``: an elastic particle body, written as point clouds and an .npz."""
    out = tmp_path / "out"
    proc = subprocess.run(
        [sys.executable, "-m", "peridyn", "--scene", "torus", "--n", "8", "--steps", "4",
         "--frame-every", "2", "--out", str(out), "--threads", "1", "--no-animation"],
        capture_output=True, text=True, timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    data = np.load(out / "frames.npz")
    n = data["positions_0"].shape[1]
    assert f"particles          {n}" in proc.stdout and n > 50
    assert data["positions_0"].shape == (3, n, 3) and "triangles_0" not in data
    cloud = trimesh.load(out / "frame_00002.ply")
    assert isinstance(cloud, trimesh.PointCloud) and len(cloud.vertices) == n
    np.testing.assert_allclose(cloud.vertices, data["positions_0"][2], atol=1e-6)  # float32 PLY
    assert (out / "final.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("args, message", [
    (["--scene", "torus", "--backend", "gpu"], "cpu only"),
    (["--scene", "torus", "--color", "stretch"], "--color stretch"),
    (["--scene", "torus", "--n", "3"], "--n must be >= 4"),
])
def test_main_job_refuses_what_the_particle_scene_lacks(tmp_path, args, message):
    proc = subprocess.run([sys.executable, "-m", "peridyn", *args, "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and message in proc.stderr, proc.stderr


def test_the_torus_falls_and_comes_to_rest_on_the_ground():
    """The torus scene's physical facts: implicit Euler's free fall while in the air (after
    ``k`` steps every particle has dropped ``g h^2 k (k + 1) / 2``, rigidly), then at rest on
    the ground, above it by no more than the particles' margin."""
    scene = peridyn.scenes.elastic_torus_scene(n=8, drop=0.05, threads=1)
    torus, solver = scene.torus, scene.solver
    start = torus.positions.copy()
    solver.run(6)  # 1/40 s: still in the air
    fall = 9.81 * solver.dt**2 * 6 * 7 / 2
    np.testing.assert_allclose(torus.positions, start - [0.0, 0.0, fall], atol=1e-9)
    solver.run(scene.steps - 6)
    assert np.abs(torus.velocities).max() < 1e-2  # at rest after 1 s
    lowest = torus.positions[:, 2].min()
    assert 0.0 < lowest < 0.5 * torus.spacing + 1e-3
    assert np.isfinite(torus.positions).all()


def test_gravity_tolerance_is_a_tenth_of_a_step_of_free_fall():
    assert peridyn.gravity_tolerance(1e-3) == pytest.approx(9.81e-7, rel=1e-12)
    assert peridyn.gravity_tolerance(2e-3, fraction=0.5) == pytest.approx(0.5 * 9.81 * 4e-6, rel=1e-12)
    assert peridyn.default_scene(n=4).solver.tol == pytest.approx(peridyn.gravity_tolerance(2e-3))
    for bad in (dict(dt=0.0), dict(dt=-1.0), dict(dt=1e-3, fraction=0.0), dict(dt=float("nan"))):
        with pytest.raises(ValueError, match="gravity_tolerance"):
            peridyn.gravity_tolerance(**bad)


def test_the_default_scene_only_dissipates():
    """A passive scene solved at its default tolerance never gains energy (kinetic +
    gravitational + elastic); at tol = 1e-4 m with dt = 2 ms, ten times g dt^2, it does
    (docs/performance.md, "Tolerance and energy")."""
    def largest_rise(**kw):
        scene = peridyn.default_scene(n=24, threads=1, **kw)
        cloth, m = scene.cloth, scene.cloth.masses
        energy = lambda: cloth.kinetic_energy() + 9.81 * float(m @ cloth.positions[:, 2]) + cloth.elastic_energy()
        E = [energy()]
        for _ in range(350):  # the swing onto the sphere and back
            scene.solver.step()
            E.append(energy())
        E = np.array(E)
        return float(np.max(E - np.minimum.accumulate(E))), E[0] - E[-1]
    rise, dissipated = largest_rise()
    assert rise <= 1e-9 * dissipated, (rise, dissipated)
    loose_rise, _ = largest_rise(tol=1e-4)
    assert loose_rise > 1e-5 * dissipated  # what the default avoids (the test can fail)


def test_main_job_rejects_bad_arguments(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "peridyn", "--steps", "-3", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "--steps" in proc.stderr
