"""The IO helpers check what they read and write: ``load_mesh`` refuses corrupt, truncated and
non-finite files with a ``ValueError`` naming the file, ``write_mesh`` refuses indices and
vertices that would make an invalid file, and ``FrameRecorder`` refuses a frame that does not
fit the recording when it is recorded, never losing the ``.npz`` at ``close()``."""

import numpy as np
import pytest
import trimesh

import peridyn
import peridyn.io
from peridyn.io import FrameRecorder, write_mesh
from peridyn.mesh import grid, load_mesh


def exported(tmp_path, suffix):
    V, F = grid(5, 5, size=(0.4, 0.3))
    path = tmp_path / f"sheet.{suffix}"
    trimesh.Trimesh(V, F, process=False).export(path)
    return path


def refused(path, *needles):
    with pytest.raises(ValueError) as info:
        load_mesh(path)
    message = str(info.value)
    assert str(path) in message, message
    for needle in needles:
        assert needle in message, message
    return message


# --------------------------------------------------------------------------------------------
# load_mesh


@pytest.mark.parametrize("suffix", ["ply", "glb", "off"])
def test_a_truncated_mesh_file_is_refused_naming_it(tmp_path, suffix):
    data = exported(tmp_path, suffix).read_bytes()
    for cut in [0, 1, 10, 40, len(data) // 4, len(data) // 2, len(data) - 7, len(data) - 1]:
        path = tmp_path / f"cut{cut}.{suffix}"
        path.write_bytes(data[:cut])
        if suffix != "off" or cut < len(data) // 2:
            refused(path)
        else:
            # OFF cut at a line end is a valid file of fewer triangles (trimesh does not
            # compare the counts of its header): what is read must be a valid mesh.
            try:
                V, F = load_mesh(path)
            except ValueError as e:
                assert str(path) in str(e)
            else:
                assert np.isfinite(V).all() and F.min() >= 0 and F.max() < len(V)


@pytest.mark.parametrize("suffix", ["ply", "obj", "stl", "glb", "off", "dae", "3mf", "xyz", "zip"])
def test_a_corrupt_mesh_file_is_refused_naming_it(tmp_path, suffix):
    path = tmp_path / f"garbage.{suffix}"
    path.write_bytes(np.random.default_rng(1).bytes(500))
    refused(path)
    flipped = bytearray(exported(tmp_path, "ply").read_bytes())
    flipped[5] ^= 0xFF  # in the header
    bad = tmp_path / "flipped.ply"
    bad.write_bytes(bytes(flipped))
    refused(bad)


TRIANGLE = "v 1 0 0\nv 0 1 0\nf 1 2 3\n"


@pytest.mark.parametrize("merge", [True, False])
@pytest.mark.parametrize("first", ["nan 0 0", "0 inf 0", "0 0 -inf", "1e400 0 0", "0 -1e309 0"])
def test_non_finite_or_overflowing_vertices_are_refused(tmp_path, first, merge):
    path = tmp_path / "bad.obj"
    path.write_text(f"v {first}\n" + TRIANGLE)
    with pytest.raises(ValueError) as info:
        load_mesh(path, merge_vertices=merge)
    assert str(path) in str(info.value) and "vertex 0 is not finite" in str(info.value)


def test_overflowing_float32_vertices_in_a_ply_are_refused(tmp_path):
    path = tmp_path / "big.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1e39 0 0\n0 1 0\n3 0 1 2\n"
    )
    with pytest.warns(RuntimeWarning):  # numpy's own warning about the cast
        refused(path, "vertex 1 is not finite")


def test_out_of_range_indices_in_a_file_are_refused(tmp_path):
    path = tmp_path / "bad.ply"
    path.write_text(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"
    )
    refused(path, "triangle 0 holds [0, 1, 7]", "[0, 3)")
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\n" + TRIANGLE.replace("f 1 2 3", "f 1 2 9"))
    refused(path)


# --------------------------------------------------------------------------------------------
# write_mesh


@pytest.mark.parametrize("suffix", ["ply", "obj"])
@pytest.mark.parametrize("F, needle", [
    ([[0, 1, 9]], "[0, 1, 9]"),
    ([[0, 1, 3]], "[0, 1, 3]"),
    ([[-1, 1, 2]], "[-1, 1, 2]"),
    (np.array([[0, 1, 2**64 - 1]], dtype=np.uint64), "18446744073709551615"),
    ([[0, 1, 2.5]], "2.5"),
    ([[0, 1, np.nan]], "nan"),
    ([[0, 1, 2], [0, 1.0000001, 2]], "triangle 1"),
    (np.array([[True, False, True]]), "bool"),
    ([["0", "1", "2"]], "<U1"),
    (np.array([[0, 1, 2j]]), "complex"),
])
def test_write_mesh_refuses_bad_indices(tmp_path, suffix, F, needle):
    V, _ = grid(2, 2)  # 4 vertices
    V = V[:3]
    path = tmp_path / f"m.{suffix}"
    with pytest.raises(ValueError) as info:
        write_mesh(path, V, F)
    assert needle in str(info.value)
    assert not path.exists()


