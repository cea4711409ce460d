//! Drucker-Prager plasticity of particle bodies (He et al. 2017, section 5, eq. 14-19 as
//! corrected in DESIGN.md section 6): the yield test on each particle's bond strain state and
//! the return that moves its reference bonds, stored once per step after the local-global
//! solve (and taken within the local step, from the same bonds: [`super::cone`]).
//!
//! **Strain state.** Particle `i`'s bond `b` has the strain `e_b = |Y_b| / |X_b| - 1`; with
//! the bonds' weights `w_b = w(born_b) V_j` and `W = sum w_b`, `e_iso = sum w_b e_b / W`
//! (eq. 16 normalised), `e_dev,b = e_b - e_iso` and `||e_dev|| = sqrt(sum w_b e_dev,b^2 / W)`.
//!
//! **Invariants (eq. 17, beyond the paper).** The paper's `I1 = -lam e_iso`, `J2 = mu int
//! e_dev^2` are dimensionally wrong and use its `mu`, `lam`, which are not Lame parameters.
//! Here they are the continuum's for the body's Young's modulus `E` and Poisson ratio `nu`
//! (shear modulus `G`, bulk modulus `K`): under a small affine strain `eps` each bond's strain
//! is `n . eps n`, whose mean over directions is `tr eps / 3` and whose deviatoric part has
//! the mean square `2/15 |eps_dev|^2`, so `I1 = tr sigma = -9 K e_iso` (positive in
//! compression) and `sqrt(J2) = sqrt(|s|^2 / 2) = sqrt(15) G ||e_dev||`. The cohesion and the
//! friction angle then mean what they mean for a continuum (with `phi = 0`, a bar in tension
//! yields at the stress `2 c`, as Tresca's does).
//!
//! **Yield (eq. 14-15): the inner cone.** `sqrt(J2) <= A + B I1` with
//! `A = 6 c cos phi / (sqrt 3 (3 + sin phi))`, `B = 2 sin phi / (sqrt 3 (3 + sin phi))`: the
//! cone through Mohr-Coulomb's extension corners, inside the Mohr-Coulomb pyramid (the outer
//! cone, `3 - sin phi`, would allow more). Hardening raises the cohesion linearly:
//! `c = c_0 + H eps_p` with the accumulated plastic strain `eps_p`, explicit (the return uses
//! the cohesion from before it).
//!
//! **Return (eq. 18, corrected).** With `f = A + B I1`: if `f > 0`, `alpha = 0`,
//! `beta = (sqrt(J2) - f) / sqrt(J2)` (the paper prints the square root over the difference);
//! else `alpha = f / (B I1)`, `beta = 1` (back to the cone's apex). The co-rotated
//! displacement `D = Y - R X` (`R` the rotation of `F_i`) splits into `D_iso = e_iso R X` (per
//! bond: the paper prints a single vector) and `D_dev = D - D_iso`, and the bond's new
//! reference vector points along `R X + alpha D_iso + beta D_dev` (eq. 19). That update takes
//! the strain out to first order only; here each new `X` gets the length that leaves the bond
//! exactly the strain `e'_b = (1 - alpha) e_iso + (1 - beta) e_dev,b`, so that after the
//! return `e'_iso = (1 - alpha) e_iso` and `||e'_dev|| = (1 - beta) ||e_dev||`: the state lies
//! on the yield surface up to round-off (a departure from the paper, whose state drifts off
//! the surface by the square of the strain).
//!
//! **The kept mean on a cone without friction: the rest volume (departure).** A body whose
//! cone has no friction (`phi = 0`, von Mises: an isochoric flow), neither granular nor thin,
//! keeps `cbrt(J_i) - 1` instead of `e_iso` (`J_i = R_i det F_i`, its volume over its rest
//! volume): [`super::cone`]'s module doc derives it; [`PlasticLaw::volumes`] and
//! [`PlasticLaw::reanchor`] carry `R_i` across the returns and the neighbour rebuild.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::error::{check_param, invalid, Result};
use crate::parallel::for_each_vertex;

use super::cone::{Cone, Factors};
use super::deformation::{shape_inverse, uninverted};
use super::elastic::Elastic;
use super::influence::influence;
use super::rest_bonds::{BondRow, RestBonds, VOLUME_RATIOS};

