//! A particle's Drucker-Prager cone (He et al. 2017, eq. 14-15, the inner cone
//! `3 + sin phi`, invariants as corrected in [`super::plasticity`]) and the return factors of
//! eq. 18 (corrected), in the simulation's precision: shared by the return at a step's end
//! ([`super::plasticity`], f64) and the return within the local step ([`Cone::local_return`]).
//!
//! **The return within the local step (departure).** The paper returns once per step, after
//! the local-global solve: every bond then stays elastic through the step's iterations and the
//! solve finds the implicit step of an elastic body that yields only afterwards, so the bonds
//! resist the step's motion like a viscosity of about `K_f h / 6` (a sand column ran out to
//! dR/R = 0.47 where Lube et al. 2004 measure 1.24), and an elastic-plastic body's set
//! depended on the step. So the kernel takes the return as part of its local step: at every
//! evaluation it projects the particle's bond strains, measured from the step's reference
//! bonds, onto the cone (`e'_b = (1 - alpha) e_iso + (1 - beta) e_dev,b`) and springs each
//! bond to the length `|X'_b| = |Y_b| / (1 + e'_b)` that leaves it that strain (the
//! dilatation term's mean strain too). The reference bonds themselves are not touched within
//! the step (the kernel stays a function of the positions, as the line search needs); the
//! return at the step's end, from the same reference bonds at the final positions, stores
//! exactly these lengths, and the directions of eq. 19. This is the implicit (backward
//! Euler) return of the step's whole strain increment. For a body of pair springs only
//! (`mu = 0`, no dilatation term: granular bodies) a bond's force depends on its reference
//! vector through its length alone, so the kernel's bonds are the stored ones exactly; with
//! `mu > 0` the kernel keeps `F_i` and the deviatoric springs' directions `dir(F_i X)` from
//! the step's bonds, which the stored ones (turned by eq. 19, each with its own length)
//! reproduce where every bond of an affinely deformed neighbourhood is scaled alike
//! (`F' X' = F X = Y`), and to first order in the plastic strain otherwise; the dilatation
//! term's lengths and shares are the stored ones exactly ([`Factors::returned`]).
//!
//! **What the return keeps of the mean strain: the rest volume (departure).** Eq. 18
//! keeps `(1 - alpha) e_iso`, the weighted mean bond strain. On a cone without friction
//! (`B = 0`: von Mises, whose flow is isochoric) the kept mean is the particle's elastic
//! dilatation, which must then be its whole dilatation from the rest state. The mean bond
//! strain measures that only to first order, and each return stores its error in the reference:
//! an increment `d eps` adds `tr(M d eps)` to it (`M = sum w n n^T / W`, not `I / 3` where a
//! surface or the flow has made the bond directions anisotropic), and a deviatoric strain of RMS
//! `d` adds about `d^2`; so an isochoric flow ratchets the reference short and the bulk term
//! resists it as a hardening (docs/particles/fluids.md). Such a cone carries the
//! volume ratio `R_i` of the particle's reference bonds to its rest volume
//! ([`super::RestBonds::volume`]) and the return keeps, instead,
//! `e_kept = cbrt(J_i) - 1` with `J_i = R_i det F_i` (`F_i` from the step's reference bonds):
//! the particle's volume over its rest volume (moved from eq. 18's mean by at most
//! [`KEPT_CORRECTION`] per return), so that the returned bonds
//! `|X'_b| = |Y_b| / (1 + e_kept + (1 - beta) (e_b - e_iso))` leave the dilatation term's mean
//! strain at the particle's true volume change, and an isochoric flow (`J_i = 1`) keeps none.
//! At the step's end `R_i` is set anew from the returned (and rebuilt) bonds at the same
//! positions, `R_i = J_i / det F_i(X')`, so `J_i` changes only as the positions do
//! ([`super::PlasticLaw::reanchor`]; kept where the new ratio leaves
//! [`super::rest_bonds::VOLUME_RATIOS`]). `F_i` is the uninverted one
//! ([`super::deformation::uninverted`]), so `det F_i >= 0`: an inverted neighbourhood counts
//! by the volume of its mirror image, `|det F|`, and its return keeps that volume while the
//! deviatoric springs push it back to its orientation. Where `J_i` is not positive (`F_i`
//! singular, a neighbourhood collapsed to a plane, or no three-dimensional neighbourhood
//! among the bonds) the return keeps eq. 18's mean.
//!
//! **A rate-dependent return: the overstress relaxed over `tau` (beyond the paper).** A
//! viscoplastic (Bingham) fluid flows at the stress `sqrt(J2) = k + sqrt(2) eta_p |D_dev|`
//! (Bingham 1922; in tension `sigma = sigma_y + 3 eta_p eps_dot`, Trouton's viscosity): a
//! neck that thins fast carries more stress than one that thins slowly. With a relaxation
//! time `tau = eta_p / G` (s, the plastic viscosity over the shear modulus) the return is
//! Duvaut and Lions' (1972) form of Perzyna's (1966) linear overstress law, taken backward
//! (implicit) over the step `h`: the state moves from its trial toward the cone's projection
//! by the fraction `r = h / (tau + h)` of the way (`alpha`, `beta` of eq. 18 times `r`), so the
//! overstress `q = sqrt(J2) - f` decays as `q' = q_trial tau / (tau + h)`. In a steady flow at
//! the deviatoric bond strain rate `d` (RMS, 1/s) each step adds `sqrt(15) G d h` to `q` and the
//! return keeps `q = sqrt(15) G tau d = sqrt(15) eta_p d`, for any step. In an isotropic
//! neighbourhood an affine rate's bond strain rates have the RMS deviation
//! `sqrt(2/15) |D_dev|`, and `q = sqrt(2) eta_p |D_dev|` is the Bingham stress; on the lattice
//! `d` is 1.117 times that for an extension along an axis (0.914 for a shear in a lattice
//! plane), and more where a surface cuts the bonds or the flow turns them (1.34 in the middle
//! of a bar 4 particles across stretched to 1.5): the overstress carries the same factor
//! (docs/particles/fluids.md, round z). The overstress is elastic strain kept in the reference bonds
//! (state already saved with them); `tau = 0` gives `r = 1` exactly, eq. 18's return.
//!
//! Scaling `alpha` and `beta` by `r` moves the bond strains to `(1 - r)` times the trial's
//! plus `r` times eq. 18's return, Duvaut and Lions' update, and `sqrt(J2)` and `I1` are
//! linear in them: in both of eq. 18's regions, the apex (`B > 0`, `f <= 0`: returned to
//! `sqrt(J2) = 0`, `f = 0`) included, the cone function `sqrt(J2) - A - B I1` of the state
//! falls to `(1 - r)` times the trial's (cone_tests). For `B > 0` eq. 18's return keeps `I1`
//! where `f > 0` (it is not the cone's closest point), so the relaxed return is Duvaut and
//! Lions' form of that non-associated return, not Perzyna's flow along the cone's gradient.
//! No body relaxes on such a cone: only a viscoelastic fluid has `tau > 0`, and its cone has
//! `B = 0` (no apex; fluid.rs, `ViscoelasticFluid::elastoplastic`). The kept mean's correction
//! toward the rest volume ([`Cone::factors_at`]) is not relaxed: it is no plastic flow (a cone
//! with `B = 0` flows isochorically) but the reference's record of the particle's true
//! volume, which each return's drift of the mean bond strain (the relaxed return's too) moves;
//! relaxed by `r`, it would leave `(1 - r)` of every step's drift, `tau / h` steps' drift in a
//! steady flow.

