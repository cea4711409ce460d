"""Helpers for material parameters (all SI: Pa, m, N*m)."""

from __future__ import annotations

import math

from ._validate import real

__all__ = ["plate_bending_stiffness"]


def plate_bending_stiffness(E: float, nu: float, thickness: float) -> float:
    """Bending rigidity of a thin elastic plate, ``D = E t^3 / (12 (1 - nu^2))``.

    Pass the result as ``Membrane(..., bending=D)``.

    Parameters
    ----------
    E : float
        Young's modulus in Pa (>= 0).
    nu : float
        Poisson's ratio, in ``(-1, 0.5]``.
    thickness : float
        Full plate thickness ``t`` in m (> 0).

    Returns
    -------
    float
        ``D`` in N*m (= J): a cylindrical bend of curvature ``k`` (1/m) stores ``D k^2 / 2``
        joules per square metre.

    Raises
    ------
    ValueError
        If a parameter is out of range, not finite or not a real number (bool, strings and
        complex numbers are refused), or if ``D`` overflows (or underflows to 0).

    Examples
    --------
    A 1 mm sheet with E = 40 kPa and nu = 0: ``plate_bending_stiffness(4e4, 0.0, 1e-3)``
    is about 3.3e-6 N*m.
    """
    where = "plate_bending_stiffness"
    E, nu, thickness = real(where, "E", E), real(where, "nu", nu), real(where, "thickness", thickness)
    if not math.isfinite(E) or E < 0.0:
        raise ValueError(f"plate_bending_stiffness: E must be >= 0 Pa, got {E!r}")
    if not math.isfinite(nu) or not -1.0 < nu <= 0.5:
        raise ValueError(f"plate_bending_stiffness: nu must be in (-1, 0.5], got {nu!r}")
    if not math.isfinite(thickness) or thickness <= 0.0:
        raise ValueError(f"plate_bending_stiffness: thickness must be > 0 m, got {thickness!r}")
    try:
        D = E * thickness**3 / (12.0 * (1.0 - nu * nu))
    except OverflowError:
        D = math.inf
    if not math.isfinite(D) or (D == 0.0 and E > 0.0):
        raise ValueError(
            f"plate_bending_stiffness: D = E t^3 / (12 (1 - nu^2)) with E = {E!r} Pa, nu = {nu!r}, "
            f"thickness = {thickness!r} m is {'not finite (overflows a float)' if D else '0 (underflows)'}: "
            "check the units of E (Pa) and thickness (m)"
        )
    return D

