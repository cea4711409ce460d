"""The garment scenes of Lu et al. 2023 (Table 1: a short skirt of about 14K vertices and a long
dress of about 33K) on an avatar given as a signed distance field.

The paper dresses a scanned avatar; ours is a mannequin assembled from simple solids (tapered
capsules and ellipsoids, united into one closed mesh by the Manifold library,
``pip install "peridyn[avatar]"``), standing in an A-pose with its feet on the ground ``z = 0``, facing
``+y``. It becomes a :class:`MeshCollider` (a signed distance field on a grid). The garments are
open tubes made to measure on that collider: from the waist to the hips they follow its surface
1 cm away, below the hips they flare. They start out of contact, settle onto the hips (their
rings above the hips are shorter than the hips' section, as a real skirt's are) and hang there,
the skirt to above the knees, the long one (the paper's dress, without a bodice) to the feet and
the ground, with self-contact on where they fold.

Sizes follow the paper's vertex counts by default; tests pass coarse meshes. Contact thickness
and barrier reach are chosen as in :mod:`peridyn.paper_scenes` (``d_hat`` capped below the
garment's rest spacing).
"""

from __future__ import annotations

import math
from typing import List, Optional, Tuple

import numpy as np

from . import _core
from .paper_scenes import _check, _cloth, _solver, _steps
from .scenes import Scene

__all__ = ["dress", "mannequin", "skirt"]

#: The mannequin's parts for a height of 1.75 m: ``(centre, radius)`` spheres joined into tapered
#: capsules (each a convex hull of its chain), and ellipsoids ``(centre, semi-axes)`` from the
#: chest down whose consecutive hulls are the torso. Metres, z up, feet on z = 0, facing +y.
_CAPSULES: List[List[Tuple[Tuple[float, float, float], float]]] = [
    [((0.0, 0.0, 1.47), 0.05), ((0.0, 0.0, 1.56), 0.05)],  # neck
    *[
        chain
        for s in (-1.0, 1.0)
        for chain in (
            # thigh and shin
            [((0.09 * s, 0.0, 0.86), 0.075), ((0.10 * s, 0.0, 0.48), 0.055)],
            [((0.10 * s, 0.0, 0.48), 0.055), ((0.10 * s, 0.0, 0.09), 0.045)],
            # foot
            [((0.10 * s, -0.02, 0.05), 0.045), ((0.10 * s, 0.13, 0.035), 0.035)],
            # upper arm and forearm, in an A-pose
            [((0.19 * s, 0.0, 1.40), 0.05), ((0.40 * s, 0.0, 1.22), 0.04)],
            [((0.40 * s, 0.0, 1.22), 0.04), ((0.60 * s, 0.0, 1.08), 0.032)],
        )
    ],
]
_HEAD = ((0.0, 0.01, 1.64), 0.10)
_TORSO = [((0.0, 0.0, 1.32), (0.17, 0.11, 0.13)),  # chest
          ((0.0, 0.0, 1.07), (0.13, 0.095, 0.10)),  # waist
          ((0.0, 0.0, 0.93), (0.175, 0.12, 0.10))]  # hips


def mannequin(*, height: float = 1.75, segments: int = 32) -> Tuple[np.ndarray, np.ndarray]:
    """A closed, watertight mesh of a standing mannequin (see the module doc).

    Parameters
    ----------
    height : float
        Its height in m (the parts scale with it; 1.75 m by default).
    segments : int
        Segments around each sphere the parts are built from (>= 8): the mesh's resolution.

    Returns
    -------
    (V, F) : (N, 3) float64 in m, (M, 3) int64, outward-facing triangles.
    """
    try:
        import manifold3d as m3d
    except ImportError as e:  # pragma: no cover - the test extra installs it
        raise ImportError("peridyn.avatar_scenes.mannequin needs the Manifold library: "
                          "pip install 'peridyn[avatar]' (or manifold3d)") from e
    _check("mannequin", height=height)
    if isinstance(segments, bool) or int(segments) != segments or segments < 8:
        raise ValueError(f"mannequin: segments must be an integer >= 8, got {segments!r}")

    def ball(centre, radius):
        return m3d.Manifold.sphere(radius, int(segments)).translate(centre)

    parts = [m3d.Manifold.batch_hull([ball(c, r) for c, r in chain]) for chain in _CAPSULES]
    parts.append(ball(*_HEAD))
    ellipsoids = [m3d.Manifold.sphere(1.0, int(segments)).scale(axes).translate(centre)
                  for centre, axes in _TORSO]
    # chest to waist and waist to hips: one hull would fill the waist in
    parts += [m3d.Manifold.batch_hull(ellipsoids[k:k + 2]) for k in range(len(ellipsoids) - 1)]
    body = m3d.Manifold.batch_boolean(parts, m3d.OpType.Add).scale([height / 1.75] * 3)
    mesh = body.to_mesh()
    V = np.asarray(mesh.vert_properties, dtype=np.float64)[:, :3]
    F = np.asarray(mesh.tri_verts, dtype=np.int64)
    return V, F


