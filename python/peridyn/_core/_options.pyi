"""The option strings the core accepts and the array aliases the stubs share."""

from typing import Literal, Sequence, Union

import numpy.typing as npt

ArrayLike = npt.ArrayLike
Vec3 = Union[Sequence[float], npt.ArrayLike]

# The option strings the core accepts (src/python/options.rs maps them to core values; any
# other string is a ValueError naming the accepted ones).
Method = Literal["sissm", "descent", "newton", "auto"]
Preconditioner = Literal["tangent", "paper"]
# "none" is a synonym of None (plain iterations); the getter returns None.
Acceleration = Literal["chebyshev", "none"]
Backend = Literal["cpu", "gpu"]
GlobalSolver = Literal["direct", "jacobi", "chebyshev", "position"]
Precision = Literal["f32", "f64"]
DescentStep = Literal["curvature", "uniform"]
ProximalMetric = Literal["jacobi", "identity"]