use nalgebra::Vector3;

use crate::real::Real;

use super::bond::BondRest;

/// The most a return that keeps the rest volume moves the kept mean strain away from eq. 18's
/// (dimensionless, per return): `cbrt(J_i) - 1` corrects the mean bond strain's drift (of the
/// order of a step's strain at a surface, its square inside, see the module's doc; a larger
/// drift is corrected over several returns while the particle yields); where the two differ
/// by far more, `det
/// F_i` measures a flattened or inverted neighbourhood (an impact), not the particle's volume,
/// and the whole correction would spring the bonds to lengths the next step's elasticity
/// answers with an enormous force. The kept mean then moves toward it by this much per return.
pub const KEPT_CORRECTION: f64 = 0.01;

/// One particle's yield cone `sqrt(J2) <= A + B I1` with `I1 = -9 K e_iso` and
/// `sqrt(J2) = sqrt(15) G ||e_dev||` ([`super::plasticity`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cone<T: Real> {
    /// `A` (Pa): the cohesion's share, hardening included.
    pub a: T,
    /// `B` (dimensionless): the friction's.
    pub b: T,
    /// `9 K` and `sqrt(15) G` (Pa).
    pub bulk9: T,
    pub shear15: T,
    /// For a return that keeps the rest volume (see the module's doc), the volume ratio `R_i`
    /// of the particle's reference bonds to its rest volume (dimensionless); `None`: eq. 18's
    /// mean.
    pub volume: Option<T>,
    /// The relaxation time `tau = eta_p / G` (s) of a rate-dependent return (see
    /// [`Self::relaxed`]); 0: the rate-independent return of eq. 18.
    pub relaxation_time: T,
    /// The time step `h` (s) the return relaxes over (unused where `relaxation_time` is 0).
    pub step: T,
}

