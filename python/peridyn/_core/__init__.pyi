"""Type stubs for the compiled Rust core ``peridyn._core``.

Every quantity is in SI units: metres, kilograms, seconds, pascals, joules.
Arrays are returned as new numpy arrays (``float64`` for real values, ``int64`` for indices);
inputs accept any float or integer dtype and any array-like of numbers that numpy can convert.
Bad input raises ``ValueError`` naming the offending argument, index and value; refused rather than
converted with a loss: complex values or dtypes (their imaginary parts), bool where a number is
meant, strings (even ``"1.5"``), and integers that do not fit in 64 bits or are out of range
(never truncated). Rotation matrices orthonormal within 1e-6 (``|R^T R - I|``, entry by entry;
e.g. rounded to float32) are accepted; beyond the core's 1e-9 they are re-orthonormalised (to the
nearest orthonormal matrix).
"""

from ._options import (
    ArrayLike as ArrayLike,
    Vec3 as Vec3,
    Method as Method,
    Preconditioner as Preconditioner,
    Acceleration as Acceleration,
    Backend as Backend,
    GlobalSolver as GlobalSolver,
    Precision as Precision,
    DescentStep as DescentStep,
    ProximalMetric as ProximalMetric,
)
from ._materials import (
    StretchA3 as StretchA3,
    NeoHookean as NeoHookean,
    Elastic as Elastic,
    DruckerPrager as DruckerPrager,
    ViscoelasticFluid as ViscoelasticFluid,
    Granular as Granular,
    Material as Material,
)
from ._bodies import (
    Particles as Particles,
    Membrane as Membrane,
)
from ._colliders import (
    Collider as Collider,
    Plane as Plane,
    Sphere as Sphere,
    Box as Box,
    Capsule as Capsule,
    MeshCollider as MeshCollider,
    Contact as Contact,
)
from ._solver import (
    StepStats as StepStats,
    Solver as Solver,
    gpu_info as gpu_info,
)
from ._sampling import (
    sample_volume as sample_volume,
    sample_surface as sample_surface,
)
from . import contact as contact

__version__: str

class DivergenceError(RuntimeError):
    """A time step produced non-finite positions; the solver state is left at the last good step."""

class PrecisionWarning(UserWarning):
    """The solver's precision cannot hold what the simulation asks of it: a body so far from the
    origin that the motion gravity gives it in one step (``|g| dt^2``) is below its coordinates'
    resolution (``|x| * epsilon`` of f32 or f64; a particle body's ``x`` measured from its
    particle family's frame origin, near its bodies, unless membranes share the step). Warned
    by ``Solver.add``, and by ``Solver.step`` on the CPU backend."""
