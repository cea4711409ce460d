"""USD export (peridyn.write_usd): the stage read back with pxr holds the recorded run.

usd-core is the optional extra ``peridyn[usd]``; the test extra installs it, so these tests run
in CI (missing, this module fails).
"""

import numpy as np
import pytest
from pxr import Usd, UsdGeom

import peridyn
from viz_scenes import PointSet, WithPoints, box_centre, swinging_cloth


def _world_point(stage, path, local, code):
    """Where the local point ``local`` of the prim at ``path`` is at time ``code``."""
    M = np.asarray(UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(code))
    return np.append(local, 1.0) @ M  # USD matrices act on row vectors


@pytest.mark.parametrize("suffix", [".usd", ".usda"])
def test_the_stage_holds_every_recorded_frame_in_metres_with_z_up(tmp_path, suffix):
    solver, cloth, rec = swinging_cloth(tmp_path)
    recording = rec.recording()
    path = peridyn.write_usd(tmp_path / f"scene{suffix}", rec)
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0 and UsdGeom.GetStageUpAxis(stage) == "Z"
    assert stage.GetTimeCodesPerSecond() == pytest.approx(1.0 / solver.dt, rel=1e-12)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0.0, 24.0)
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Bodies/body_0"))
    points = mesh.GetPointsAttr()
    assert points.GetTimeSamples() == [float(s) for s in recording.steps]
    for f, code in enumerate(recording.steps):
        # USD stores float32 points: 6e-8 relative, far below 1e-6 m at 1 m.
        np.testing.assert_allclose(np.asarray(points.Get(float(code))), recording.bodies[0].positions[f], atol=1e-6)
    np.testing.assert_array_equal(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()), cloth.triangles.reshape(-1))
    assert set(mesh.GetFaceVertexCountsAttr().Get()) == {3}
    # between samples a reader interpolates linearly: the cloth is falling, so z lies between
    mid = np.asarray(points.Get(3.0))[:, 2]
    z0, z1 = recording.bodies[0].positions[0][:, 2], recording.bodies[0].positions[1][:, 2]
    assert np.all((mid <= z0 + 1e-7) & (mid >= z1 - 1e-7))


def test_colliders_are_prims_at_their_recorded_poses(tmp_path):
    solver, cloth, rec = swinging_cloth(tmp_path)
    recording = rec.recording()
    stage = Usd.Stage.Open(str(peridyn.write_usd(tmp_path / "scene.usd", rec)))
    kinds = [stage.GetPrimAtPath(f"/World/Colliders/collider_{c}").GetAttribute("peridyn:kind").Get() for c in range(3)]
    assert kinds == ["Sphere", "Box", "Plane"]
    sphere = UsdGeom.Sphere(stage.GetPrimAtPath("/World/Colliders/collider_0/shape"))
    assert sphere.GetRadiusAttr().Get() == pytest.approx(0.15)
    np.testing.assert_allclose(_world_point(stage, "/World/Colliders/collider_0/shape", np.zeros(3), 0.0)[:3],
                               [0.25, 0.2, -0.3], atol=1e-12)
    # the box moves up at 1 m/s: its centre follows the recorded poses, 0.048 m in 24 steps
    for f, code in enumerate(recording.steps):
        centre = _world_point(stage, "/World/Colliders/collider_1/shape", np.zeros(3), float(code))[:3]
        np.testing.assert_allclose(centre, box_centre(recording, f), atol=1e-12)
    assert box_centre(recording, recording.num_frames - 1)[2] == pytest.approx(-0.5 + 24 * solver.dt, abs=1e-12)
    # a corner of the cube (size 2, scaled by the half extents) is a corner of the box
    corner = _world_point(stage, "/World/Colliders/collider_1/shape", np.ones(3), 0.0)[:3]
    np.testing.assert_allclose(corner, [1.1, 0.45, -0.45], atol=1e-12)


def test_a_point_body_becomes_a_points_prim(tmp_path):
    solver, _, _ = swinging_cloth(tmp_path / "a", steps=0)
    points = PointSet(np.random.default_rng(1).uniform(0.0, 0.5, (40, 3)))
    rec = peridyn.FrameRecorder(tmp_path / "b", fmt=None)
    host = WithPoints(solver, points)
    rec.record(host)
    solver.step()
    points.positions = points.positions * 0.5
    rec.record(host)
    stage = Usd.Stage.Open(str(peridyn.write_usd(tmp_path / "p.usda", rec, point_width=0.01)))
    prim = UsdGeom.Points(stage.GetPrimAtPath("/World/Bodies/body_1"))
    assert prim and list(prim.GetWidthsAttr().Get()) == [pytest.approx(0.01)]
    np.testing.assert_allclose(np.asarray(prim.GetPointsAttr().Get(1.0)), points.positions, atol=1e-7)


def test_bad_usd_arguments_are_value_errors(tmp_path):
    _, _, rec = swinging_cloth(tmp_path, steps=0)
    with pytest.raises(ValueError, match=r"'\.abc'"):
        peridyn.write_usd(tmp_path / "scene.abc", rec)
    with pytest.raises(ValueError, match="point_width"):
        peridyn.write_usd(tmp_path / "scene.usd", rec, point_width=0.0)