/// A Drucker-Prager plastic law for a particle body. With `friction_angle` exactly 0 (von
/// Mises) the return of a body neither granular nor thin keeps each particle's rest volume
/// ([`super::cone`]); any positive angle keeps eq. 18's mean.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DruckerPrager {
    /// Internal friction angle `phi` (degrees, in [0, 90)).
    pub friction_angle: f64,
    /// Cohesion `c` (Pa, >= 0; > 0 when `phi = 0`).
    pub cohesion: f64,
    /// Hardening modulus `H` (Pa, >= 0): the cohesion grows by `H` per unit of accumulated
    /// plastic strain. 0 (the paper): perfectly plastic.
    pub hardening: f64,
    /// Whether the body's neighbours are searched anew on its deformed positions after every
    /// step (eq. 20, [`super::neighbour_rebuild`]); without it the body keeps its bonds.
    pub rebuild_neighbours: bool,
}

impl DruckerPrager {
    /// Checks the parameters, naming the bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "friction_angle",
            self.friction_angle,
            |v| (0.0..90.0).contains(&v),
            "an angle in [0, 90) degrees",
        )?;
        check_param("cohesion", self.cohesion, |v| v >= 0.0, "a stress >= 0 Pa")?;
        check_param(
            "hardening",
            self.hardening,
            |v| v >= 0.0,
            "a modulus >= 0 Pa",
        )?;
        if self.cohesion == 0.0 && self.friction_angle == 0.0 {
            return Err(invalid!(
                "cohesion = 0 Pa with friction_angle = 0 degrees has no strength at all: give \
                 one of them a positive value"
            ));
        }
        Ok(())
    }

    /// `A` (Pa) and `B` (dimensionless) of eq. 15, the inner cone, for the cohesion `c` (Pa).
    pub fn cone(&self, c: f64) -> (f64, f64) {
        let (sin, cos) = self.friction_angle.to_radians().sin_cos();
        let d = 3f64.sqrt() * (3.0 + sin);
        (6.0 * c * cos / d, 2.0 * sin / d)
    }
}

/// The continuum shear and bulk moduli `G`, `K` (Pa) of an elastic particle material, which
/// the invariants of the yield test are measured with (see the module's doc): from `E`, `nu`
/// as asked, or for the paper's parameters `E = (2 mu + lam) / 6` and `nu = 1/4`.
pub fn shear_and_bulk(material: &Elastic) -> (f64, f64) {
    let (e, nu) = match *material {
        Elastic::Young { e, nu } => (e, nu),
        Elastic::Paper { mu, lam } => ((2.0 * mu + lam) / 6.0, 0.25),
    };
    (e / (2.0 * (1.0 + nu)), e / (3.0 * (1.0 - 2.0 * nu)))
}

/// What a particle's bonds say at the positions `y`: its deformation gradient, the weighted
/// mean and RMS deviation of its bond strains, and the strains themselves.
pub(crate) struct LocalStrain {
    /// `F_i` from the current reference bonds, inversion turned back (dimensionless).
    pub f: Matrix3<f64>,
    /// `e_iso` and `||e_dev||` (dimensionless).
    pub iso: f64,
    pub dev: f64,
    /// `W = sum_b w_b` (dimensionless).
    pub weight: f64,
}

/// Particle `i`'s [`LocalStrain`] at the positions `y` (m), or `None` where it has no bonds
/// with weight or its shape matrix is singular.
pub(crate) fn local_strain(
    bonds: &RestBonds,
    i: usize,
    y: &[Vector3<f64>],
    delta: f64,
    volume: f64,
) -> Option<LocalStrain> {
    bonds.bonds_of(i).strain(i, y, delta, volume)
}

