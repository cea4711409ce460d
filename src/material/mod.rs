//! Constitutive models written in principal stretches, each split into the positive part of
//! the diagonal stress that SISSM treats implicitly and the negative part it treats explicitly
//! (Lu et al. 2023, section 5).

mod neo_hookean;
mod stretch_a3;

use crate::error::{check_param, Result};
use crate::real::{Lanes, Real};

/// An isotropic hyperelastic material. Stiffnesses are in Pa, energies in J/m^3.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// `Psi = s0 sum_m A3(lambda_m)` (eq. 39-41).
    StretchA3 { s0: f64 },
    /// `Psi = s0 (I1 - 3 - ln I3) + s1 (sqrt(I3) - 1)^2` (eq. 36-38).
    NeoHookean { s0: f64, s1: f64 },
}

impl Material {
    /// The A3 stretching model with stiffness `s0` (Pa, >= 0).
    pub fn stretch_a3(s0: f64) -> Result<Self> {
        let s0 = check_param("s0", s0, |v| v >= 0.0, "a finite stiffness >= 0 Pa")?;
        Ok(Self::StretchA3 { s0 })
    }

    /// The compressible neo-Hookean model (`s0`, `s1` in Pa, >= 0).
    pub fn neo_hookean(s0: f64, s1: f64) -> Result<Self> {
        let s0 = check_param("s0", s0, |v| v >= 0.0, "a finite stiffness >= 0 Pa")?;
        let s1 = check_param("s1", s1, |v| v >= 0.0, "a finite stiffness >= 0 Pa")?;
        Ok(Self::NeoHookean { s0, s1 })
    }

    /// The A3 model of a sheet with in-plane Young's modulus `E` (Pa): `s0 = E / 2`. A3 has no
    /// Poisson coupling, so `nu` must be 0.
    pub fn stretch_a3_from_young(young: f64, nu: f64) -> Result<Self> {
        check_param("E", young, |v| v > 0.0, "a finite modulus > 0 Pa")?;
        if nu != 0.0 {
            return Err(crate::error::invalid!(
                "StretchA3 has Poisson's ratio 0 (its principal stretches are uncoupled); got nu = {nu}. \
                 Use NeoHookean.from_young for nu != 0"
            ));
        }
        Self::stretch_a3(young / 2.0)
    }

    /// The neo-Hookean model of a sheet with in-plane (plane-stress) Young's modulus `E` (Pa)
    /// and Poisson ratio `nu`: `s0 = E / (4 (1 + nu))`, `s1 = E nu / (2 (1 - nu^2))`, so that
    /// the sheet (normal unstretched, plane strain with `mu = 2 s0`, `lambda = 2 s1`) answers a
    /// small uniaxial stress with strain `sigma / E` and lateral contraction `nu`.
    pub fn neo_hookean_from_young(young: f64, nu: f64) -> Result<Self> {
        check_param("E", young, |v| v > 0.0, "a finite modulus > 0 Pa")?;
        check_param(
            "nu",
            nu,
            |v| (0.0..0.5).contains(&v),
            "in [0, 0.5) for a sheet",
        )?;
        Self::neo_hookean(
            young / (4.0 * (1.0 + nu)),
            young * nu / (2.0 * (1.0 - nu * nu)),
        )
    }

    /// Small-strain shear modulus (Pa).
    pub fn shear_modulus(&self) -> f64 {
        match *self {
            Self::StretchA3 { s0 } => s0,
            Self::NeoHookean { s0, .. } => 2.0 * s0,
        }
    }

    /// Small-strain first Lame parameter (Pa) of the model with its normal stretch held at 1.
    pub fn lame_lambda(&self) -> f64 {
        match *self {
            Self::StretchA3 { .. } => 0.0,
            Self::NeoHookean { s1, .. } => 2.0 * s1,
        }
    }

    /// The material's constants converted to the simulation's precision.
    pub fn to_real<T: Real>(&self) -> MaterialModel<T> {
        let model = match *self {
            Self::StretchA3 { s0 } => MaterialModel::StretchA3 { s0 },
            Self::NeoHookean { s0, s1 } => MaterialModel::NeoHookean { s0, s1 },
        };
        model.to_real()
    }
}

/// [`Material`] in the simulation's precision, evaluated per vertex in the hot loop.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MaterialModel<T> {
    StretchA3 { s0: T },
    NeoHookean { s0: T, s1: T },
}

impl MaterialModel<f64> {
    /// The same model in another precision.
    pub fn to_real<T: Real>(&self) -> MaterialModel<T> {
        match *self {
            Self::StretchA3 { s0 } => MaterialModel::StretchA3 { s0: T::of(s0) },
            Self::NeoHookean { s0, s1 } => MaterialModel::NeoHookean {
                s0: T::of(s0),
                s1: T::of(s1),
            },
        }
    }
}

impl<S: Lanes> MaterialModel<S> {
    /// Energy density `Psi(lambda)` (J/m^3).
    #[inline]
    pub fn energy(&self, l: [S; 3]) -> S {
        match *self {
            Self::StretchA3 { s0 } => stretch_a3::energy(s0, l),
            Self::NeoHookean { s0, s1 } => neo_hookean::energy(s0, s1, l),
        }
    }

    /// Diagonal first Piola-Kirchhoff stress `dPsi/dlambda_m` (Pa), eq. 35.
    #[inline]
    pub fn stress(&self, l: [S; 3]) -> [S; 3] {
        let (plus, minus) = self.stress_split(l);
        [plus[0] + minus[0], plus[1] + minus[1], plus[2] + minus[2]]
    }