@pytest.mark.parametrize("suffix", ["ply", "obj"])
@pytest.mark.parametrize("V, needle", [
    ([[0, 0, 0], [1, 0, 0], [0, 1, np.nan]], "vertex 2 is not finite"),
    ([[0, 0, np.inf], [1, 0, 0], [0, 1, 0]], "vertex 0 is not finite"),
    (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 1j]]), "complex"),
    ([["0", "0", "0"], ["1", "0", "0"], ["0", "1", "0"]], "<U1"),
])
def test_write_mesh_refuses_non_finite_or_non_real_vertices(tmp_path, suffix, V, needle):
    path = tmp_path / f"m.{suffix}"
    with pytest.raises(ValueError, match="write_mesh") as info:
        write_mesh(path, V, [[0, 1, 2]])
    assert needle in str(info.value)
    assert not path.exists()


def test_write_mesh_refuses_coordinates_a_ply_turns_into_inf(tmp_path):
    V = [[0, 0, 0], [1, 0, 0], [0, 1e39, 0]]
    with pytest.raises(ValueError, match="vertex 2 .* float32"):
        write_mesh(tmp_path / "m.ply", V, [[0, 1, 2]])
    assert not (tmp_path / "m.ply").exists()
    path = write_mesh(tmp_path / "m.obj", V, [[0, 1, 2]])  # OBJ writes decimals: fine
    assert load_mesh(path, merge_vertices=False)[0][2, 1] == pytest.approx(1e39)


def test_write_mesh_takes_whole_float_indices_only(tmp_path):
    V, F = grid(3, 3)
    path = write_mesh(tmp_path / "m.obj", V, F.astype(np.float64))
    V2, F2 = load_mesh(path, merge_vertices=False)
    np.testing.assert_array_equal(F2, F)
    with pytest.raises(ValueError, match="triangle 3 holds"):
        write_mesh(tmp_path / "m.obj", V, F + np.where(np.arange(len(F)) == 3, 0.25, 0.0)[:, None])


# --------------------------------------------------------------------------------------------
# FrameRecorder


def sheet(n):
    V, F = grid(n, n, size=(0.2, 0.2))
    return peridyn.Membrane(V, F, thickness=1e-3, density=200.0, material=peridyn.StretchA3(s0=1e3))


def solver(*sizes):
    s = peridyn.Solver(dt=1e-3, threads=1)
    for n in sizes:
        s.add(sheet(n))
    return s


@pytest.mark.parametrize("fmt", ["ply", None])
def test_a_body_of_another_size_is_refused_at_record_and_close_keeps_the_frames(tmp_path, fmt):
    rec = FrameRecorder(tmp_path, fmt=fmt)
    first = solver(4, 5)
    rec.record(first)
    first.step()
    rec.record(first)
    with pytest.raises(ValueError, match="body 1 now has 36 vertices, the recording started with 25"):
        rec.record(solver(4, 6))
    with pytest.raises(ValueError, match="3 bodies"):
        rec.record(solver(4, 5, 3))
    assert rec.num_frames == 2
    npz = rec.close()
    with np.load(npz) as data:
        assert data["positions_0"].shape == (2, 16, 3) and data["positions_1"].shape == (2, 25, 3)
        assert len(data["times"]) == len(data["steps"]) == 2


def test_a_body_with_other_triangles_is_refused_at_record(tmp_path):
    rec = FrameRecorder(tmp_path, fmt=None)
    rec.record(solver(4))
    V, F = grid(4, 4, diagonal="alternate")
    other = peridyn.Solver(dt=1e-3)
    other.add(peridyn.Membrane(V, F, thickness=1e-3, density=200.0, material=peridyn.StretchA3(s0=1e3)))
    with pytest.raises(ValueError, match="other triangles"):
        rec.record(other)
    assert rec.num_frames == 1
    rec.close()


def test_a_failed_mesh_write_records_no_half_frame(tmp_path, monkeypatch):
    s = solver(4, 5)
    rec = FrameRecorder(tmp_path)
    rec.record(s)
    real = peridyn.io.write_mesh

    def failing(path, V, F):
        if "body1" in str(path):
            raise OSError("disk full")
        return real(path, V, F)

    monkeypatch.setattr(peridyn.io, "write_mesh", failing)
    s.step()
    with pytest.raises(OSError):
        rec.record(s)
    monkeypatch.setattr(peridyn.io, "write_mesh", real)
    s.step()
    assert rec.record(s) == 1
    with np.load(rec.close()) as data:
        assert data["positions_0"].shape[0] == data["positions_1"].shape[0] == len(data["times"]) == 2
        np.testing.assert_array_equal(data["steps"], [0, 2])


def test_the_npz_is_written_at_the_path_returned(tmp_path):
    s = solver(4)
    with FrameRecorder(tmp_path, fmt=None, npz_name="frames.bin") as rec:
        rec.record(s)
    assert rec.npz_path == tmp_path / "frames.bin" and rec.npz_path.is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["frames.bin"]
    with np.load(rec.npz_path) as data:
        assert data["positions_0"].shape == (1, 16, 3)
