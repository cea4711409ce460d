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
