"""The materials of membranes and particle bodies (constitutive laws and plasticity)."""

from typing import Optional, Union

import numpy as np

from ._options import ArrayLike

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
    continuum moduli (docs/particles/plasticity.md). With ``friction_angle`` exactly 0 (von Mises) a
    solid, non-granular body's return keeps each particle's rest volume (an isochoric flow);
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
    neighbour holds a two-sided density constraint on its free-surface-corrected density),
    ``surface_tension`` (N/m, >= 0; water 0.072: the cohesion force of Akinci, Akinci and
    Teschner 2013 between the liquid's particles (without their curvature term), an explicit
    force at each step's start, its coefficient calibrated on the rest lattice by the work of
    cutting it along a plane; 0: none). Approximate: a drop's l = 2 oscillation reads back 0.8
    to 1.4 of the tension asked at 0.1-0.4 N/m but 0.1 of it at 0.5 N/m (docs/particles/fluids.md,
    fluids, round x), and above about 1 N/m at dt = 5 ms the explicit force blows drops apart),
    ``plastic_viscosity`` (Pa s, >= 0: the Bingham viscosity of a viscoelastic fluid's flow
    beyond yield; its return relaxes the stress beyond the cone over ``plastic_viscosity /
    shear_modulus`` (Duvaut and Lions' form of Perzyna's overstress law), so a steady flow
    carries ``yield_stress + 3 plastic_viscosity eps_dot`` in tension; not the Laplacian
    ``viscosity``, which acts at every strain; 0: rate-independent, the paper's).
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
        surface_tension: float = 0.0,
        plastic_viscosity: float = 0.0,
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
    @property
    def surface_tension(self) -> float: ...
    @property
    def plastic_viscosity(self) -> float: ...

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
    ``rolling_resistance`` ``mu_r`` (>= 0, None for none; needs ``contact_friction`` > 0):
    each grain turns within the step until its contacts' friction torque lies within ``mu_r``
    times its radius times its contacts' normal loads (0: it rolls freely; None, the default:
    grains do not turn and resist rolling without bound),
    ``wicking`` ``D`` (m^2/s, in [0, 0.01]; 0: none): the capillary diffusivity of the water
    the grains hold, which moves from grain to grain conserved (a wetting front advances
    about ``sqrt(D t)``); a step whose wicking would need more than 100 explicit substeps
    (they grow as ``D dt / spacing^2``) raises a ValueError naming ``wicking`` and keeps the
    last good state. docs/particles/granular.md gives the defaults' reasons.
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
        rolling_resistance: Optional[float] = None,
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
    def rolling_resistance(self) -> Optional[float]: ...
    @property
    def static_friction(self) -> Optional[float]: ...
    @property
    def wicking(self) -> float: ...
    def stiffness(self, density_ratio: float) -> float:
        """``k_f + k_c`` (Pa) at the density ratio ``rho / rho_0`` (eq. 25-27)."""
