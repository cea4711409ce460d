"""Argument checks of the Python helpers, matching the Rust edge's (``src/python/scalars.rs``):
a real number is an ``int``, a ``float`` or a numpy scalar of a real or integer dtype; bool,
strings (even ``"1.5"``) and complex numbers are refused with a ValueError naming the argument,
not converted (``float("1.5")`` parses, ``float(True)`` is 1)."""

from __future__ import annotations

import numbers

import numpy as np

__all__ = ["real"]


def real(where: str, name: str, value: object) -> float:
    """``value`` as a float, or a ValueError ``"{where}: {name} must be a real number, got ..."``."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    if isinstance(value, np.ndarray):
        ok = value.ndim == 0 and value.dtype.kind in "fiu"
    if not ok:
        raise ValueError(
            f"{where}: {name} must be a real number, got {type(value).__name__} {value!r}"
        )
    return float(value)
