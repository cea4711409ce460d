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

from typing import Any, Dict, Literal, Optional, Sequence, Tuple, Union

import numpy as np
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

__version__: str

class DivergenceError(RuntimeError):
    """A time step produced non-finite positions; the solver state is left at the last good step."""

class PrecisionWarning(UserWarning):
    """The solver's precision cannot hold what the simulation asks of it: a body so far from the
    origin that the motion gravity gives it in one step (``|g| dt^2``) is below its coordinates'
    resolution (``|x| * epsilon`` of f32 or f64). Warned by ``Solver.add``, and by
    ``Solver.step`` on the CPU backend."""

class StretchA3:
    """Stretching model of Lu et al. 2023, eq. 39-41: ``Psi = s0 * sum_m A3(lambda_m)``.

    ``A3(s) = ((s^4 - 1)/4 + (s^-2 - 1)/2) / 3``; in-plane small-strain shear modulus ``s0``,
    Poisson's ratio 0, Young's modulus ``2 s0``.
    """

    def __init__(self, *, s0: float) -> None: ...
    @staticmethod
    def from_young(E: float, nu: float = 0.0) -> "StretchA3":
        """``s0 = E / 2``; ``nu`` must be 0 (the A3 model has no Poisson coupling)."""
    @property
    def s0(self) -> float:
        """Stiffness in Pa."""
    @property
    def shear_modulus(self) -> float:
        """Small-strain shear modulus in Pa."""
    @property
    def youngs_modulus(self) -> float:
        """Small-strain in-plane Young's modulus in Pa."""
    @property
    def poisson_ratio(self) -> float: ...
    def stress(self, stretches: ArrayLike) -> np.ndarray:
        """Principal first Piola-Kirchhoff stresses ``dPsi/dlambda`` (Pa) for stretches of shape (..., 3)."""
    def energy_density(self, stretches: ArrayLike) -> np.ndarray:
        """Energy density ``Psi`` (J/m^3) for principal stretches of shape (..., 3)."""

class NeoHookean:
    """Compressible neo-Hookean model of Lu et al. 2023, eq. 36-38:
    ``Psi = s0 (I1 - 3 - ln I3) + s1 (sqrt(I3) - 1)^2`` (s0, s1 in Pa).

    The membrane keeps its normal unstretched (Kirchhoff-Love), so the in-plane response is that
    of plane strain with Lame parameters ``mu = 2 s0`` and ``lambda = 2 s1``.
    """

    def __init__(self, *, s0: float, s1: float) -> None: ...
    @staticmethod
    def from_young(E: float, nu: float) -> "NeoHookean":
        """From the sheet's in-plane (plane-stress) Young's modulus E (Pa) and Poisson ratio nu:
        ``s0 = E / (4 (1 + nu))``, ``s1 = E nu / (2 (1 - nu^2))``; a thin sheet then answers a small
        uniaxial stress with strain ``sigma / E`` and lateral contraction ``nu``."""
    @property
    def s0(self) -> float: ...
    @property
    def s1(self) -> float: ...
    @property
    def shear_modulus(self) -> float: ...
    @property
    def youngs_modulus(self) -> float: ...
    @property
    def poisson_ratio(self) -> float: ...
    def stress(self, stretches: ArrayLike) -> np.ndarray: ...
    def energy_density(self, stretches: ArrayLike) -> np.ndarray: ...

Material = Union[StretchA3, NeoHookean]

class Elastic:
    """The elastic material of particle bodies (He, Wang and Wu 2017, eq. 8).

    ``Elastic(mu=, lam=)`` takes the paper's parameters (Pa, >= 0, not both 0): ``mu`` weighs
    the deviatoric term, ``lam`` the isotropic one. They are NOT Lame parameters: under an
    affine deformation both terms are pair springs, so the paper's model has Poisson's ratio
    1/4 whatever they are and Young's modulus about ``(2 mu + lam) / 6``. No surface
    correction. ``Elastic.from_young(E, nu)`` gives bodies the Young's modulus ``E`` (Pa) and
    Poisson ratio ``nu`` (in [0, 0.45]) along the axes of their sampling lattice: calibrated
    by lattice sums for the body's spacing and horizon, with a dilatation term beyond the
    paper (as in state-based LPS) and the bonds near free surfaces stiffened. ValueError
    naming the bad parameter."""

    def __init__(self, *, mu: float, lam: float) -> None: ...
    @staticmethod
    def from_young(E: float, nu: float) -> Elastic: ...
    @property
    def mu(self) -> Optional[float]:
        """The paper's mu (Pa); None for ``from_young`` (see ``Particles.moduli``)."""
    @property
    def lam(self) -> Optional[float]:
        """The paper's lam (Pa); None for ``from_young``."""
    @property
    def youngs_modulus(self) -> Optional[float]:
        """E asked of ``from_young`` (Pa); None for the paper's parameters."""
    @property
    def poisson_ratio(self) -> Optional[float]:
        """nu asked of ``from_young``; None for the paper's parameters (whose ratio is 1/4)."""

class DruckerPrager:
    """Drucker-Prager plasticity of particle bodies (He, Wang and Wu 2017, section 5).

    ``friction_angle`` (degrees, in [0, 90)), ``cohesion`` (Pa, >= 0; > 0 when the angle is
    0), ``hardening`` (Pa per unit of accumulated plastic strain, >= 0; 0: perfectly
    plastic), ``rebuild_neighbours`` (search the neighbours anew on the deformed positions
    after every step, eq. 20). The inner cone of eq. 15, its invariants from the body's
    continuum moduli (docs/model.md). With ``friction_angle`` exactly 0 (von Mises) a solid,
    non-granular body's return keeps each particle's rest volume (an isochoric flow);
    any positive angle, however small, keeps the paper's mean bond strain instead.
    ValueError naming the bad parameter."""

    def __init__(
        self,
        *,
        friction_angle: float,
        cohesion: float,
        hardening: float = 0.0,
        rebuild_neighbours: bool = True,
    ) -> None: ...
    @property
    def friction_angle(self) -> float: ...
    @property
    def cohesion(self) -> float: ...
    @property
    def hardening(self) -> float: ...
    @property
    def rebuild_neighbours(self) -> bool: ...

