"""Notebook views (peridyn.show), headless: the figure built from a real run holds the run."""

import json

import numpy as np
import pytest

import peridyn
from viz_scenes import PointSet, WithPoints, box_centre, swinging_cloth


def test_every_frame_of_the_view_holds_the_recorded_positions(tmp_path):
    solver, cloth, rec = swinging_cloth(tmp_path)
    recording = rec.recording()
    fig = peridyn.show(rec, field="speed")
    assert len(fig.frames) == recording.num_frames == 5
    assert len(fig.layout.sliders[0].steps) == 5
    for f, frame in enumerate(fig.frames):
        body = frame.data[0]
        X = np.column_stack([body.x, body.y, body.z])
        np.testing.assert_array_equal(X, recording.bodies[0].positions[f])
        np.testing.assert_array_equal(np.column_stack([body.i, body.j, body.k]), cloth.triangles)
        np.testing.assert_array_equal(body.intensity, np.linalg.norm(recording.bodies[0].velocities[f], axis=1))
        # the moving box (trace 2: body, sphere, box, plane) is drawn at its recorded pose
        box = frame.data[2]
        centre = np.array([np.mean(box.x), np.mean(box.y), np.mean(box.z)])  # 8 corners
        np.testing.assert_allclose(centre, box_centre(recording, f), atol=1e-12)
    np.testing.assert_array_equal(np.column_stack([fig.frames[-1].data[0].x, fig.frames[-1].data[0].y,
                                                   fig.frames[-1].data[0].z]), cloth.positions)
    json.loads(fig.to_json())  # what the notebook front end receives is valid plotly JSON


def test_a_solver_is_shown_as_it_is_now_without_a_slider(tmp_path):
    solver, cloth, _ = swinging_cloth(tmp_path, steps=4)
    fig = peridyn.show(solver)
    assert len(fig.frames) == 0 and not fig.layout.sliders
    assert [type(t).__name__ for t in fig.data] == ["Mesh3d"] * 4
    np.testing.assert_array_equal(fig.data[0].z, cloth.positions[:, 2])
    sphere = fig.data[1]
    r = np.linalg.norm(np.column_stack([sphere.x, sphere.y, sphere.z]) - [0.25, 0.2, -0.3], axis=1)
    np.testing.assert_allclose(r, 0.15, rtol=1e-12)


def test_a_point_body_is_shown_as_points_and_every_thins_the_frames(tmp_path):
    solver, _, _ = swinging_cloth(tmp_path / "a", steps=0)
    points = PointSet(np.zeros((30, 3)))
    host = WithPoints(solver, points)
    rec = peridyn.FrameRecorder(tmp_path / "b", fmt=None)
    for k in range(5):
        points.positions = np.full((30, 3), 0.1 * k)
        rec.record(host)
        solver.step()
    fig = peridyn.show(rec, every=3)
    assert [int(fr.name) for fr in fig.frames] == [0, 3, 4]  # the last frame is always shown
    pts = fig.frames[1].data[1]
    assert type(pts).__name__ == "Scatter3d" and pts.mode == "markers"
    np.testing.assert_array_equal(pts.x, np.full(30, 0.1 * 3))
    with pytest.raises(ValueError, match="every"):
        peridyn.show(rec, every=0)
    with pytest.raises(ValueError, match="stretches"):
        peridyn.show(rec, field="stretch")  # the point body has none
