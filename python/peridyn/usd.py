"""A recorded run as one USD stage, for Blender, Houdini, Omniverse and anything reading ``pxr``.

Needs the optional extra ``peridyn[usd]`` (the ``usd-core`` wheel). The stage layout:

- ``/World`` (the default prim), in metres (``metersPerUnit = 1``) with +z up
  (``upAxis = "Z"``; peridyn's gravity points along -z in every ready scene);
- ``/World/Bodies/body_<b>``: a ``Mesh`` per membrane, a ``Points`` prim per particle set,
  with ``points`` time-sampled at every recorded frame (float32, as USD stores points);
- ``/World/Colliders/collider_<c>``: an ``Xform`` carrying the collider's recorded pose
  (time-sampled when it moves), holding its shape: ``Sphere``, ``Cube`` (a box), ``Capsule``,
  a ``Mesh`` (a mesh collider, and a plane as a square of the run's size), with the custom
  attributes ``peridyn:kind`` and ``peridyn:friction``.

Time codes are step counts (``steps`` of the recording) and ``timeCodesPerSecond`` is ``1/dt``,
so a player shows the run in real time.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Optional, Sequence, Union

import numpy as np

from .recording import Recording, as_recording

__all__ = ["write_usd"]

PathLike = Union[str, "os.PathLike[str]"]


def _pxr() -> Any:
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, Vt
    except ImportError as err:  # the optional extra is missing
        raise ImportError('write_usd needs usd-core: pip install "peridyn[usd]"') from err
    return Gf, Sdf, Usd, UsdGeom, Vt


def _matrix(Gf: Any, rotation: np.ndarray, translation: np.ndarray, scale: Optional[np.ndarray] = None) -> Any:
    """The USD matrix (row vectors: ``p' = p M``) of ``x -> R diag(scale) x + t``."""
    M = np.eye(4)
    A = np.asarray(rotation, dtype=np.float64)
    if scale is not None:
        A = A * np.asarray(scale, dtype=np.float64)[None, :]
    M[:3, :3] = A.T
    M[3, :3] = translation
    return Gf.Matrix4d(M.tolist())


def _time_codes(rec: Recording) -> float:
    """Time codes per second: 1/dt from the recorded clock (1 when it does not tell)."""
    span = int(rec.steps[-1] - rec.steps[0])
    seconds = float(rec.times[-1] - rec.times[0])
    # rounded to 12 digits: 1/dt read back from a float clock (499.99999999999966 -> 500)
    return float(f"{span / seconds:.12g}") if span > 0 and seconds > 0.0 else 1.0


def _shape(stage: Any, where: str, collider: Any, center: np.ndarray, half: float) -> None:
    """Defines the prim of one collider's shape (as built) at path ``where``."""
    from . import _core
    from .shapes import collider_mesh

    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    if isinstance(collider, _core.Sphere):
        prim = UsdGeom.Sphere.Define(stage, where)
        prim.CreateRadiusAttr(float(collider.radius))
        prim.AddTransformOp().Set(_matrix(Gf, np.eye(3), np.asarray(collider.center)))
    elif isinstance(collider, _core.Box):
        prim = UsdGeom.Cube.Define(stage, where)
        prim.CreateSizeAttr(2.0)  # a cube from -1 to 1, scaled by the half extents
        prim.AddTransformOp().Set(_matrix(Gf, np.asarray(collider.rotation), np.asarray(collider.center),
                                          np.asarray(collider.half_extents)))
    elif isinstance(collider, _core.Capsule):
        a, b = np.asarray(collider.a, dtype=np.float64), np.asarray(collider.b, dtype=np.float64)
        axis = b - a
        length = float(np.linalg.norm(axis))
        prim = UsdGeom.Capsule.Define(stage, where)
        prim.CreateRadiusAttr(float(collider.radius))
        prim.CreateHeightAttr(length)  # the cylinder between the two cap centres
        prim.CreateAxisAttr("Z")
        R = np.eye(3)
        if length > 0.0:  # a rotation taking +z to the capsule's axis
            z = axis / length
            x = np.cross([0.0, 1.0, 0.0] if abs(z[1]) < 0.9 else [1.0, 0.0, 0.0], z)
            x /= np.linalg.norm(x)
            R = np.column_stack([x, np.cross(z, x), z])
        prim.AddTransformOp().Set(_matrix(Gf, R, 0.5 * (a + b)))
    else:  # MeshCollider; a Plane as a square patch
        V, F = collider_mesh(collider, center, half)
        prim = UsdGeom.Mesh.Define(stage, where)
        prim.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(V.astype(np.float32)))
        prim.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(F), 3, dtype=np.int32)))
        prim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(F.reshape(-1).astype(np.int32)))
        prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        if isinstance(collider, _core.Plane):
            prim.GetPrim().CreateAttribute("peridyn:normal", Sdf.ValueTypeNames.Double3).Set(
                Gf.Vec3d(*np.asarray(collider.normal, dtype=np.float64).tolist()))
    prim.CreateDisplayColorAttr([Gf.Vec3f(0.54, 0.54, 0.54)])
    prim.CreateDisplayOpacityAttr([0.35])