class ViscoelasticFluid:
    """A fluid material of particle bodies (He, Wang and Wu 2017, section 6), for
    ``Particles(X, spacing=, density=, material=ViscoelasticFluid(...))``: incompressibility by
    one-sided position-based density constraints (Macklin and Mueller 2013) on the spiky
    kernel's lattice-normalised SPH density (support 2.2 spacings), projected after the
    elastic solve, and an implicit viscosity of kinematic viscosity ``viscosity / density``.
    The defaults make a Newtonian liquid (water-like, no elasticity).

    ``viscosity`` (dynamic, Pa s, >= 0), ``density_iterations`` (most projections per step,
    >= 1; a conjugate-gradient iteration counts as one), ``density_solver`` (``"cg"``,
    the default: per linearisation, the coupled system of the active constraints by
    diagonally preconditioned conjugate gradients, which carry a correction across a deep
    liquid in fewer passes; ``"jacobi"``: Macklin and Mueller's Jacobi projections, each pass
    relinearising),
    ``density_tolerance`` (the projections stop once no particle is denser than
    ``density * (1 + density_tolerance)``; in (0, 0.1]), ``relaxation`` (the constraints'
    eps as a fraction of their denominator on the rest lattice, > 0), ``redistribution``
    (strength in [0, 1] of the particle redistribution, eq. 21-24 corrected, lowering
    ``||grad rho||^2`` after the density projection, a position correction whose moves do
    not become velocity and which never pushes a free surface out; 0: none),
    ``redistribution_iterations`` (its passes per step, in [1, 100]), ``shear_modulus`` (Pa,
    >= 0: a viscoelastic fluid, elastic bonds of continuum shear modulus ``G`` whose rest shape
    follows the flow beyond ``yield_stress``, a von Mises cone (friction angle 0) whose return
    keeps each particle's rest volume; 0: a Newtonian liquid) and ``yield_stress``
    (uniaxial von Mises yield stress, Pa, > 0; None: the shear modulus), ``bulk_modulus``
    (Pa, the elasticity's bulk modulus, which alone holds the volume in tension, from 2/3 to
    29/3 of the shear modulus, Poisson ratio 0 to 0.45; None: 5/3 of it), ``adhesion`` (the
    liquid sticks to the body's pinned ghost particles: each ghost with a free liquid
    neighbour holds a two-sided density constraint on its free-surface-corrected density).
    ValueError naming the bad parameter."""

    def __init__(
        self,
        *,
        viscosity: float = 1e-3,
        density_iterations: int = 50,
        density_solver: str = "cg",
        density_tolerance: float = 1e-3,
        relaxation: float = 0.1,
        redistribution: float = 0.0,
        redistribution_iterations: int = 5,
        shear_modulus: float = 0.0,
        yield_stress: float | None = None,
        bulk_modulus: float | None = None,
        adhesion: bool = False,
    ) -> None: ...
    @property
    def viscosity(self) -> float: ...
    @property
    def density_iterations(self) -> int: ...
    @property
    def density_solver(self) -> str: ...
    @property
    def density_tolerance(self) -> float: ...
    @property
    def relaxation(self) -> float: ...
    @property
    def redistribution(self) -> float: ...
    @property
    def redistribution_iterations(self) -> int: ...
    @property
    def shear_modulus(self) -> float: ...
    @property
    def yield_stress(self) -> float | None: ...
    @property
    def bulk_modulus(self) -> float | None: ...
    @property
    def adhesion(self) -> bool: ...

class Granular:
    """Dry and wet sand (He, Wang and Wu 2017, section 7, eq. 25-28 corrected): a particle
    material whose stiffness ``lam = k_f + k_c`` follows each particle's SPH density (over the
    same sum at its reference bonds, so 1 at a free surface at rest), which yields by its
    friction angle (Drucker-Prager; wet sand with the capillary cohesion its cohesion
    stiffness holds, dry sand without), searches its neighbours anew every step and holds
    still by static friction.

    ``friction_angle`` (degrees, in (0, 90)), ``saturation`` (water, in [0, 1]; 0: dry),
    ``friction_stiffness`` ``K_f`` (Pa, > 0) and ``friction_hardening`` ``H_f`` (>= 0) of
    eq. 25, ``cohesion_stiffness`` ``K_c`` (Pa, >= 0) of eq. 26, ``cohesion_falloff``
    ``H_0`` (> 0) and ``debonding`` ``b`` (in [0, 1]) of eq. 27, ``static_friction``
    ``eta`` (in (0, 1], None for none) of eq. 28, ``contact_friction`` ``mu_c`` (>= 0): the
    Coulomb friction coefficient at the contacts of touching grains (0: frictionless balls),
    ``wicking`` ``D`` (m^2/s, in [0, 0.01]; 0: none): the capillary diffusivity of the water
    the grains hold, which moves from grain to grain conserved (a wetting front advances
    about ``sqrt(D t)``); a step whose wicking would need more than 100 explicit substeps
    (they grow as ``D dt / spacing^2``) raises a ValueError naming ``wicking`` and keeps the
    last good state. docs/model.md gives the defaults' reasons.
    ValueError naming the bad parameter."""

    def __init__(
        self,
        *,
        friction_angle: float,
        saturation: float = 0.0,
        friction_stiffness: float = 1e5,
        friction_hardening: float = 10.0,
        cohesion_stiffness: float = 2e4,
        cohesion_falloff: float = 10.0,
        debonding: float = 1.0,
        static_friction: Optional[float] = 0.8,
        contact_friction: float = 0.0,
        wicking: float = 1e-5,
    ) -> None: ...
    @property
    def friction_angle(self) -> float: ...
    @property
    def saturation(self) -> float: ...
    @property
    def friction_stiffness(self) -> float: ...
    @property
    def friction_hardening(self) -> float: ...
    @property
    def cohesion_stiffness(self) -> float: ...
    @property
    def cohesion_falloff(self) -> float: ...
    @property
    def debonding(self) -> float: ...
    @property
    def contact_friction(self) -> float: ...
    @property
    def static_friction(self) -> Optional[float]: ...
    @property
    def wicking(self) -> float: ...
    def stiffness(self, density_ratio: float) -> float:
        """``k_f + k_c`` (Pa) at the density ratio ``rho / rho_0`` (eq. 25-27)."""

