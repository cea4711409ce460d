"""Animations (peridyn.animate) and the main job's outputs, from real runs.

The pictures are checked by what they must show: one video frame per recorded frame, the
cloth's colour following the field (at rest everything is at the bottom of the colour map),
and the motion (the first and last frames differ).
"""


import imageio.v3 as iio
import numpy as np
import pytest
import trimesh
from matplotlib import colormaps

import peridyn
from peridyn import animation
from peridyn.__main__ import main
from viz_scenes import PointSet, WithPoints, swinging_cloth


def _share_near(frame, rgb, tol=40):
    """Share of the frame's pixels within ``tol`` (per channel) of colour ``rgb``."""
    return float(np.mean(np.all(np.abs(frame.astype(int) - np.asarray(rgb)) <= tol, axis=-1)))


def test_an_mp4_has_one_frame_per_recorded_frame_and_shows_the_motion(tmp_path):
    solver, cloth, rec = swinging_cloth(tmp_path)
    out = peridyn.animate(rec, tmp_path / "run.mp4", size=(320, 256))
    assert out == tmp_path / "run.mp4"
    frames = iio.imread(out)
    assert frames.shape == (rec.num_frames, 256, 320, 3)
    # The cloth fell ~0.03 m out of a 1.3 m view: a visible change, not noise (H.264 is lossy).
    moved = np.mean(np.abs(frames[-1].astype(int) - frames[0].astype(int)) > 40)
    assert moved > 1e-3


def test_colour_by_speed_starts_at_the_bottom_of_the_colour_map(tmp_path):
    """At frame 0 the cloth is at rest (speed 0, the colour map's bottom, viridis' dark
    purple); 48 ms later its free part falls at ~0.4 m/s, above the middle of clim (0, 0.5)."""
    solver, cloth, rec = swinging_cloth(tmp_path)
    speed = np.linalg.norm(cloth.velocities, axis=1)
    assert np.median(speed) > 0.3
    out = peridyn.animate(rec, tmp_path / "run.gif", field="speed", clim=(0.0, 0.5), size=(320, 256))
    frames = iio.imread(out, index=None)
    bottom = (np.asarray(colormaps["viridis"](0.0)[:3]) * 255).round()
    first, last = _share_near(frames[0], bottom), _share_near(frames[-1], bottom)
    assert first > 0.005 and last < 0.2 * first, (first, last)  # the cloth covers ~1.5 % of the view


def test_without_an_mp4_encoder_a_gif_is_written(tmp_path, monkeypatch):
    _, _, rec = swinging_cloth(tmp_path, steps=6)
    monkeypatch.setattr(animation, "_mp4_encoder_available", lambda: False)
    with pytest.warns(RuntimeWarning, match="GIF"):
        out = peridyn.animate(rec, tmp_path / "run.mp4", size=(160, 128))
    assert out == tmp_path / "run.gif" and out.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    assert iio.imread(out, index=None).shape[0] == rec.num_frames


def test_a_body_without_triangles_is_recorded_and_drawn_as_points(tmp_path):
    """The particle protocol: a body with positions only goes into the recording and the
    .npz without triangles, into point-cloud PLY files, and is drawn (here 50 points moving 0.2 m between frames)."""
    solver, cloth, rec0 = swinging_cloth(tmp_path / "a", steps=0)
    points = PointSet(np.random.default_rng(0).uniform(0.0, 0.5, (50, 3)))
    host = WithPoints(solver, points)
    rec = peridyn.FrameRecorder(tmp_path / "b", fmt="ply", every=1)
    rec.record(host)
    points.positions = points.positions + [0.0, 0.0, -0.2]
    solver.step()
    rec.record(host)
    recording = rec.recording()
    assert recording.bodies[1].triangles is None and recording.bodies[1].velocities is None
    np.testing.assert_array_equal(recording.bodies[1].positions[1], points.positions)
    assert sorted(p.name for p in (tmp_path / "b").glob("*.ply")) == [
        "body0_frame_00000.ply", "body0_frame_00001.ply", "body1_frame_00000.ply", "body1_frame_00001.ply"]
    cloud = trimesh.load(tmp_path / "b" / "body1_frame_00001.ply")  # the point set as a point cloud
    np.testing.assert_allclose(cloud.vertices, points.positions, atol=1e-6)
    with np.load(rec.close()) as data:
        assert "triangles_1" not in data and data["positions_1"].shape == (2, 50, 3)
    back = peridyn.load_recording(rec.npz_path)
    assert back.bodies[1].triangles is None
    np.testing.assert_array_equal(back.bodies[0].triangles, cloth.triangles)
    out = peridyn.animate(back, tmp_path / "points.gif", size=(160, 128), field="height")
    assert iio.imread(out, index=None).shape[0] == 2


def test_bad_animation_arguments_are_value_errors(tmp_path):
    _, _, rec = swinging_cloth(tmp_path, steps=0)
    with pytest.raises(ValueError, match="unknown field 'temperature'"):
        peridyn.animate(rec, tmp_path / "a.mp4", field="temperature")
    with pytest.raises(ValueError, match="fps"):
        peridyn.animate(rec, tmp_path / "a.mp4", fps=0)
    with pytest.raises(ValueError, match=r"'\.avi'"):
        peridyn.animate(rec, tmp_path / "a.avi")
    with pytest.raises(ValueError, match="size"):
        peridyn.animate(rec, tmp_path / "a.mp4", size=(8, 400))
    loaded = peridyn.load_recording(rec.close())  # no collider objects in the file
    with pytest.raises(ValueError, match="no colliders"):
        peridyn.animate(loaded, tmp_path / "a.mp4", field="contact")


def test_the_main_job_writes_an_animation_and_a_usd_stage(tmp_path, capsys):
    from pxr import Usd, UsdGeom

    out = tmp_path / "out"
    assert main(["--n", "8", "--steps", "20", "--frame-every", "5", "--out", str(out),
                 "--usd", "--no-progress", "--threads", "1"]) == 0
    frames = iio.imread(out / "animation.mp4")
    assert frames.shape[0] == 5  # steps 0, 5, 10, 15, 20
    stage = Usd.Stage.Open(str(out / "scene.usd"))
    with np.load(out / "frames.npz") as data:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Bodies/body_0"))
        last = np.asarray(mesh.GetPointsAttr().Get(20.0))
        np.testing.assert_allclose(last, data["positions_0"][-1], atol=1e-6)  # float32 in USD
    printed = capsys.readouterr().out
    assert "animation.mp4" in printed and "scene.usd" in printed
