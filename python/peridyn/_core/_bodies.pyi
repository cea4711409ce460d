"""The bodies a solver steps: particle bodies and membranes."""

from typing import Any, Dict, Optional, Tuple, Union

import numpy as np

from ._options import ArrayLike
from ._materials import DruckerPrager, Elastic, Granular, Material, ViscoelasticFluid

class Particles:
    """An elastic body of particles (He, Wang and Wu 2017) stepped by projective peridynamics.

    Parameters
    ----------
    positions : (N, 3) reference positions (m), finite; e.g. from :func:`sample_volume`.
    spacing : lattice spacing (m, > 0): each particle stands for a cube of this side (mass
        ``density * spacing^3``) and keeps half of it from colliders. It must be the spacing
        the positions were sampled at: within a factor of 4 either way of the median distance
        between the particles and their nearest neighbours (a lattice or
        :func:`sample_volume` sits within a few tenths of 1; far outside, the spacing is
        another unit's or another body's, each particle's mass is off by 64 times or more and
        the run diverges), else a ``ValueError`` gives both numbers.
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
    def pressure(self) -> np.ndarray:
        """(N,) pressure of each fluid particle over the last step (Pa, float64, read-only):
        ``p_i = -kappa rho0 lambda_i / h^2`` of the density projection's multipliers summed
        over the step's passes (``kappa`` = 0.817, the SPH gradient's factor on the rest
        lattice), so a resting column reads ``rho0 g depth`` (within 10 % below its top
        layers). Zeros before the first step, after ``positions`` were set (the last step's
        pressure was of other positions; so after :func:`peridyn.load_state` too) and at
        particles without a density constraint (solids, sand beside a liquid); never
        negative but at adhered ghosts (``ViscoelasticFluid(adhesion=True)``). Not part of a
        saved state: the next step does not start from it."""
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
        elastic body. Settable (checked: symmetric rows, finite nonzero vectors, lengths > 0,
        plastic strain >= 0, ``volume`` within [1e-3, 1e3], each culprit named; None: the
        reference positions' bonds; a dict without ``volume``, as written before it, gives every
        particle 1)."""
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