class Particles:
    """An elastic body of particles (He, Wang and Wu 2017) stepped by projective peridynamics.

    Parameters
    ----------
    positions : (N, 3) reference positions (m), finite; e.g. from :func:`sample_volume`.
    spacing : lattice spacing (m, > 0): each particle stands for a cube of this side (mass
        ``density * spacing^3``) and keeps half of it from colliders.
    density : kg/m^3 (> 0).
    material : an :class:`Elastic`; a :class:`Granular` (sand: ``density`` is its reference
        density ``rho_0``, the packing it is sampled at); or a :class:`ViscoelasticFluid` for a
        fluid body (then no ``horizon`` or ``plasticity``: its neighbourhoods are the SPH
        support, 2.2 spacings).
    horizon : radius of each particle's neighbourhood (m, > spacing); None: 2.2 spacings (32
        neighbours on a cubic lattice). Every particle needs a three-dimensional neighbourhood:
        a flat or linear one is refused, naming the particle.
    plasticity : None (elastic) or a :class:`DruckerPrager`: after every step the particles
        that yield move their reference bonds, which the body keeps.
    """

    def __init__(
        self,
        positions: ArrayLike,
        *,
        spacing: float,
        density: float,
        material: Union[Elastic, Granular],
        horizon: Optional[float] = None,
        plasticity: Optional[DruckerPrager] = None,
    ) -> None: ...
    @staticmethod
    def shell(
        mesh: Any,
        *,
        spacing: float,
        thickness: float,
        density: float,
        material: Elastic,
        horizon: Optional[float] = None,
        seed: int = 0,
    ) -> "Particles":
        """A shell (He et al. 2017, Fig. 5): one layer of real particles on the surface
        ``mesh`` (a trimesh.Trimesh or a ``(vertices, triangles)`` pair, m; closed or open),
        sampled as :func:`sample_surface` does (at least ``spacing`` m apart, seeded), and two
        layers of ghost particles at ``+-thickness / sqrt(8)`` along each particle's triangle
        normal, so that the three layers have the plate's second moment of area
        ``thickness^3 / 12``: bending stiffness grows as ``thickness^3``.

        ``thickness`` (m) in ``(0, 2 * spacing]`` (thicker: sample a solid with
        :func:`sample_volume`). Each particle stands for an equal share of ``area * thickness``
        (the mass is exact) and real particles keep ``thickness / 2`` from colliders.

        Ghosts are ordinary particles in the elasticity, mass, positions and pins, but no
        collider acts on them. Layout: particles ``0..n`` are the real ones (``num_real``),
        ``n..2n`` the ghosts on the normal's side, ``2n..3n`` the others; ``ghost_owner`` maps
        each ghost to its particle. Pinning a real particle pins its ghosts too (a clamped edge
        is clamped in rotation). With :meth:`Elastic.from_young` the paper's ``mu`` is folded
        into ``lam`` (same response to every affine deformation), so that bending comes from the
        section and not from the sampling; with ``Elastic(mu=, lam=)`` bending also follows
        ``mu``, as in the paper's Fig. 5.
        """
    @staticmethod
    def rod(
        points: ArrayLike,
        *,
        spacing: float,
        radius: float,
        density: float,
        material: Elastic,
        horizon: Optional[float] = None,
    ) -> "Particles":
        """A rod (He et al. 2017, Fig. 6) of ``radius`` (m, in ``(0, spacing]``) along the
        polyline ``points`` ((P, 3) m, P >= 2, consecutive points distinct, no 180-degree
        turn): real particles at equal arc-length steps of at most ``spacing`` (m), both ends
        included, each with four ghosts on a ring of radius ``radius * sqrt(5/8)`` across the
        line (the disk's second moment of area ``pi r^4 / 4``), carried along the curve by
        parallel transport. Particles ``0..n`` are real, ghosts ``n + 4k .. n + 4k + 4``
        belong to particle ``k``. Mass exact (``density * pi r^2 * length``); real particles
        keep ``radius`` from colliders; ghosts, pins and materials as for :meth:`shell`.
        Bending and twisting stiffness cannot be set apart (the paper's limitation).
        """
    @property
    def plasticity(self) -> Optional[DruckerPrager]: ...
    def yield_state(self) -> Optional[tuple[np.ndarray, np.ndarray]]:
        """(sqrt_J2, strength) per particle (Pa) of a plastic body at its current positions
        and reference bonds (NaN without a 3D neighbourhood); None for an elastic body."""
    @property
    def num_particles(self) -> int:
        """Every particle, ghosts included."""
    @property
    def num_real(self) -> int:
        """Particles that are not ghosts: ``0..num_real`` (all of them for a solid)."""
    @property
    def real_positions(self) -> np.ndarray:
        """(num_real, 3) positions of the real particles (m): ``positions[:num_real]``."""
    @property
    def ghost_owner(self) -> np.ndarray:
        """(num_particles - num_real,) int64: the real particle each ghost belongs to."""
    @property
    def positions(self) -> np.ndarray:
        """(N, 3) current positions (m), ghosts included (after the real particles);
        settable (finite, same shape)."""
    @positions.setter
    def positions(self, value: ArrayLike) -> None: ...
    @property
    def velocities(self) -> np.ndarray:
        """(N, 3) velocities (m/s); settable."""
    @velocities.setter
    def velocities(self, value: ArrayLike) -> None: ...
    @property
    def rest_positions(self) -> np.ndarray:
        """(N, 3) reference positions (m)."""
    @property
    def spacing(self) -> float: ...
    @property
    def density(self) -> float: ...
    @property
    def horizon(self) -> float:
        """Horizon radius (m)."""
    @property
    def material(self) -> Union[Elastic, Granular, ViscoelasticFluid]: ...
    def set_material(self, material: Union[Elastic, ViscoelasticFluid],
                     indices: Optional[ArrayLike] = None) -> None:
        """Changes the material during a run (He et al. 2017, Fig. 19): an ``Elastic`` makes
        the body a solid whose bonds are born at its current positions (they become the
        reference; default horizon), a ``ViscoelasticFluid`` melts it. Positions, velocities
        and pins are kept; solvers rebuild the body's working set at their next step.
        ValueError, changing nothing, for another material, a shell, rod or sand, a plastic
        body made fluid, or a particle without a three-dimensional neighbourhood at its
        current position (named).

        With ``indices`` only those particles change, between a Newtonian fluid and an
        elastic solid (one of each per body): bonds between solid particles of which one
        changed are born at the current positions, others kept; none across the fluid-solid
        boundary, where the fluid's density constraints see the solid particles as
        neighbours. ValueError naming a bad index or a second elastic or fluid material."""
    @property
    def saturation(self) -> Optional[np.ndarray]:
        """A sand body's water saturation per particle (in [0, 1]): the material's, risen
        where a liquid in the same solver reached the grains and wicked on from grain to
        grain (``Granular(wicking=)``); None for other bodies."""
    @property
    def fluid_particles(self) -> np.ndarray:
        """Per particle, True for a fluid particle (bool): all for a fluid body, none for a
        solid, a region after ``set_material(material, indices)``."""
    @property
    def moduli(self) -> Tuple[float, float, float]:
        """``(mu, lam, kappa)`` (Pa) the material resolved to on this body's lattice: the
        paper's mu and lam and the dilatation modulus (0 for ``Elastic(mu=, lam=)``)."""
    @property
    def particle_mass(self) -> float:
        """Mass of each particle (kg)."""
    def neighborhood(self) -> Tuple[np.ndarray, np.ndarray]:
        """CSR ``(offsets, indices)`` (int64) of every particle's neighbours within the horizon."""
    @property
    def rest_bonds(self) -> Optional[Dict[str, np.ndarray]]:
        """A plastic body's current reference bonds (``offsets`` (N + 1,), ``neighbours``
        (B,) int64; ``vectors`` (B, 3) m, ``born`` (B,) m, ``plastic_strain`` (N,), ``volume`` (N,): the
        volume each particle's reference bonds span over its rest volume); None for an
        elastic body. Settable (checked; None: the reference positions' bonds; a dict without
        ``volume``, as written before it, gives every particle 1)."""
    @rest_bonds.setter
    def rest_bonds(self, value: Optional[Dict[str, np.ndarray]]) -> None: ...
    @property
    def material_state(self) -> Dict[str, np.ndarray]:
        """The material as the run left it (``elastic``, ``fluid``, ``horizon`` (m),
        ``reference`` (N, 3) m, ``fluid_mask``, ``wetted``, ``region_<bond entry>``; an
        optional part empty when absent): what ``save_state`` saves. Settable into a body set
        up as the one it came from (checked whole; parts equal to its own change nothing)."""
    @material_state.setter
    def material_state(self, value: Dict[str, np.ndarray]) -> None: ...
    def pin(self, indices: ArrayLike, targets: Optional[ArrayLike] = None) -> None:
        """Fixes particles at ``targets`` ((len(indices), 3) m; default: where they are)."""
    def unpin(self, indices: Optional[ArrayLike] = None) -> None:
        """Releases the given pinned particles (all when None)."""
    @property
    def pinned(self) -> np.ndarray:
        """Sorted indices of the pinned particles (int64)."""
    @property
    def pin_targets(self) -> np.ndarray:
        """(P, 3) targets of the pinned particles (m), in the order of ``pinned``; settable."""
    @pin_targets.setter
    def pin_targets(self, value: ArrayLike) -> None: ...
    def elastic_energy(self) -> float:
        """Elastic energy (J) at the current positions (eq. 8 with the dilatation term)."""
    def internal_forces(self) -> np.ndarray:
        """(N, 3) internal forces (N) at the current positions (eq. 12)."""
    def kinetic_energy(self) -> float:
        """Kinetic energy (J)."""