impl BondRow<'_> {
    /// The weight `w(born) V` of the row's bond `k` for the horizon `delta` and particle
    /// volume `volume` (m, m^3).
    #[inline]
    fn weight(&self, k: usize, delta: f64, volume: f64) -> f64 {
        influence(self.born[k], delta) * volume
    }

    /// The strain `|Y| / |X| - 1` of the row's bond `k` at the positions `y` (m) of the
    /// particle `i` whose row it is.
    #[inline]
    fn bond_strain(&self, k: usize, i: usize, y: &[Vector3<f64>]) -> f64 {
        (y[self.indices[k] as usize] - y[i]).norm() / self.xi[k].norm() - 1.0
    }

    /// The [`LocalStrain`] of particle `i`, whose bonds these are, at the positions `y` (m)
    /// (see [`local_strain`]).
    fn strain(&self, i: usize, y: &[Vector3<f64>], delta: f64, volume: f64) -> Option<LocalStrain> {
        let (mut shape, mut sum) = (Matrix3::zeros(), Matrix3::zeros());
        let (mut weight, mut mean) = (0.0, 0.0);
        for k in 0..self.xi.len() {
            let (x, w) = (self.xi[k], self.weight(k, delta, volume));
            let yb = y[self.indices[k] as usize] - y[i];
            shape += x * x.transpose() * w;
            sum += yb * x.transpose() * w;
            weight += w;
            mean += w * (yb.norm() / x.norm() - 1.0);
        }
        if weight <= 0.0 {
            return None;
        }
        let f = uninverted(sum * shape_inverse(&shape)?);
        let iso = mean / weight;
        let square: f64 = (0..self.xi.len())
            .map(|k| {
                let e = self.bond_strain(k, i, y);
                self.weight(k, delta, volume) * (e - iso) * (e - iso)
            })
            .sum();
        Some(LocalStrain {
            f,
            iso,
            dev: (square / weight).sqrt(),
            weight,
        })
    }
}

/// The rotation of the polar decomposition of `f` (`U V^T` of its SVD, a proper rotation).
fn rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = f.svd(true, true);
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    if (u * v_t).determinant() < 0.0 {
        let k = svd.singular_values.imin();
        u.column_mut(k).neg_mut();
    }
    u * v_t
}

/// A particle's volume ratio `R_i = J_i / det F_i` (dimensionless) for its volume over its
/// rest volume `volume` (`J_i`, kept from the bonds it had) and the determinant `det` of its
/// deformation gradient from its new bonds: the old ratio `ratio` where `J_i` or `det` is not
/// positive or the new ratio is not within [`VOLUME_RATIOS`] (so a state a body steps with is
/// one [`RestBonds::check`] accepts, and `J_i` stays continuous where `det F_i` says nothing).
pub(crate) fn reanchored(ratio: f64, volume: f64, det: f64) -> f64 {
    let (low, high) = VOLUME_RATIOS;
    let new = volume / det;
    if volume > 0.0 && det > 0.0 && (low..=high).contains(&new) {
        new
    } else {
        ratio
    }
}

/// A particle's yield measure: `sqrt(J2)` and the cone's `A + B I1` (Pa).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YieldState {
    pub sqrt_j2: f64,
    pub strength: f64,
}

/// The plastic law of one body with what its yield test needs.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PlasticLaw {
    pub law: DruckerPrager,
    /// `G` and `K` (Pa) of [`shear_and_bulk`].
    pub shear: f64,
    pub bulk: f64,
    /// Horizon (m) and particle volume (m^3).
    pub delta: f64,
    pub volume: f64,
    /// Whether the return keeps the rest volume ([`super::cone`]): a cone without friction,
    /// `friction_angle` exactly 0 (then and only then `B = 0`: any positive angle, however
    /// small, keeps eq. 18's mean), on a body neither granular nor thin.
    pub anchored: bool,
    /// The relaxation time `tau = eta_p / G` (s) of a viscoplastic fluid's rate-dependent
    /// return ([`super::cone`]; [`super::ViscoelasticFluid::plastic_viscosity`]); 0: eq. 18's.
    pub relaxation_time: f64,
    /// The time step `h` (s) of the step under way ([`Self::at_step`]), which a rate-dependent
    /// return relaxes over.
    pub step: f64,
}

impl PlasticLaw {
    /// The yield measure of a [`LocalStrain`] for a particle with the plastic strain `eps_p`.
    pub fn measure(&self, local: &LocalStrain, eps_p: f64) -> YieldState {
        let cone = self.cone_at(self.law.cohesion, eps_p);
        let (sqrt_j2, strength) = cone.state(local.iso, local.dev);
        YieldState { sqrt_j2, strength }
    }

    /// The cone of a particle with the cohesion `c` (Pa) before hardening and the plastic
    /// strain `eps_p`, with eq. 18's kept mean (see [`Self::anchored_cone`]).
    pub fn cone_at(&self, c: f64, eps_p: f64) -> Cone<f64> {
        let (a, b) = self.law.cone(c + self.law.hardening * eps_p);
        Cone {
            a,
            b,
            bulk9: 9.0 * self.bulk,
            shear15: 15f64.sqrt() * self.shear,
            volume: None,
            relaxation_time: self.relaxation_time,
            step: self.step,
        }
    }

    /// The law for a step of `h` (s).
    pub fn at_step(self, h: f64) -> Self {
        Self { step: h, ..self }
    }