def write_usd(
    path: PathLike,
    source: Any,
    *,
    colliders: Optional[Sequence[Any]] = None,
    point_width: Optional[float] = None,
) -> Path:
    """Write a recorded run as one USD stage (``.usd`` / ``.usdc`` binary, ``.usda`` text).

    Parameters
    ----------
    path : str or path-like
        Output file; parent directories must exist. An existing file is replaced.
    source : FrameRecorder, Recording, Solver, str or path-like
        The run (see :func:`peridyn.recording.as_recording`); a solver gives its state now.
    colliders : sequence of colliders, optional
        Replaces the recording's colliders (needed for a recording read from an ``.npz``).
    point_width : float, optional
        Diameter (m) of the points of a particle set; default 1 % of the first frame's
        bounding-box diagonal.

    Returns
    -------
    pathlib.Path
        The stage file (binary crate for ``.usd`` / ``.usdc``, text for ``.usda``).

    Raises
    ------
    ImportError
        Without usd-core (``pip install "peridyn[usd]"``).
    ValueError
        For a recording without frames, a suffix USD does not write, or ``point_width <= 0``.
    """
    Gf, Sdf, Usd, UsdGeom, Vt = _pxr()
    from .render import _run_view_box

    path = Path(path)
    if path.suffix.lower() not in (".usd", ".usda", ".usdc"):
        raise ValueError(f"write_usd: unsupported suffix {path.suffix!r} in {str(path)!r}; use .usd, .usda or .usdc")
    if point_width is not None and not point_width > 0.0:
        raise ValueError(f"write_usd: point_width must be > 0 (m), got {point_width!r}")
    rec = as_recording(source, colliders)
    if rec.num_frames == 0:
        raise ValueError("write_usd: the recording has no frames")

    if path.exists():
        path.unlink()
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    codes = [float(s) for s in rec.steps]
    stage.SetStartTimeCode(codes[0])
    stage.SetEndTimeCode(codes[-1])
    stage.SetTimeCodesPerSecond(_time_codes(rec))
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    UsdGeom.Scope.Define(stage, "/World/Bodies")

    for b, track in enumerate(rec.bodies):
        where = f"/World/Bodies/body_{b}"
        if track.triangles is not None:
            prim = UsdGeom.Mesh.Define(stage, where)
            F = track.triangles
            prim.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(F), 3, dtype=np.int32)))
            prim.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(F.reshape(-1).astype(np.int32)))
            prim.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)  # flat triangles, as simulated
            prim.CreateDoubleSidedAttr(True)
        else:
            prim = UsdGeom.Points.Define(stage, where)
            X0 = track.positions[0]
            width = point_width if point_width is not None else 0.01 * float(np.linalg.norm(np.ptp(X0, axis=0)) or 1.0)
            prim.CreateWidthsAttr(Vt.FloatArray([width]))
            prim.SetWidthsInterpolation(UsdGeom.Tokens.constant)
        points, extent = prim.CreatePointsAttr(), prim.CreateExtentAttr()
        for f, code in enumerate(codes):
            X = track.positions[f]
            points.Set(Vt.Vec3fArray.FromNumpy(X.astype(np.float32)), code)
            extent.Set(Vt.Vec3fArray.FromNumpy(np.stack([X.min(axis=0), X.max(axis=0)]).astype(np.float32)), code)

    if rec.colliders:
        UsdGeom.Scope.Define(stage, "/World/Colliders")
        center, half = _run_view_box(rec)
    for c, collider in enumerate(rec.colliders):
        where = f"/World/Colliders/collider_{c}"
        xform = UsdGeom.Xform.Define(stage, where)
        prim = xform.GetPrim()
        prim.CreateAttribute("peridyn:kind", Sdf.ValueTypeNames.String).Set(type(collider).__name__)
        prim.CreateAttribute("peridyn:friction", Sdf.ValueTypeNames.Double).Set(float(collider.friction))
        if rec.collider_rotations is not None:
            op = xform.AddTransformOp()
            poses = [rec.collider_pose(f, c) for f in range(rec.num_frames)]
            moves = any(not (np.array_equal(p[0], poses[0][0]) and np.array_equal(p[1], poses[0][1])) for p in poses)
            if moves:
                for (R, t), code in zip(poses, codes):
                    op.Set(_matrix(Gf, R, t), code)
            else:
                op.Set(_matrix(Gf, *poses[0]))
        _shape(stage, f"{where}/shape", collider, center, half)

    stage.GetRootLayer().Save()
    return path