/// The factors of eq. 18 (corrected) for one particle beyond its cone, with its mean strain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Factors<T: Real> {
    /// `alpha`, `beta` (dimensionless, in [0, 1]).
    pub alpha: T,
    pub beta: T,
    /// `e_iso` before the return (dimensionless).
    pub iso: T,
    /// The mean strain the return keeps (dimensionless): `(1 - alpha) e_iso` (eq. 18), or
    /// `cbrt(J_i) - 1` on a cone that keeps the rest volume (see the module's doc).
    pub kept: T,
}

impl<T: Real> Cone<T> {
    /// `sqrt(J2)` and `A + B I1` (Pa) at the mean strain `iso` and the RMS deviation `dev`.
    #[inline]
    pub fn state(&self, iso: T, dev: T) -> (T, T) {
        (self.shear15 * dev, self.a - self.b * self.bulk9 * iso)
    }

    /// The fraction `r = h / (tau + h)` (dimensionless, in (0, 1]) of the way from the trial
    /// state to the cone that the return takes (see the module's doc): 1 exactly for the
    /// rate-independent return (`tau = 0`).
    #[inline]
    pub fn relaxed(&self) -> T {
        if self.relaxation_time > T::zero() {
            self.step / (self.relaxation_time + self.step)
        } else {
            T::one()
        }
    }

    /// Eq. 18 (corrected) at the mean strain `iso` and the RMS deviation `dev`: `None` inside
    /// the cone; else, with `f = A + B I1`, `alpha = 0`, `beta = (sqrt(J2) - f) / sqrt(J2)`
    /// if `f > 0`, and `alpha = f / (B I1)`, `beta = 1` (to the apex) otherwise; both times
    /// [`Self::relaxed`]'s `r` for a rate-dependent return.
    #[inline]
    pub fn factors(&self, iso: T, dev: T) -> Option<Factors<T>> {
        let (sqrt_j2, f) = self.state(iso, dev);
        if sqrt_j2 <= f {
            return None;
        }
        let b_i1 = -self.b * self.bulk9 * iso;
        let (alpha, beta) = if f > T::zero() {
            (T::zero(), (sqrt_j2 - f) / sqrt_j2)
        } else if b_i1 != T::zero() {
            (f / b_i1, T::one())
        } else {
            (T::zero(), T::one())
        };
        let r = self.relaxed();
        let (alpha, beta) = (alpha * r, beta * r);
        Some(Factors {
            alpha,
            beta,
            iso,
            kept: (T::one() - alpha) * iso,
        })
    }

    /// [`Self::factors`] of a particle whose deformation gradient from the step's reference
    /// bonds has the determinant `det`: on a cone that keeps the rest volume, with the kept
    /// mean `cbrt(R_i det) - 1` where `R_i det > 0` (see the module's doc), moved from eq. 18's
    /// by at most [`KEPT_CORRECTION`].
    #[inline]
    pub fn factors_at(&self, iso: T, dev: T, det: T) -> Option<Factors<T>> {
        let mut factors = self.factors(iso, dev)?;
        if let Some(reference) = self.volume {
            let volume = reference * det;
            if volume > T::zero() {
                let bound = T::of(KEPT_CORRECTION);
                let correction = volume.cbrt() - T::one() - factors.kept;
                factors.kept += correction.max(-bound).min(bound);
            }
        }
        Some(factors)
    }