    /// [`Self::cone_at`] of a particle whose reference bonds span the volume ratio `volume`
    /// ([`RestBonds::volume`]): where the law is [`Self::anchored`], a cone whose return keeps
    /// the rest volume ([`super::cone`]).
    pub fn anchored_cone(&self, c: f64, eps_p: f64, volume: f64) -> Cone<f64> {
        Cone {
            volume: self.anchored.then_some(volume),
            ..self.cone_at(c, eps_p)
        }
    }

    /// Re-anchors a body whose return keeps the rest volume on its bonds `bonds` (the
    /// returned and rebuilt ones) at the positions `y` (m). First every bond is born again at
    /// its reference length (`born = |X|`): the flowed neighbourhood is the body's reference
    /// now, weighted and sprung as a fresh body's of that shape would be, so that a bond the
    /// flow has stretched to `L` does not keep the weight `w(born)` and the springs
    /// `~ w(born) / born^2` of a shorter one (its stiffness against strain, `k L^2`, would grow
    /// as `(L / born)^2`: a hardening of the flow). Then each particle's
    /// [`RestBonds::volume`] is set anew, given in `volumes` its volume `J_i` with the step's
    /// bonds ([`Self::apply`]): `R_i = J_i / det F_i` with the new bonds and weights
    /// ([`reanchored`]), so that `J_i` changes only as the positions do. `volumes` is left
    /// holding the old ratios (a buffer the next [`Self::apply`] refills). The springs, and
    /// the global matrix's values, change with the birth lengths; its pattern does not.
    pub fn reanchor(&self, bonds: &mut RestBonds, y: &[Vector3<f64>], volumes: &mut Vec<f64>) {
        bonds
            .born
            .par_iter_mut()
            .zip(&bonds.xi)
            .for_each(|(born, xi)| {
                let length = xi.norm();
                if length > 0.0 && length.is_finite() {
                    *born = length;
                }
            });
        volumes.par_iter_mut().enumerate().for_each(|(i, v)| {
            let det = local_strain(bonds, i, y, self.delta, self.volume)
                .map_or(0.0, |l| l.f.determinant());
            *v = reanchored(bonds.volume[i], *v, det);
        });
        std::mem::swap(&mut bonds.volume, volumes);
    }

    /// Every particle's yield measure at the positions `y` (m; `None` for a particle without
    /// a three-dimensional weighted neighbourhood).
    pub fn yield_states(&self, bonds: &RestBonds, y: &[Vector3<f64>]) -> Vec<Option<YieldState>> {
        (0..bonds.len())
            .into_par_iter()
            .map(|i| {
                local_strain(bonds, i, y, self.delta, self.volume)
                    .map(|l| self.measure(&l, bonds.plastic_strain[i]))
            })
            .collect()
    }

    /// The return of eq. 18-19 on every particle of `bonds` at the positions `y` (m): moves
    /// the reference vectors of the particles that yield, in place, and adds to their plastic
    /// strain. Returns how many yielded. Each particle's update reads and writes its own
    /// bonds only (in parallel), so the result does not depend on the number of threads.
    /// The particles that yield are marked in `yielded_flags` (one per particle; the others
    /// are left as they are). `cohesion`, per particle (Pa), replaces the law's (wetted
    /// sand, [`super::wet_sand`]). `volumes` receives every particle's volume over its rest
    /// volume before the return, `J_i = R_i det F_i` (dimensionless; 0 where it has no
    /// deformation gradient), which [`Self::reanchor`] keeps across the new bonds.
    pub fn apply(
        &self,
        bonds: &mut RestBonds,
        y: &[Vector3<f64>],
        yielded_flags: &mut [bool],
        cohesion: Option<&[f64]>,
        volumes: &mut Vec<f64>,
    ) -> usize {
        let RestBonds {
            offsets,
            indices,
            xi,
            born,
            plastic_strain,
            volume,
        } = bonds;
        let mut outcomes = vec![(None, 0.0); plastic_strain.len()];
        for_each_vertex(offsets, xi, &mut outcomes, &|i, xi: &mut [Vector3<f64>]| {
            let row = offsets[i] as usize..offsets[i + 1] as usize;
            let (indices, born) = (&indices[row.clone()], &born[row]);
            let view = BondRow { indices, xi, born };
            let Some(local) = view.strain(i, y, self.delta, self.volume) else {
                return (None, 0.0);
            };
            let c = cohesion.map_or(self.law.cohesion, |c| c[i]);
            let j = volume[i] * local.f.determinant();
            let Some(plan) = self.plan(&view, &local, i, y, (plastic_strain[i], volume[i]), c)
            else {
                return (None, j);
            };
            for (k, x) in xi.iter_mut().enumerate() {
                let yb = y[indices[k] as usize] - y[i];
                if let Some(moved) = plan.moved(x, &yb) {
                    *x = moved;
                }
            }
            (Some(plan.increment), j)
        });
        volumes.clear();
        volumes.extend(outcomes.iter().map(|o| o.1));
        let mut yielded = 0;
        for (i, (increment, _)) in outcomes.into_iter().enumerate() {
            if let Some(strain) = increment {
                plastic_strain[i] += strain;
                yielded_flags[i] = true;
                yielded += 1;
            }
        }
        yielded
    }