#: The garments' top ring and the hips' widest section: heights in m on the 1.75 m mannequin.
_WAIST_Z, _HIPS_Z = 1.07, 0.93


def _radial_extent(avatar: _core.MeshCollider, angle: np.ndarray, z: np.ndarray) -> np.ndarray:
    """How far (m) the avatar's surface lies from the z axis along the horizontal rays of
    ``angle`` (rad) at heights ``z`` (m), both flattened, by bisection on its signed distance
    between the axis (inside the torso) and 0.4 m (outside it, clear of the arms)."""
    inner, outer = np.zeros(angle.size), np.full(angle.size, 0.4)
    direction = np.stack([np.cos(angle), np.sin(angle), np.zeros(angle.size)], axis=1)
    base = np.stack([np.zeros(z.size), np.zeros(z.size), z], axis=1)
    for _ in range(40):
        middle = 0.5 * (inner + outer)
        outside = avatar.signed_distance(base + middle[:, None] * direction) > 0.0
        outer = np.where(outside, middle, outer)
        inner = np.where(outside, inner, middle)
    return outer


def _fitted_tube(avatar: _core.MeshCollider, length: float, flare: float, clearance: float,
                 around: int, rows: int) -> Tuple[np.ndarray, np.ndarray]:
    """An open tube hanging from the waist (:data:`_WAIST_Z`) down ``length`` (m), a garment
    made to measure: from the waist to the hips each ring follows the avatar's section
    ``clearance`` (m) away from it, below the hips the hips' section widens by ``flare`` m per
    metre down. ``around`` vertices per ring, ``rows`` rings; quads split along alternating
    diagonals. Its rings above the hips are shorter than the hips' section, so that it hangs
    on them."""
    z = np.linspace(_WAIST_Z, _WAIST_Z - length, rows)
    angle = 2.0 * np.pi * np.arange(around) / around
    fitted = np.maximum(z, _HIPS_Z)
    extent = _radial_extent(avatar, np.tile(angle, rows), np.repeat(fitted, around))
    radius = extent.reshape(rows, around) + clearance + flare * (fitted - z)[:, None]
    V = np.stack([(radius * np.cos(angle)).ravel(), (radius * np.sin(angle)).ravel(),
                  np.repeat(z, around)], axis=1)
    i, j = np.meshgrid(np.arange(rows - 1), np.arange(around), indexing="ij")
    a = i * around + j
    b = i * around + (j + 1) % around
    c, d = a + around, b + around
    even = ((i + j) % 2 == 0).ravel()
    a, b, c, d = (x.ravel() for x in (a, b, c, d))
    F = np.concatenate([
        np.where(even[:, None], np.stack([a, c, d], 1), np.stack([a, c, b], 1)),
        np.where(even[:, None], np.stack([a, d, b], 1), np.stack([b, c, d], 1)),
    ])
    return V, F