    /// The return within the local step (see the module's doc) of a particle with the bonds
    /// `bonds` at the bond vectors `y` (`Y_b`, m) and the deformation gradient's determinant
    /// `det` (evaluated only on a cone that keeps the rest volume): its factors ([`Self::factors_at`]), or `None` inside the cone or without
    /// weighted bonds. The strains are `|Y_b| / |X_b| - 1`, weighted by the bonds' `w V_j`.
    #[inline]
    pub fn local_return(
        &self,
        bonds: &[BondRest<T>],
        y: &[Vector3<T>],
        det: impl FnOnce() -> T,
    ) -> Option<Factors<T>> {
        let strain = |bond: &BondRest<T>, y: &Vector3<T>| y.norm() / bond.length - T::one();
        let (mut weight, mut mean) = (T::zero(), T::zero());
        for (bond, y) in bonds.iter().zip(y) {
            weight += bond.weight;
            mean += bond.weight * strain(bond, y);
        }
        if weight <= T::zero() {
            return None;
        }
        let iso = mean / weight;
        let square = bonds.iter().zip(y).fold(T::zero(), |s, (bond, y)| {
            let e = strain(bond, y) - iso;
            s + bond.weight * e * e
        });
        // The determinant only where the cone keeps the rest volume (the kernel's hot path).
        let det = if self.volume.is_some() {
            det()
        } else {
            T::zero()
        };
        self.factors_at(iso, (square / weight).sqrt(), det)
    }
}

impl<T: Real> Factors<T> {
    /// The strain a bond of strain `e` keeps, `e_kept + (1 - beta) (e - e_iso)` (eq. 18:
    /// `e_kept = (1 - alpha) e_iso`).
    #[inline]
    pub fn target(&self, e: T) -> T {
        self.kept + (T::one() - self.beta) * (e - self.iso)
    }

    /// The weighted mean of the kept strains, `sum w_b e'_b / W = e_kept` (the deviations
    /// have mean 0): the dilatation term's mean strain `sum a'_b (|Y_b| - |X'_b|)` over the
    /// [`Self::returned`] bonds, without a pass over them (a bond squeezed to nothing, which
    /// keeps its length, is off by its share of the difference).
    #[inline]
    pub fn kept_mean(&self) -> T {
        self.kept
    }

    /// The length `|X'| = |Y| / (1 + e')` (m) that leaves a bond of the reference length
    /// `length` (m), stretched to `norm = |Y|` (m), the strain `e'` = [`Self::target`];
    /// `None` for a bond squeezed below `1e-6` of its reference length, which keeps its
    /// reference (no length or direction to give it). `1 + e'` is at least `1e-6` (a
    /// collapsed neighbourhood, `e_iso = -1`, would give `0 / 0`). The one test of both
    /// returns: within the local step ([`Self::returned`]) and at the step's end
    /// ([`super::plasticity`]), so they keep the same bonds.
    #[inline]
    pub fn kept_length(&self, norm: T, length: T) -> Option<T> {
        let floor = T::of(1e-6);
        let kept = self.target(norm / length - T::one());
        let returned = norm / (T::one() + kept).max(floor);
        (returned > floor * length).then_some(returned)
    }

    /// `bond` with the length `|X'|` of [`Self::kept_length`] at the bond vector `y` (m), and
    /// the share of the mean strain that the rest rebuilt from `|X'|` gives it:
    /// `a' = w V_j / (A_i |X'|) = a |X| / |X'|` (1/m, see [`super::bond`]). Exact for the
    /// uncorrected shares, which every plastic body has ([`super::rest`]: the
    /// direction-based corrections skip plastic bodies). A squeezed bond keeps its length,
    /// as at the step's end.
    #[inline]
    pub fn returned(&self, bond: &BondRest<T>, y: &Vector3<T>) -> BondRest<T> {
        match self.kept_length(y.norm(), bond.length) {
            Some(length) => BondRest {
                length,
                share: bond.share * (bond.length / length),
                ..*bond
            },
            None => *bond,
        }
    }
}

#[cfg(test)]
#[path = "cone_tests.rs"]
mod tests;