    /// The return of particle `i` with its bonds `row` and their [`LocalStrain`] `local`,
    /// plastic strain and volume ratio `(eps_p, volume)` at the positions `y` (m), if it
    /// yields with the cohesion `c` (Pa) before hardening.
    fn plan(
        &self,
        row: &BondRow<'_>,
        local: &LocalStrain,
        i: usize,
        y: &[Vector3<f64>],
        (eps_p, volume): (f64, f64),
        c: f64,
    ) -> Option<Return> {
        let cone = self.anchored_cone(c, eps_p, volume);
        let factors = cone.factors_at(local.iso, local.dev, local.f.determinant())?;
        let mut plan = Return {
            factors,
            rotation: rotation(&local.f),
            increment: 0.0,
        };
        let removed: f64 = (0..row.xi.len())
            .map(|k| {
                let e = row.bond_strain(k, i, y);
                let w = row.weight(k, self.delta, self.volume);
                w * (e - factors.target(e)).powi(2)
            })
            .sum();
        plan.increment = (removed / local.weight).sqrt();
        Some(plan)
    }
}

/// One particle's return (eq. 18-19, see the module's doc).
pub(super) struct Return {
    /// `alpha`, `beta` of eq. 18 and `e_iso` before the return (dimensionless).
    pub(super) factors: Factors<f64>,
    /// The rotation `R` of `F_i`.
    pub(super) rotation: Matrix3<f64>,
    /// The plastic strain the return takes away (dimensionless).
    pub(super) increment: f64,
}

impl Return {
    /// The new reference vector (m) of a bond with the vector `x` (m) and the deformed vector
    /// `yb` (m): the direction of eq. 19 with the length of [`Factors::kept_length`], the
    /// kernel's (`None`, the bond keeping its vector, exactly when the kernel keeps it). Where
    /// eq. 19 gives no direction (`along = 0`) the bond takes `yb`'s, which the kept length
    /// (`> 0`) guarantees.
    #[inline]
    pub(super) fn moved(&self, x: &Vector3<f64>, yb: &Vector3<f64>) -> Option<Vector3<f64>> {
        let Factors {
            alpha, beta, iso, ..
        } = self.factors;
        let length = self.factors.kept_length(yb.norm(), x.norm())?;
        let rx = self.rotation * x;
        let d = yb - rx;
        let d_iso = rx * iso;
        let along = rx + d_iso * alpha + (d - d_iso) * beta;
        let norm = along.norm();
        Some(if norm > 0.0 {
            along * (length / norm)
        } else {
            yb * (length / yb.norm())
        })
    }
}

impl PlasticLaw {
    /// The law of a plastic body (`None` for an elastic one).
    pub fn of(body: &super::Particles) -> Option<Self> {
        let (shear, bulk) = shear_and_bulk(&body.params().material);
        let thin = body.num_real() < body.num_particles();
        body.plasticity().map(|&law| Self {
            law,
            shear,
            bulk,
            delta: body.horizon(),
            volume: body.volume(),
            anchored: law.friction_angle == 0.0 && body.granular().is_none() && !thin,
            relaxation_time: body.fluid_material().map_or(0.0, |f| f.relaxation_time()),
            step: 0.0,
        })
    }
}

impl super::Particles {
    /// Every particle's yield measure (Pa) at the current positions with the current
    /// reference bonds (`None` for a particle without a three-dimensional neighbourhood), or
    /// `None` for an elastic body.
    pub fn yield_states(&self) -> Option<Vec<Option<YieldState>>> {
        let law = PlasticLaw::of(self)?;
        Some(law.yield_states(&self.current_rest_bonds(), self.positions()))
    }
}