def _garment(name: str, length: float, flare: float, around: int, rows: int,
             s0: float, kb: float, xi: float, friction: float, gravity: float, dt: float,
             duration: float, resolution: int, tol: float, max_iters: int, threads: Optional[int],
             solver_options: Optional[dict]) -> Scene:
    """A garment made to measure (:func:`_fitted_tube`) on the mannequin, with self-contact."""
    _check(name, length=length, s0=s0, xi=xi, gravity=gravity, dt=dt, duration=duration)
    for what, value in (("around", around), ("rows", rows)):
        if isinstance(value, bool) or int(value) != value or value < 3:
            raise ValueError(f"{name}: {what} must be an integer >= 3, got {value!r}")
    Va, Fa = mannequin()
    colliders = {"avatar": _core.MeshCollider(Va, Fa, resolution=resolution, friction=friction),
                 "ground": _core.Plane(friction=friction)}
    V, F = _fitted_tube(colliders["avatar"], length, flare, _CLEARANCE, int(around), int(rows))
    solver = _solver(name, xi, [(V, F)], solver_options, dt=dt, tol=tol, max_iters=max_iters,
                     threads=threads, gravity=(0.0, 0.0, -gravity))
    garment = _cloth(V, F, s0, kb)
    garment.pin(np.arange(int(around)))  # the waistband: the top ring, held at the waist
    solver.add(garment)
    for collider in colliders.values():
        solver.add_collider(collider)
    description = (f"{name}: a tube of {len(V)} vertices ({around} around, {rows} rows; "
                   f"s0 = {s0:g} Pa, kb = {kb:g}) hanging from a mannequin SDF's hips "
                   f"({len(Fa)} triangles, grid {resolution}); xi = {xi * 1e3:g} mm, "
                   f"g = {gravity:g} m/s^2, h = {dt:g} s")
    return Scene(solver, {name: garment}, colliders, _steps(duration, dt), description)


#: How far (m) a garment starts from the avatar's surface: beyond the contact reach
#: (``xi + d_hat``), so that it starts out of contact and settles onto the hips.
_CLEARANCE = 0.01


def skirt(*, around: int = 192, rows: int = 74, length: float = 0.40, flare: float = 0.3,
          s0: float = 12000.0, kb: float = 0.01, xi: float = 1e-3, friction: float = 0.3,
          gravity: float = 9.81, dt: float = 1e-3, duration: float = 1.0, resolution: int = 96,
          tol: float = 1e-4, max_iters: int = 100, threads: Optional[int] = None,
          solver_options: Optional[dict] = None) -> Scene:
    """A short skirt (14.2K vertices by default) made to measure, hanging from the mannequin's
    hips to above its knees.

    Parameters
    ----------
    around, rows : int
        Vertices per ring and rings (>= 3 each).
    length : float
        From the waist (1.07 m above the ground) to the hem in m.
    flare : float
        Below the hips, the radius gained per metre down (m/m); above them the skirt follows the
        mannequin 1 cm away.
    s0, kb : float
        :class:`StretchA3` stiffness (Pa) and bending factor (see :mod:`peridyn.paper_scenes`).
    xi : float
        Contact thickness in m.
    friction : float
        Coulomb coefficient of the avatar and of the ground.
    gravity : float
        Its magnitude in m/s^2, along -z (Table 1: the skirt at 1 g, the dress at 0.1 g).
    dt, duration : float
        Time step and simulated time covered by the suggested steps (s).
    resolution : int
        Grid nodes along the avatar SDF's longest side.
    tol, max_iters, threads, solver_options
        Passed to :class:`Solver`.
    """
    if not (math.isfinite(flare) and flare >= 0.0):
        raise ValueError(f"skirt: flare must be >= 0, got {flare!r}")
    return _garment("skirt", length, flare, around, rows, s0, kb, xi, friction, gravity, dt, duration,
                    resolution, tol, max_iters, threads, solver_options)


def dress(*, around: int = 200, rows: int = 165, length: float = 1.02, flare: float = 0.15,
          s0: float = 12000.0, kb: float = 0.01, xi: float = 1e-3, friction: float = 0.3,
          gravity: float = 0.981, dt: float = 2e-3, duration: float = 1.0, resolution: int = 96,
          tol: float = 1e-4, max_iters: int = 100, threads: Optional[int] = None,
          solver_options: Optional[dict] = None) -> Scene:
    """A long skirt (33K vertices by default; the paper's long dress) made to measure, hanging
    from the mannequin's hips to its ankles, where it folds onto its feet and the ground.
    Parameters as :func:`skirt`."""
    if not (math.isfinite(flare) and flare >= 0.0):
        raise ValueError(f"dress: flare must be >= 0, got {flare!r}")
    return _garment("dress", length, flare, around, rows, s0, kb, xi, friction, gravity, dt, duration,
                    resolution, tol, max_iters, threads, solver_options)
