"""Particles sampled from meshes: volumes for solids, surfaces for shells."""

from typing import Any

import numpy as np

def sample_volume(mesh: Any, spacing: float, *, jitter: float = 0.0, seed: int = 0) -> np.ndarray:
    """Particles filling the solid bounded by a closed mesh: the sites of a cubic lattice of
    ``spacing`` (m) centred in the mesh's bounding box that lie strictly inside (exact signed
    distance), as an (N, 3) float64 array (m). Each particle stands for ``spacing**3`` (m^3) of
    material; ``N * spacing**3`` is the enclosed volume to within about half a spacing-thick
    surface layer.

    ``mesh`` is a trimesh.Trimesh (anything with ``vertices`` and ``faces``) or a
    ``(vertices, triangles)`` pair: (n, 3) real numbers (m) and (m, 3) integers, closed and
    consistently oriented. ``jitter`` in [0, 0.5) moves each site by a random offset uniform in
    the ball of radius ``jitter * spacing`` (particles stay at least ``(1 - 2 jitter) spacing``
    apart), drawn from ``seed`` (an integer in [0, 2**64)); the result is the same for a seed on
    any number of threads. Raises ValueError naming the culprit: dtype, shape, a non-finite
    vertex, an open or degenerate mesh, ``spacing`` not positive, or more than 2**26 particles
    expected (the count is named)."""

def sample_surface(mesh: Any, spacing: float, *, seed: int = 0) -> np.ndarray:
    """A single layer of particles on a triangle surface (closed or open), for shells, as an
    (N, 3) float64 array (m): greedy Poisson-disk sampling, in a random order drawn from
    ``seed``, of candidates at most ``spacing / 3`` apart on the triangles. Distinct particles
    are at least ``spacing`` (m) apart; every point of the surface is within about
    ``1.38 spacing`` of one; N is about ``0.7 A / spacing**2`` for area A (m^2), so each
    particle stands for ``A / N`` (m^2). ``mesh`` as for :func:`sample_volume` (any manifold
    surface). Raises ValueError naming the culprit, or above 2**26 candidate points (named)."""
