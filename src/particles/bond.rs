//! The per-bond local step and forces of the particle model (He et al. 2017, eq. 8-11 as
//! corrected in DESIGN.md section 6).
//!
//! For the bond `xi = x_j - x_i` of particle `i` with `Y = y_j - y_i`, the energy of eq. 8
//! (times the volumes `V_i V_j`) is
//! `e = k_dev / 2 (|F_i xi| - |xi|)^2 + k_iso / 2 (|Y| - |xi|)^2` (J), with the constant bond
//! stiffnesses `k_dev = 2 mu V_i V_j w / |xi|^2` and `k_iso = lam V_i V_j w / |xi|^2` (N/m).
//! The local step projects each bond: `p_dev = |xi| dir(F_i xi)`, `p_iso = |xi| dir Y`
//! (the "dim Y" of section 4.2 is `dir Y`), and the bond's force state (eq. 10-11, times
//! `V_i V_j`) is `g = k_dev (Y - p_dev) + k_iso (Y - p_iso)` (N): `+g` acts on `i`, `-g` on
//! `j`. The isotropic part is the exact gradient of its energy; the deviatoric part drops the
//! derivative of `F_i` (eq. 9 -> 10: `Y* ~ Y`), so it is not a gradient of anything.
//!
//! **Dilatation (beyond the paper, as in state-based LPS, Silling et al. 2007).** Particle `i`
//! stores `9 kappa V_i / 2 s_i^2` (J) more, with `s_i = sum_j a_j (|Y_j| - |xi_j|)` the
//! weighted mean bond strain (`a_j = w V_j / (A_i |xi_j|)`, 1/m, `A_i = sum_j w V_j`; under
//! a small affine strain `s_i = tr eps / 3`) and `kappa` (Pa) the modulus the calibration
//! adds to `C11` and `C12` ([`super::calibration`]): the pressure `P = 9 kappa V_i s_i` (J)
//! adds `P a_j dir Y` to each bond's force, the exact gradient of this energy.

use nalgebra::{Matrix3, Vector3};

use crate::real::{Lanes, Real};

/// `|len| dir(v)` for `v` of norm `norm`: `v` scaled to the length `len` (m); `fallback`
/// (already of length `len`) where `v` has no direction.
#[inline(always)]
fn projected<T: Real>(v: &Vector3<T>, norm: T, len: T, fallback: Vector3<T>) -> Vector3<T> {
    if norm > T::zero() {
        v * (len / norm)
    } else {
        fallback
    }
}

/// The rest data of one bond, in the simulation's precision.
#[derive(Clone, Copy, Debug)]
pub struct BondRest<T: Real> {
    /// `xi = x_j - x_i` (m) and `|xi|` (m).
    pub xi: Vector3<T>,
    pub length: T,
    /// `w V_j` (dimensionless): the bond's weight in `F_i` and `K_i`.
    pub weight: T,
    /// `k_dev` and `k_iso` (N/m).
    pub k_dev: T,
    pub k_iso: T,
    /// `a = w V_j / (A_i |xi|)` (1/m): the bond's share of the mean strain of its particle.
    pub share: T,
}

/// The local step of one bond at `Y = y_j - y_i` with the particle's deformation gradient
/// `f` and dilatation pressure `pressure` (J): the bond's force on `i`, `g` (N), and its
/// spring energy `e` (J; the dilatation energy is the particle's, not the bond's).
#[inline(always)]
pub fn bond_force<T: Real>(
    bond: &BondRest<T>,
    f: &Matrix3<T>,
    y: &Vector3<T>,
    pressure: T,
) -> (Vector3<T>, T) {
    let lanes = BondLanes::<T>::gather(std::slice::from_ref(bond));
    let (g, e, directed) = bond_force_lanes(&lanes, f, y, pressure);
    if directed {
        return (g, e);
    }
    // Without a direction (a collapsed bond), each projection takes the other's, then the
    // rest direction.
    let fxi = f * bond.xi;
    let (fxi_norm, y_norm) = (fxi.norm(), y.norm());
    let p_iso = projected(
        y,
        y_norm,
        bond.length,
        projected(&fxi, fxi_norm, bond.length, bond.xi),
    );
    let p_dev = projected(&fxi, fxi_norm, bond.length, p_iso);
    let dilatation = p_iso * (pressure * bond.share / bond.length);
    let g = (y - p_dev) * bond.k_dev + (y - p_iso) * bond.k_iso + dilatation;
    (g, e)
}

/// The constants of [`BondRest`] that the local step reads, one bond per lane of `S` (a
/// scalar: one bond; a SIMD pack: [`Lanes`] bonds of one particle at once).
#[derive(Clone, Copy, Debug)]
pub struct BondLanes<S: Lanes> {
    pub xi: Vector3<S>,
    pub length: S,
    pub k_dev: S,
    pub k_iso: S,
    pub share: S,
}

impl<S: Lanes> BondLanes<S> {
    /// The bonds `bonds[0..LANES]`, one per lane.
    #[inline(always)]
    pub fn gather(bonds: &[BondRest<S::Scalar>]) -> Self {
        let field = |get: fn(&BondRest<S::Scalar>) -> S::Scalar| S::gather(|l| get(&bonds[l]));
        Self {
            xi: Vector3::new(field(|b| b.xi.x), field(|b| b.xi.y), field(|b| b.xi.z)),
            length: field(|b| b.length),
            k_dev: field(|b| b.k_dev),
            k_iso: field(|b| b.k_iso),
            share: field(|b| b.share),
        }
    }
}

/// [`bond_force`] of the bonds in the lanes of `bond` where both `F xi` and `Y` have a
/// direction (the third value: in which lanes they have; the other lanes' forces are not
/// numbers): `g = k_dev (Y - p_dev) + k_iso (Y - p_iso) + P a p_iso / |xi|` with
/// `p_iso = |xi| Y / |Y|` and `p_dev = |xi| F xi / |F xi|`, gathered on `Y` and `F xi` (two
/// divisions per bond), and the spring energy `e` in every lane. Every lane performs the
/// scalar operations in the scalar order, so a pack's lanes are bit-identical to the bonds
/// computed one at a time ([`Lanes`]).
#[inline(always)]
pub fn bond_force_lanes<S: Lanes>(
    bond: &BondLanes<S>,
    f: &Matrix3<S>,
    y: &Vector3<S>,
    pressure: S,
) -> (Vector3<S>, S, S::SimdBool) {
    let fxi = f * bond.xi;
    let (fxi_norm, y_norm) = (fxi.norm(), y.norm());
    let zero = S::zero();
    let directed = fxi_norm.simd_gt(zero) & y_norm.simd_gt(zero);
    let (over_y, over_f) = (S::one() / y_norm, S::one() / fxi_norm);
    let along_y =
        bond.k_dev + bond.k_iso + (pressure * bond.share - bond.k_iso * bond.length) * over_y;
    let g = y * along_y - fxi * (bond.k_dev * bond.length * over_f);
    let half = S::lit(0.5);
    let dev = fxi_norm - bond.length;
    let iso = y_norm - bond.length;
    let e = half * (bond.k_dev * dev * dev + bond.k_iso * iso * iso);
    (g, e, directed)
}