class Membrane:
    """A thin hyperelastic membrane (triangle mesh) simulated by projective peridynamics.

    Parameters
    ----------
    vertices : (N, 3) rest positions in m (any float dtype).
    triangles : (M, 3) vertex indices (any integer dtype).
    thickness : full physical thickness in m (> 0). Mass = density * area * thickness; the
        Kirchhoff-Love virtual bond has length thickness / 2 (the paper's xi).
    density : mass density in kg/m^3 (> 0).
    material : StretchA3 or NeoHookean.
    bending : bending rigidity D in N*m (J), >= 0: a bend with curvature tensor H stores
        D |H|^2 / 2 per unit area (Kirchhoff plate with bending Poisson ratio 0; a cylindrical
        bend of curvature k stores D k^2 / 2 in any direction).
    hourglass : dimensionless stiffness (>= 0) of the in-plane non-affine (hourglass) penalty,
        relative to the material's shear modulus; suppresses zero-energy modes of the
        1-ring deformation gradient, vanishes under mesh refinement for smooth motion.
    neighbors : k of the k-ring neighbourhood (1 = mesh 1-ring, as in the paper).
    self_contact : whether a solver with contact keeps this membrane's own triangles apart.
    friction : Coulomb friction coefficient against membranes (itself included), >= 0 (default
        0, frictionless); a pair of primitives takes the geometric mean of its two bodies'
        coefficients. Static and kinetic, in the contact local step (CPU solver only).
    """

    def __init__(
        self,
        vertices: ArrayLike,
        triangles: ArrayLike,
        *,
        thickness: float,
        density: float,
        material: Material,
        bending: float = 0.0,
        hourglass: float = 0.5,
        neighbors: int = 1,
        self_contact: bool = True,
        friction: float = 0.0,
    ) -> None: ...
    @property
    def self_contact(self) -> bool: ...
    @self_contact.setter
    def self_contact(self, value: bool) -> None: ...
    @property
    def friction(self) -> float: ...
    @friction.setter
    def friction(self, value: float) -> None: ...
    @property
    def num_vertices(self) -> int: ...
    @property
    def num_triangles(self) -> int: ...
    @property
    def positions(self) -> np.ndarray:
        """(N, 3) current positions in m; settable (takes effect at the next step)."""
    @positions.setter
    def positions(self, value: ArrayLike) -> None: ...
    @property
    def velocities(self) -> np.ndarray:
        """(N, 3) velocities in m/s; settable."""
    @velocities.setter
    def velocities(self, value: ArrayLike) -> None: ...
    @property
    def rest_positions(self) -> np.ndarray: ...
    @property
    def triangles(self) -> np.ndarray: ...
    @property
    def masses(self) -> np.ndarray:
        """(N,) lumped vertex masses in kg (density * thickness * area / 3 per incident triangle)."""
    @property
    def volumes(self) -> np.ndarray:
        """(N,) lumped vertex volumes in m^3."""
    @property
    def thickness(self) -> float: ...
    @property
    def density(self) -> float: ...
    @property
    def material(self) -> Material: ...
    @property
    def bending(self) -> float: ...
    @property
    def hourglass(self) -> float: ...
    @property
    def neighbors(self) -> int: ...
    def neighborhood(self) -> Tuple[np.ndarray, np.ndarray]:
        """CSR ``(offsets, indices)`` of every vertex's neighbours (int64)."""
    def pin(self, indices: ArrayLike, targets: Optional[ArrayLike] = None) -> None:
        """Fix vertices at ``targets`` ((len(indices), 3) m; default: where they are now)."""
    def unpin(self, indices: Optional[ArrayLike] = None) -> None:
        """Release the given pinned vertices (all when None)."""
    @property
    def pinned(self) -> np.ndarray:
        """Sorted int64 indices of pinned vertices."""
    @property
    def pin_targets(self) -> np.ndarray:
        """(P, 3) targets of the pinned vertices, in the order of ``pinned``; settable to move
        them (scripted motion); the solver moves them there at the next step."""
    @pin_targets.setter
    def pin_targets(self, value: ArrayLike) -> None: ...
    def elastic_energy(self) -> float:
        """Stretching + bending + hourglass energy (J) at the current positions."""
    def energy_terms(self) -> dict:
        """{'stretch': J, 'bending': J, 'hourglass': J} at the current positions."""
    def internal_forces(self) -> np.ndarray:
        """(N, 3) internal forces in N (minus the gradient of ``elastic_energy``)."""
    def stretches(self) -> np.ndarray:
        """(N, 3) principal stretches per vertex (in-plane two descending, then the normal one)."""
    def kinetic_energy(self) -> float: ...

class Collider:
    """Base of every collider. Every collider takes ``friction`` (Coulomb coefficient, >= 0:
    membranes stick while the tangential force stays within ``friction`` times the contact
    force, and slide against it otherwise) and ``velocity`` (m/s, constant; the pose given is
    the one at time 0). A solver can also drive any collider by rigid poses
    (:meth:`Solver.set_collider_pose`).

    Vertices are kept half their membrane's thickness outside, on the side they came from:
    a move that would cross a collider within one step (a fast impact on a thin plate, or a
    plate sweeping through a cloth) stops on the near face and slides along it, whatever the
    speed and thickness."""

    def signed_distance(self, points: ArrayLike, time: float = 0.0) -> np.ndarray:
        """Signed distances (m, positive outside) of (n, 3) points at ``time`` (s)."""
    @property
    def friction(self) -> float:
        """Coulomb friction coefficient against membranes (>= 0)."""
    @property
    def velocity(self) -> np.ndarray:
        """Constant velocity (m/s); the pose given is the one at time 0."""

