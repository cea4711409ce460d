//! The per-point linear system of a Jacobi move, its solve and its step length (Lu et al.
//! 2023, eq. 25 and 31-33), shared by every body family.

use nalgebra::Vector3;

use crate::real::Lanes;
use crate::symmetric::SymmetricMatrix3;

/// The linear system of point `k` at the current iterate (Lu et al. 2023, eq. 25 in residual
/// form): `D delta = r` with `D = m I + h^2 C` and `r = m (y* - y) + h^2 f`, where `C` is the
/// point's gathered preconditioner (a membrane vertex's `n_k C_k + sum_j C_j`); of one point
/// (`S` a [`Real`](crate::real::Real)) or of a SIMD pack of points, one per lane (`S` a
/// [`Real::Pack`](crate::real::Real::Pack), every lane bit-identical to the scalar system of
/// its point).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PointSystem<S: Lanes> {
    pub mass: S,
    pub residual: Vector3<S>,
    /// `D` (kg).
    pub system: SymmetricMatrix3<S>,
    /// `D^-1` (1/kg), or `I / m` where `det D` is zero or its reciprocal overflows (see
    /// [`PointSystem::new`]).
    pub inverse: SymmetricMatrix3<S>,
    /// `h^2 f`.
    pub force_h2: Vector3<S>,
    /// `h^2` times the elastic energy of the vertices whose neighbourhood holds `k`.
    pub energy_h2: S,
}

impl<S: Lanes> PointSystem<S> {
    /// `D = m I + h^2 C`, `r = m (y* - y) + h^2 f` from the gathered sums `C` (N/m) and `E` (J).
    #[inline(always)]
    pub(crate) fn assemble(
        mass: S,
        to_prediction: Vector3<S>,
        force_h2: Vector3<S>,
        precond: SymmetricMatrix3<S>,
        energy: S,
        h2: S,
    ) -> Self {
        Self::new(
            mass,
            precond * h2,
            to_prediction * mass + force_h2,
            force_h2,
            energy * h2,
        )
    }

    /// `D = m I + stiffness` and its inverse. `D` is symmetric positive definite for a mass
    /// `m > 0` and a positive semi-definite `stiffness` (kg); should round-off still make it
    /// singular (`det D` zero, or so small that its reciprocal overflows), the inverse falls
    /// back to `I / m`, the explicit move `r / m`. A non-finite stiffness gives a non-finite
    /// inverse, and the move is then caught as divergence.
    #[inline(always)]
    pub fn new(
        mass: S,
        stiffness: SymmetricMatrix3<S>,
        residual: Vector3<S>,
        force_h2: Vector3<S>,
        energy_h2: S,
    ) -> Self {
        let system = stiffness.plus_identity(mass);
        let inverse = system.inverse_or(S::one() / mass);
        Self {
            mass,
            residual,
            system,
            inverse,
            force_h2,
            energy_h2,
        }
    }

    /// The system of a unit mass at rest (`D = I`, `r = 0`): the filler of a per-point buffer
    /// before its first assembly.
    pub fn unit() -> Self {
        Self::new(
            S::one(),
            SymmetricMatrix3::zeros(),
            Vector3::zeros(),
            Vector3::zeros(),
            S::zero(),
        )
    }

    /// One Jacobi solve, `D^-1 r`.
    #[inline(always)]
    pub fn solve(&self) -> Vector3<S> {
        self.inverse.mul_vector(&self.residual)
    }

    /// The step length of eq. 31-33 for the move `delta`: `alpha = E / (h^2 f . delta)` where
    /// the linearised elastic energy would drop below zero, else 1. The cut applies only when
    /// that elastic release is a sizeable part of the move's inertial cost,
    /// `h^2 f . delta > STEP_LENGTH_SIGNIFICANCE m |delta|^2`: below it the release is either
    /// harmless or round-off (a vertex at rest has `E` and `f` at round-off level, and cutting
    /// there would freeze it).
    #[inline(always)]
    pub fn step_length(&self, delta: &Vector3<S>) -> S {
        let descent = self.force_h2.dot(delta);
        let significant =
            descent.simd_gt(S::lit(STEP_LENGTH_SIGNIFICANCE) * self.mass * delta.norm_squared());
        let cut = descent.simd_gt(self.energy_h2) & significant;
        (self.energy_h2.simd_max(S::zero()) / descent).select(cut, S::one())
    }

    /// The system of lane `l`.
    #[inline(always)]
    pub(crate) fn lane(&self, l: usize) -> PointSystem<S::Scalar> {
        let vector = |v: &Vector3<S>| Vector3::new(v.x.extract(l), v.y.extract(l), v.z.extract(l));
        let matrix = |m: &SymmetricMatrix3<S>| SymmetricMatrix3 {
            diagonal: m.diagonal.map(|x| x.extract(l)),
            upper: m.upper.map(|x| x.extract(l)),
        };
        PointSystem {
            mass: self.mass.extract(l),
            residual: vector(&self.residual),
            system: matrix(&self.system),
            inverse: matrix(&self.inverse),
            force_h2: vector(&self.force_h2),
            energy_h2: self.energy_h2.extract(l),
        }
    }

    /// The residual per unit mass, `r / m` (m): the convergence measure of a vertex touching
    /// neither a collider nor another membrane (see [`super::membranes::jacobi::free_residual`]).
    #[inline(always)]
    pub(crate) fn residual_per_mass(&self) -> Vector3<S> {
        self.residual * (S::one() / self.mass)
    }
}

/// See [`PointSystem::step_length`].
const STEP_LENGTH_SIGNIFICANCE: f64 = 0.1;