    /// The stress split into its positive and negative parts `(P+, P-)` (eq. 38 and 41).
    #[inline]
    pub fn stress_split(&self, l: [S; 3]) -> ([S; 3], [S; 3]) {
        match *self {
            Self::StretchA3 { s0 } => stretch_a3::stress_split(s0, l),
            Self::NeoHookean { s0, s1 } => neo_hookean::stress_split(s0, s1, l),
        }
    }

    /// Second derivatives of `Psi` in the in-plane stretches at fixed `lambda_3`:
    /// `(d2Psi/dl1^2, d2Psi/dl2^2, d2Psi/dl1 dl2)` (Pa).
    #[inline]
    pub fn in_plane_hessian(&self, l: [S; 3]) -> [S; 3] {
        match *self {
            Self::StretchA3 { s0 } => stretch_a3::in_plane_hessian(s0, l),
            Self::NeoHookean { s0, s1 } => neo_hookean::in_plane_hessian(s0, s1, l),
        }
    }

    /// `P+_m / lambda_m` (Pa), the non-negative stiffness that SISSM treats implicitly: the
    /// matrix `U diag(P+/lambda) U^T` of eq. 24-26.
    #[inline]
    pub fn implicit_stiffness(&self, l: [S; 3]) -> [S; 3] {
        match *self {
            Self::StretchA3 { s0 } => stretch_a3::implicit_stiffness(s0, l),
            Self::NeoHookean { s0, s1 } => neo_hookean::implicit_stiffness(s0, s1, l),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stress of every model is the derivative of its energy (central differences), and
    /// the split parts add up to it with P+ >= 0 >= P-.
    #[test]
    fn stress_is_the_gradient_of_energy_and_splits_by_sign() {
        let models = [
            MaterialModel::StretchA3 { s0: 1234.0f64 },
            MaterialModel::NeoHookean {
                s0: 900.0,
                s1: 2500.0,
            },
        ];
        let samples: [[f64; 3]; 4] = [
            [1.0, 1.0, 1.0],
            [1.3, 0.8, 1.0],
            [0.4, 2.2, 1.0],
            [0.9, 1.1, 0.7],
        ];
        for m in models {
            for l in samples {
                let p = m.stress(l);
                let (plus, minus) = m.stress_split(l);
                for k in 0..3 {
                    let h = 1e-6;
                    let (mut a, mut b) = (l, l);
                    a[k] += h;
                    b[k] -= h;
                    let fd = (m.energy(a) - m.energy(b)) / (2.0 * h);
                    assert!(
                        (fd - p[k]).abs() <= 1e-6 * (1.0 + p[k].abs()),
                        "{m:?} {l:?} {k}: {fd} vs {}",
                        p[k]
                    );
                    assert!(plus[k] >= 0.0 && minus[k] <= 0.0);
                    let stiff = m.implicit_stiffness(l)[k];
                    assert!((stiff - plus[k] / l[k]).abs() <= 1e-12 * stiff.abs().max(1.0));
                }
                let hess = m.in_plane_hessian(l);
                for (k, (a, b)) in [(0, 0), (1, 1), (0, 1)].into_iter().enumerate() {
                    let h = 1e-6;
                    let (mut up, mut down) = (l, l);
                    up[b] += h;
                    down[b] -= h;
                    let fd = (m.stress(up)[a] - m.stress(down)[a]) / (2.0 * h);
                    assert!(
                        (fd - hess[k]).abs() <= 1e-6 * (1.0 + fd.abs()),
                        "{m:?} {l:?} H{a}{b}: {fd} vs {}",
                        hess[k]
                    );
                }
            }
            assert!(m.energy([1.0; 3]).abs() < 1e-12);
            assert!(m.stress([1.0; 3]).iter().all(|s| s.abs() < 1e-12));
        }
    }

    /// At the stretch floor of f32 (a collapsed neighbourhood) the energies stay finite and
    /// agree with f64 to 2e-6: the neo-Hookean `ln x` must not be taken as `ln(1 + u)` at the
    /// floor, nor `u - ln(1 + u)` as a difference near 1.
    #[test]
    fn f32_energies_are_finite_and_accurate_at_extreme_stretches() {
        for m in [
            Material::stretch_a3(3e4).unwrap(),
            Material::neo_hookean(1e4, 2e4).unwrap(),
        ] {
            // Stretches exactly representable in f32, so only the evaluation differs.
            for l in [
                [1.0 / 8192.0, 1.0 / 8192.0, 1.0],
                [1.0 / 8192.0, 3.0, 1.0],
                [1.0 + 1.0 / 8192.0, 1.0, 1.0],
                [40.0, 0.75, 1.0],
            ] {
                let wide = m.to_real::<f64>().energy(l);
                let narrow = m.to_real::<f32>().energy(l.map(|x| x as f32)) as f64;
                assert!(
                    narrow.is_finite() && (narrow - wide).abs() <= 2e-6 * wide,
                    "{m:?} {l:?}: f32 {narrow} vs f64 {wide}"
                );
            }
        }
    }

    /// Small strain: Psi ~ mu |eps|^2 + lambda/2 tr(eps)^2 with the moduli reported.
    #[test]
    fn small_strain_moduli_match_the_reported_ones() {
        for m in [
            Material::stretch_a3(700.0).unwrap(),
            Material::neo_hookean(300.0, 450.0).unwrap(),
        ] {
            let model = m.to_real::<f64>();
            let e = 1e-4;
            let (mu, lam) = (m.shear_modulus(), m.lame_lambda());
            let psi = model.energy([1.0 + e, 1.0 - 0.5 * e, 1.0]);
            let expected = mu * (e * e + 0.25 * e * e) + 0.5 * lam * (0.5 * e).powi(2);
            assert!(
                (psi - expected).abs() < 1e-3 * expected,
                "{m:?}: {psi} vs {expected}"
            );
        }
    }
}