class Plane(Collider):
    """Half-space collider: vertices stay on the side the ``normal`` points to."""

    def __init__(self, *, point: Vec3 = (0.0, 0.0, 0.0), normal: Vec3 = (0.0, 0.0, 1.0), friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None: ...
    @property
    def point(self) -> np.ndarray: ...
    @property
    def normal(self) -> np.ndarray: ...

class Sphere(Collider):
    """Solid sphere collider (m)."""

    def __init__(self, *, center: Vec3, radius: float, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None: ...
    @property
    def center(self) -> np.ndarray: ...
    @property
    def radius(self) -> float: ...

class Box(Collider):
    """Solid oriented box collider (m)."""

    def __init__(self, *, center: Vec3, half_extents: Vec3, rotation: Optional[ArrayLike] = None, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """``rotation``: 3x3 rotation matrix (orthonormal within 1e-6, re-orthonormalised; det +1)
        whose columns are the box axes (default: axis-aligned)."""
    @property
    def center(self) -> np.ndarray: ...
    @property
    def half_extents(self) -> np.ndarray: ...
    @property
    def rotation(self) -> np.ndarray: ...

class Capsule(Collider):
    """Solid capsule collider: the points within ``radius`` (m) of the segment from ``a`` to ``b``."""

    def __init__(self, *, a: Vec3, b: Vec3, radius: float, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None: ...
    @property
    def a(self) -> np.ndarray: ...
    @property
    def b(self) -> np.ndarray: ...
    @property
    def radius(self) -> float: ...

class MeshCollider(Collider):
    """Solid bounded by a closed triangle mesh, turned into a signed distance field on a grid.

    Every grid node holds the exact distance to the nearest triangle (a bounding volume
    hierarchy finds it), signed by the angle-weighted pseudonormal of the nearest feature
    (negative inside). Queries interpolate trilinearly; the normal is the normalised gradient
    of that interpolated field. Outside the grid the field continues as the distance to the
    grid box plus the value there. Error: O(h^2) where the surface is smooth, up to about
    h/2 near sharp edges, for the cell size ``h`` = :attr:`cell_size`.

    The mesh must be closed (watertight: every edge shared by exactly two triangles) and
    consistently oriented; an inside-out mesh is turned outward. Open, non-manifold or
    inconsistently oriented meshes, degenerate triangles, non-finite vertices and triangle
    indices out of range raise ``ValueError`` naming the edge, triangle or vertex.
    """

    def __init__(self, vertices: Any, triangles: Optional[ArrayLike] = None, *, resolution: int = 64, margin: Optional[float] = None, friction: float = 0.0, velocity: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """``vertices`` (n, 3) in m and ``triangles`` (m, 3) vertex indices, or a
        ``trimesh.Trimesh`` alone. ``resolution``: cells along the longest side of the mesh's
        bounding box (>= 2; cell size = longest side / resolution, m): the speed/accuracy
        knob (the default 64 gives about 78^3 = 475K nodes; measured build cost about 4 CPU-s
        per million nodes for a 5K-triangle mesh, 9 for 20K triangles, spread over the
        threads). ``margin`` (m, >= 0): how far the grid reaches beyond the mesh's bounding box
        (default max(0.1 longest side, 2 cells)); keep the membranes' reach within it. A grid of
        more than 2^27 nodes (1 GiB) is a ValueError naming the resolution and the margin."""
    @property
    def cell_size(self) -> float:
        """Grid node spacing h (m)."""
    @property
    def grid_shape(self) -> Tuple[int, int, int]:
        """Grid nodes along x, y and z."""
    @property
    def bounds(self) -> Tuple[np.ndarray, np.ndarray]:
        """Lowest and highest corner of the grid box (m)."""
    @property
    def vertices(self) -> np.ndarray:
        """(n, 3) mesh vertices (m)."""
    @property
    def triangles(self) -> np.ndarray:
        """(m, 3) triangles, oriented outward (counter-clockwise seen from outside)."""

class Contact:
    """Contact between and within membranes: the local step of Algorithm 2 (Lu et al. 2023).

    Parameters
    ----------
    thickness : contact thickness xi in m (> 0): mid-surfaces stay about xi apart, never closer
        than eps * xi.
    d_hat : barrier range in m on the gap f(d) - xi (None: thickness / 2; Table 1 has
        4 * thickness). Layers at rest on one another lie about thickness + d_hat apart.
    eps : minimal separation multiplier of eq. 51 in (0, 1); also the largest descent move per
        iteration in units of xi.
    weight : barrier weight mu of eq. 47 (> 0; with proximal="jacobi" in units of the mean
        Jacobi block d, see below).
    max_iters : descent iterations per local step (>= 1). A local step stops earlier once its
        largest move is below eps * xi / 100, or below tol / 5 where the solver's tol is
        smaller: its result is only that exact, and a stop above about tol / 2 lets the global
        iteration go on at tol without converging. A tight tol thus also costs local
        iterations (on three layers at tol = 1e-6 m, 19 per step median against 11).
    step : the descent's step rule: "curvature" (default) moves each vertex by its direction
        times (W + K)^-1, W the proximal metric (below) and K the barrier's curvature along the
        contact normals there (a block-Jacobi-preconditioned descent: stiff along the normals,
        free along the contact), or
        "uniform", eq. 53 of the paper: one step length for all vertices from the barrier's
        steepest slope. Both move no vertex more than eps * xi per iteration; near contact
        "uniform" creeps and a local step usually ends at max_iters, far from its minimum. A
        move shorter than a quarter of the stopping distance (eps * xi / 400 unless tol asks
        for less) is not taken (the vertex has settled).
    toi_threshold : times of impact in (toi_threshold, 1) clamp vertices inside the descent.
    ccd_s, ccd_t_c : the additive CCD's s and t_c (paper: 0.1 and 0.95).
    warm_start : start each local step's descent from the global step's result plus the move
        the last local step made (where the barrier pushed), instead of the global step's result
        alone (the paper): the local steps of a time step continue one another's descent. Same
        guarantees; on the 3-layer drop about half the descent iterations, and steps whose
        contacts persist converge instead of stalling at the local step's stopping test.
    parallel_angle : radians in [0, pi/2); default asin(sqrt(1e-3)), 1.8 degrees, IPC's
        edge-edge mollifier (not in the paper). An edge-edge pair whose edges are closer to
        parallel than this at the local step's start enters the barrier with a weight falling
        to 0 for parallel edges; the point-triangle pairs hold the contact there. The closest
        points of nearly parallel edges jump along them, and without the fade (0) stacked
        layers stall at a convergence measure of about a micrometre: a tol below that runs
        steps to max_iters, and every local step to its own max_iters.
    proximal : the metric W_i of eq. 47's proximal term, sum_i (z_i - y_i)^T W_i (z_i - y_i) / 2.
        "jacobi" (default, not in the paper): W_i = D_i / d, the global step's Jacobi block of
        the vertex (m_i I + h^2 sum (C_i + C_j), kg) over d, the mean of trace(D_i) / 3 over the
        free vertices. Both steps then work in one metric: the iteration's fixed points are the
        stationary points of the implicit Euler energy plus d * weight * B / h^2, and a pair's
        contact forces cancel (contact conserves momentum); the barrier's weight is effectively
        d * weight. "identity": the paper's W_i = I; the contact force on a vertex is then
        scaled by its own D_i, so contact between bodies of different mass or stiffness makes
        momentum (a light sheet stops a heavy one as hard as it is stopped). On stacked layers
        landing at speed "jacobi" also took 44 % fewer local iterations.
    """

    def __init__(
        self,
        *,
        thickness: float = 1.5e-3,
        d_hat: Optional[float] = None,
        eps: float = 0.1,
        weight: float = 1.0,
        max_iters: int = 32,
        step: DescentStep = "curvature",
        toi_threshold: float = 0.1,
        ccd_s: float = 0.1,
        ccd_t_c: float = 0.95,
        warm_start: bool = True,
        parallel_angle: Optional[float] = None,
        proximal: ProximalMetric = "jacobi",
    ) -> None: ...
    @property
    def thickness(self) -> float: ...
    @property
    def d_hat(self) -> float: ...
    @property
    def eps(self) -> float: ...
    @property
    def weight(self) -> float: ...
    @property
    def max_iters(self) -> int: ...
    @property
    def step(self) -> DescentStep: ...
    @property
    def toi_threshold(self) -> float: ...
    @property
    def warm_start(self) -> bool: ...
    @property
    def proximal(self) -> ProximalMetric: ...
    @property
    def parallel_angle(self) -> float: ...
    @property
    def ccd_s(self) -> float: ...
    @property
    def ccd_t_c(self) -> float: ...
    def stop_distance(self, tol: float) -> float:
        """The local step's stopping distance in m under the solver tolerance ``tol`` (m, >= 0;
        0 for a fixed iteration count): eps * xi / 100, or tol / 5 where that is smaller. The
        local step's result is only this exact."""
    def replace(self, **changes: Any) -> "Contact":
        """A copy with the parameters named by keyword (the constructor's names) changed and the
        rest kept, validated as the constructor validates: ``c.replace(parallel_angle=0.0)``.
        ``d_hat`` is kept unless named, also where ``thickness`` changes."""

class StepStats:
    """What one time step did."""

    @property
    def iterations(self) -> int: ...
    @property
    def last_move(self) -> float:
        """The last iteration's max_i |y_i^k - y_i^(k-1)| in m (the convergence measure of
        Algorithm 1): the last of ``moves``."""
    @property
    def converged(self) -> bool:
        """True when ``residual`` fell below ``tol`` (always False when tol == 0)."""
    @property
    def moves(self) -> np.ndarray:
        """Largest vertex move of each iteration (m)."""
    @property
    def residual(self) -> float:
        """max_i |r_i| / m_i (m) for the residual r = m (y* - y) + h^2 f at the last evaluated
        iterate, without the contact reactions (the colliders' reaction to the vertex's Jacobi
        move, normal and Coulomb friction within the cone, and the part of the contact local
        step's move that its barrier push and the normals of the colliders the vertex rests on
        explain): an upper bound on the mass-weighted RMS distance to the exact implicit Euler
        solution where the energy is convex. The last of ``residuals``."""
    @property
    def residuals(self) -> np.ndarray:
        """``residual`` after each iteration (m): whether a step that ran to max_iters was
        still converging or had stalled. With contact the first one measures the whole
        residual (no local step has run before it) and cannot decide convergence."""
    @property
    def energies(self) -> np.ndarray:
        """Total variational energy E(y^k) (J) of every iterate k = 0..iterations; empty unless
        the solver records it (``record_energy=True``)."""
    @property
    def linear_products(self) -> int:
        """``method="newton"``: Hessian products of its conjugate-gradient solves in the step
        (0 for the other methods)."""
    @property
    def newton(self) -> dict:
        """``method="newton"``: milliseconds per phase of its iterations, summed over the step:
        'jacobi' (SISSM's systems and residual), 'models' (the Hessian models),
        'coarse_assembly', 'coarse_factor', 'cg', 'line_search'; counts 'factorizations' (of
        the coarse matrix) and 'trials' (line-search kernel passes). Zeros for the other
        methods."""
    @property
    def timings(self) -> dict:
        """Milliseconds per phase: 'predict', 'global' (of which 'kernel': the vertex kernel, CPU SISSM only, else 0; a granular body's return within the iterations is part of its kernel passes), 'colliders', 'finish' (of which 'plasticity': the plastic return stored at the step's end and the rest rebuild of plastic particle bodies, their share of 'neighbours': the search on deformed positions, and their share of 'density': the SPH density and stiffness of granular bodies; t_p, t_n and t_d of He et al. 2017, Table 1), and for fluids, outside 'predict' and 'finish': 'neighbours' (their searches at the step's start and before the projection), 'viscosity' (at the step's start), 'density' (the projection), 'redistribution'; 'coupling' (particles against membrane triangles), 'contact' (the membrane contact local steps whole: the broad phase, CCD and descent of `contact` and the rest, the proximal metric, set-up passes and realised reaction), 'total'."""
    @property
    def particles(self) -> dict:
        """The particle bodies' share of the step (zeros without them), from its start:
        milliseconds 'kernel_ms', 'residual_ms', 'solve_ms', 'line_search_ms', 'project_ms';
        'evaluations' (kernel passes, line search trials included), 'factorizations' (of
        the direct solver's matrix), 'held_static' (granular particles held by static
        friction, eq. 28), 'density_passes' (the fluids' density projections) and
        'density_error' (the largest relative excess density rho / rho0 - 1 left);
        'roundoff_floor' (m: the largest round-off floor eps |y_i| D_i / m_i that the last
        convergence measure subtracted; it grows with the distance from the origin, and above
        ``tol`` "converged" means within ``tol`` of what the precision resolves there) and
        'worst_particle' ((body, index) of the particle holding that measure's largest term,
        None when every particle is within its floor)."""
    @property
    def contact(self) -> dict:
        """Contact figures (zeros when contact is off): 'candidate_pairs' (triangle pairs of
        the broad phase's last build, largest over the iterations), 'box_pairs' (the triangle
        pairs of that build whose inflated boxes overlap, before the distance test that leaves
        the candidates; largest), 'cached_pairs' (primitive pairs of that build and of the
        repairs since, which each filter chooses from; largest), 'primitive_pairs'
        (primitive pairs that may come within the barrier's reach, largest), 'active_pairs'
        (primitive pairs within the barrier's reach at the end), 'local_iterations' (descent
        iterations, summed), 'clamped' (vertices the final CCD clamp moved, summed),
        'ccd_queries' (primitive pair CCD queries, summed), 'broad_phase_builds' (summed; the
        other local steps reused the last build), 'cache_repairs' (summed; repairs of the last
        build for a few vertices that strayed beyond their skins, each instead of a build),
        'live_refreshes' (filterings of the cached pairs into the live list, summed),
        'sweeps' (those filterings that looked at every cached pair near enough afresh,
        summed; the others looked again only at the pairs that may have come nearer since the
        last sweep), 'broad_phase_ms', 'ccd_ms', 'descent_ms', and 'barrier_energy' (J, the
        barrier's energy d mu B / h^2 at the step's end)."""
    @property
    def time(self) -> float:
        """Simulation time after the step (s)."""
    @property
    def step(self) -> int:
        """Index of the step (0-based)."""

class Solver:
    """Implicit Euler time stepping by the semi-implicit successive substitution method (SISSM).

    Parameters
    ----------
    dt : time step h in s (> 0), such that ``dt^2`` is a normal number and ``1/dt`` finite in the
        chosen precision (f32: about 1.1e-19 s <= dt <= 1.8e19 s; f64: 1.5e-154 s to 1.3e154 s);
        ValueError otherwise, here and in the ``dt`` setter.
    gravity : acceleration (m/s^2).
    tol : stop when the error bound ``StepStats.residual`` < tol (m): the mass-weighted RMS
        distance to the exact implicit Euler solution is then below tol; 0 runs exactly
        ``max_iters`` iterations.
    max_iters : cap on global iterations per step (>= 1).
    threads : worker threads, 1 to 1024 (None: all cores). Results are bit-identical for any count.
    step_length : apply the per-vertex step length of eq. 31-33.
    precision : "f64" (reference) or "f32" (fast path); None: "f64" on the CPU, "f32" on the GPU.
    preconditioner : "tangent" (curvature bounds of the energy: convergent at any stiffness and
        time step) or "paper" (the P+/lambda split of eq. 24-26: cheaper, can diverge when stiff).
    acceleration : None (plain SISSM iterations) or "chebyshev" (Wang 2015 semi-iterative
        acceleration: 5-9x fewer iterations to a given error on benches/convergence.py; in f32
        it amplifies round-off near the precision floor). With contact (method "sissm" only)
        it extrapolates the local step's result; the local step keeps the intersection-free
        positions and a step always ends on them. Pick rho near the plain iteration's
        per-iteration decay of ``StepStats.residuals`` (about 0.8 on stacked layers
        landing, where rho = 0.85 saved a fifth of the iterations).
    chebyshev_rho : spectral-radius estimate in (0, 1) for Chebyshev (higher: stronger, riskier);
        None: 0.99. A value given applies to membranes with ``acceleration="chebyshev"`` and
        to particle bodies with ``global_solver="chebyshev"`` or an acceleration; given with
        neither, ValueError.
    chebyshev_delay : plain iterations before extrapolating (>= 1); None: 3. Like
        ``chebyshev_rho``, a value given applies to membranes with ``acceleration="chebyshev"``
        and to particle bodies with ``global_solver="chebyshev"`` or an acceleration; given
        with neither, ValueError.
    record_energy : record the variational energy of every iterate in ``StepStats.energies``.
    method : "sissm" (the paper's method) or "descent" (the baseline of Fig. 13, Wang and Yang
        2016: gradient descent preconditioned by the diagonal of the energy's Hessian, with a
        step length halved whenever the energy would rise and Chebyshev restarted then; the
        Hessian diagonal is taken by finite differences, so an iteration costs tens of SISSM
        iterations) or "newton" (Newton steps on the implicit Euler energy: a projected Hessian
        solved by conjugate gradients preconditioned with SISSM's blocks, then a line search
        that never lets the energy rise; colliders, contact and the convergence test as SISSM;
        no Chebyshev, ValueError; for fine or stiff cloth asked to converge, see
        docs/performance.md) or "auto" (per step: Newton where ``0 < tol <= 1e-5`` m and the
        cloth is stiff and fine enough that SISSM's slowest error would need more than 100
        iterations, ``min(h^2 k / m, N / pi^2) > 100`` over the N membrane vertices; else SISSM,
        with the acceleration asked for; SISSM with particle bodies and on the GPU).
    inner_iters : Jacobi sweeps on the linear system of eq. 25 per global iteration (Fig. 6).
    backend : "cpu" (Rust, rayon threads) or "gpu" (wgpu compute shaders, state on the device;
        f32 by default, f64 where the adapter has SHADER_F64; raises RuntimeError naming what
        is missing when there is no adapter, see :func:`gpu_info`). The adapter follows
        WGPU_BACKEND, WGPU_POWER_PREF and WGPU_ADAPTER_NAME. The GPU runs SISSM (optionally
        Chebyshev) with every collider (friction and motion included) and leaves the bodies'
        positions and velocities on the device until they are read; it refuses contact,
        method="descent" or "newton" and inner_iters > 1 (ValueError).
    global_solver : how particle bodies solve the linear system of their global step (He et
        al. 2017, Fig. 7; membranes ignore it): "direct" (a sparse Cholesky factor of
        ``M + h^2 L``, computed when dt or the pins change; exact solve per iteration; it does
        not yet converge at collider contact), "jacobi" (``inner_iters`` Jacobi sweeps),
        "chebyshev" (Jacobi with Chebyshev acceleration, ``chebyshev_rho`` when given, else
        0.99) or "position" (position-based averaging over
        bonds). Every one has the implicit Euler solution as its fixed point; each iteration's
        step length is chosen by Armijo backtracking (eq. 13) on the residual of eq. 12.
        ``method="descent"`` and the GPU backend refuse particle bodies.
    contact : a ``Contact`` to keep every body's triangles apart from the other bodies' (and
        its own, unless built with ``self_contact=False``); None: no contact between membranes.
    particle_tol : particle bodies only (> 0, m/s^2; default 0.0981, a hundredth of g): a step
        stops once every particle's force imbalance per unit mass ``|r_i| / (m_i dt^2)``
        (Newton's law at the step's accelerations, colliders' reactions taken out, less its
        round-off floor) is below it and its distance measure below ``tol``: particle steps
        stop at ``min(tol, particle_tol * dt^2)`` m, so that a short step is not "converged"
        before it has moved (docs/model.md, "Convergence measure").
    two_level : particle bodies with ``global_solver`` "jacobi" or "chebyshev" only (default
        True): add a two-level correction on aggregates of about 30 particles to every sweep
        (issue 38): fewer iterations where a body's slow elastic modes hold the step (a
        landing, a stretched or pinned body), for a sparse Cholesky factor of the coarse
        matrix whenever the time step or the held set (pins, contacts) changes and two passes
        over the bonds per iteration. Steps whose move is round-off (at rest, free fall) skip
        it. False: the paper's one-level sweep.
    """

    def __init__(
        self,
        *,
        dt: float,
        gravity: Vec3 = (0.0, 0.0, -9.81),
        tol: float = 1e-4,
        max_iters: int = 100,
        threads: Optional[int] = None,
        step_length: bool = True,
        precision: Optional[Precision] = None,
        preconditioner: Preconditioner = "tangent",
        acceleration: Optional[Acceleration] = None,
        chebyshev_rho: Optional[float] = None,
        chebyshev_delay: Optional[int] = None,
        record_energy: bool = False,
        method: Method = "sissm",
        inner_iters: int = 1,
        backend: Backend = "cpu",
        contact: Optional[Contact] = None,
        global_solver: GlobalSolver = "chebyshev",
        particle_tol: float = 0.0981,
        two_level: bool = True,
    ) -> None: ...
    def add(self, body: Union[Membrane, Particles]) -> None: ...
    def add_collider(self, collider: Collider) -> None: ...
    def set_collider_pose(self, index: int, *, rotation: Optional[ArrayLike] = None, translation: Optional[Vec3] = None) -> None:
        """Sets the pose collider ``index`` (in the order added) reaches at the end of the next
        step: its geometry as given, turned by ``rotation`` (3x3, orthonormal within 1e-6,
        re-orthonormalised; det +1; default
        identity) and moved by ``translation`` (m; default 0). During the step it moves rigidly
        from its pose at the start; friction drags each contact along with the collider's own
        material point there, so a turning collider carries a membrane around. Afterwards a
        ``velocity`` carries it on from that pose. Call it before every step to drive a
        collider (a pose not set leaves it moving at its velocity). CPU backend only."""
    def collider_pose(self, index: int) -> Tuple[np.ndarray, np.ndarray]:
        """Current pose of collider ``index``: ``(rotation, translation)``, a point ``b`` of the
        geometry as given is now at ``rotation @ b + translation``; the distance to the
        collider where it is now is ``collider.signed_distance((x - translation) @ rotation)``."""
    def collider_motion(self, index: int) -> Tuple[Tuple[np.ndarray, np.ndarray], Optional[Tuple[np.ndarray, np.ndarray]]]:
        """What the motion of collider ``index`` depends on besides its velocity and the clock,
        for saving a simulation (:func:`peridyn.save_state`): ``(base, target)``, the pose at
        time 0 its velocity carries on from and the pose set with :meth:`set_collider_pose` for
        the end of the next step (None when none is pending), each ``(rotation, translation)``."""
    def set_collider_motion(self, index: int, *, base_rotation: ArrayLike, base_translation: Vec3, target_rotation: Optional[ArrayLike] = None, target_translation: Optional[Vec3] = None) -> None:
        """Restores a motion read with :meth:`collider_motion` (both parts of the target, or
        neither)."""
    def internal_state(self) -> Dict[str, np.ndarray]:
        """What the next steps depend on besides the bodies, the clock, ``dt`` and the
        colliders' motion, as named arrays (:func:`peridyn.save_state` saves them as entries
        ``internal_<name>``): ``contact_warm_start`` (N, 3) m, the contact local step's warm
        start per membrane vertex (the bodies in order; (0, 3) before the first contact step);
        the rest gaps of the contact pairs that started within the barrier's reach:
        ``contact_rest_gaps_seeded`` (bool), ``contact_rest_gap_reach`` (m),
        ``contact_rest_gap_vertices`` (G, 4) int64, ``contact_rest_gap_edge_edge`` (G,) bool,
        ``contact_rest_gap_distances`` (G,) m; the friction at the grains' contacts the next
        step starts from: ``grain_contact_pairs`` (P, 2) int64, particle indices over the
        particle bodies in order (each touching pair in both orders), and
        ``grain_contact_multipliers`` (P, 3) m. The GPU backend has no contact: all empty."""
    def set_internal_state(self, state: Dict[str, ArrayLike]) -> None:
        """Restores a dict read with :meth:`internal_state` into a solver set up the same way
        (same bodies in the same order, parameters and colliders); the next step takes it.
        Checked whole before anything changes (``ValueError`` naming the entry); an empty dict
        resets it (the next contact step starts afresh); a dict without the two
        ``grain_contact_`` entries (saved before them) starts the grains' friction from 0."""
    def step(self) -> StepStats: ...
    @property
    def dt(self) -> float: ...
    @dt.setter
    def dt(self, value: float) -> None: ...
    @property
    def gravity(self) -> np.ndarray: ...
    @property
    def tol(self) -> float: ...
    @tol.setter
    def tol(self, value: float) -> None: ...
    @property
    def max_iters(self) -> int: ...
    @max_iters.setter
    def max_iters(self, value: int) -> None: ...
    @property
    def backend(self) -> Backend: ...
    @property
    def threads(self) -> int: ...
    @property
    def bytes_per_iteration(self) -> Optional[int]:
        """Bytes the GPU kernels load and store per global iteration (None on the CPU)."""
    @property
    def step_length(self) -> bool: ...
    @property
    def precision(self) -> Precision: ...
    @property
    def preconditioner(self) -> Preconditioner: ...
    @property
    def acceleration(self) -> Optional[Literal["chebyshev"]]: ...
    @property
    def record_energy(self) -> bool: ...
    @property
    def method(self) -> Method: ...
    @property
    def inner_iters(self) -> int: ...
    @property
    def global_solver(self) -> GlobalSolver:
        """How particle bodies solve their global step."""
    @property
    def particle_tol(self) -> float:
        """The particles' force-imbalance tolerance (m/s^2)."""
    @particle_tol.setter
    def particle_tol(self, value: float) -> None: ...
    @property
    def contact(self) -> Optional[Contact]:
        """The contact parameters, or None when contact is off. Settable to another Contact
        between steps (re-tuning), but contact cannot be switched on or off (ValueError)."""
    @contact.setter
    def contact(self, contact: Contact) -> None: ...
    @property
    def time(self) -> float: ...
    @property
    def steps_taken(self) -> int: ...
    def set_clock(self, time: float, steps_taken: int) -> None:
        """Sets the simulation time (s) and step count, e.g. when restoring a saved state."""
    @property
    def bodies(self) -> list: ...
    @property
    def colliders(self) -> list: ...

def gpu_info() -> dict:
    """The adapter the GPU backend would use: ``name``, ``backend`` (e.g. "vulkan"),
    ``device_type`` (e.g. "Cpu" for lavapipe), ``driver``, ``f64`` (SHADER_F64 offered, so
    ``Solver(backend="gpu", precision="f64")`` works) and ``limits`` (dict). Raises RuntimeError naming what is
    missing when there is no adapter."""

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
