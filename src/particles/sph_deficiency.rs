//! The SPH density of a particle corrected for the neighbours it misses at a free surface
//! (beyond the paper; the fluids' density constraints, [`crate::solve::particles`]).
//!
//! **Why.** At a free surface the SPH sum `rho_i` ([`super::sph`]) misses the neighbours
//! outside the liquid: on the flat top of a rest lattice (spiky kernel, support 2.2 spacings)
//! it is 0.85 `rho0`. A density constraint on `rho_i` then holds nothing at the surface until
//! a surface particle has sunk into the hollows of the layer below (a resting column's top
//! layer sank by half a spacing), and a two-sided constraint there would pull it in.
//!
//! **The correction.** The missing neighbours leave the neighbourhood lopsided: the first
//! moment `M_i = sum_j m_j W(|y_i - y_j|) (y_j - y_i)` (kg/m^2) points into the liquid, and
//! it vanishes by symmetry inside a regular liquid. The corrected density is
//!
//! `rho~_i = rho_i + k |M_i|^2`, `k = (rho_full - rho_top) / |M_top|^2` (m/kg),
//!
//! with `rho_full`, `rho_top` and `M_top` the density and moment of an interior and of a
//! flat-top particle of the rest lattice (so the top layer of a rest lattice has exactly
//! `rho_full`: `k` is found from lattice sums, [`Deficiency::on_lattice`]; as `rho` scales with
//! the particle mass `m` and `|M|^2` with `m^2`, `k = kappa / m_i` with `kappa` in m, so one
//! calibration serves every mass). Quadratic in `M`: it is smooth
//! where `M = 0`, it adds the deficiencies of an edge's two faces (orthogonal moments), and the
//! moment noise of a disordered interior (a few per cent of `M_top`) biases `rho~` by its
//! square only (a tenth of a per cent).
//!
//! **Gradient** (exact, as [`super::sph::Sph::density_gradient`]): with `d = y_i - y_j`,
//! `W = W(|d|)`, `g = grad W(d)`: `d M_i / d y_j = m_j (W I + d g^T)` and so
//! `d rho~_i / d y_j = m_j (-g + 2 k (W M_i + (M_i . d) g))`, and `d rho~_i / d y_i` is minus
//! their sum.

use nalgebra::Vector3;

use crate::real::Real;

use super::sph::Sph;

/// The free-surface correction of a kernel's densities (see the module's doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deficiency {
    /// `kappa = k m` (m): the correction of a particle of mass `m_i` is `kappa / m_i |M_i|^2`.
    pub kappa: f64,
}

impl Deficiency {
    /// The correction calibrated on the flat top of the simple cubic lattice of spacing
    /// `spacing` (m) and particle mass `mass` (kg) for the kernel `sph`: `k` such that a
    /// top-layer particle's `rho~` equals an interior particle's `rho`.
    pub fn on_lattice(sph: &Sph, spacing: f64, mass: f64) -> Self {
        let reach = (sph.radius / spacing).ceil() as i64;
        let (mut full, mut top) = (0.0, 0.0);
        let mut moment = Vector3::zeros();
        for a in -reach..=reach {
            for b in -reach..=reach {
                for c in -reach..=reach {
                    let p = Vector3::new(a as f64, b as f64, c as f64) * spacing;
                    let w = mass * sph.value(p.norm());
                    full += w;
                    if c <= 0 {
                        top += w;
                        moment += p * w;
                    }
                }
            }
        }
        Self {
            kappa: (full - top) / moment.norm_squared() * mass,
        }
    }

    /// `k` (m/kg) of a particle of mass `mass` (kg).
    #[inline]
    fn k<T: Real>(&self, mass: T) -> T {
        T::of(self.kappa) / mass
    }

    /// Particle `i`'s moment `M_i` (kg/m^2) at the positions `y` (m), masses `masses` (kg),
    /// over the neighbours `indices[offsets[i]..offsets[i + 1]]`.
    pub fn moment<T: Real>(
        &self,
        sph: &Sph,
        i: usize,
        y: &[Vector3<T>],
        (offsets, indices): (&[u32], &[u32]),
        masses: &[T],
    ) -> Vector3<T> {
        let mut m = Vector3::zeros();
        for &j in &indices[offsets[i] as usize..offsets[i + 1] as usize] {
            let j = j as usize;
            let d = y[j] - y[i];
            m += d * (masses[j] * sph.value(d.norm()));
        }
        m
    }

    /// `rho~_i` (kg/m^3) from the plain SPH density `rho` (kg/m^3), the moment `m`
    /// ([`Self::moment`]) and the particle's mass `mass` (kg).
    #[inline]
    pub fn corrected<T: Real>(&self, rho: T, m: &Vector3<T>, mass: T) -> T {
        rho + self.k(mass) * m.norm_squared()
    }

    /// The gradient of `rho~_i` (kg/m^4): writes `d rho~_i / d y_j` for each neighbour `j`
    /// (in list order) into `out` and returns `d rho~_i / d y_i`; `m` is `M_i`.
    #[allow(clippy::too_many_arguments)]
    pub fn gradient<T: Real>(
        &self,
        sph: &Sph,
        i: usize,
        y: &[Vector3<T>],
        (offsets, indices): (&[u32], &[u32]),
        masses: &[T],
        m: &Vector3<T>,
        out: &mut [Vector3<T>],
    ) -> Vector3<T> {
        let two_k = T::of(2.0) * self.k(masses[i]);
        let mut own = Vector3::zeros();
        let row = &indices[offsets[i] as usize..offsets[i + 1] as usize];
        for (&j, out) in row.iter().zip(out) {
            let j = j as usize;
            let d = y[i] - y[j];
            let g = sph.gradient(&d);
            let w = sph.value(d.norm());
            let grad = (-g + (m * w + g * m.dot(&d)) * two_k) * masses[j];
            own -= grad;
            *out = grad;
        }
        own
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::find_horizons;
    use crate::particles::sph::Kernel;
    use crate::test_rng::Rng;

    /// A block of `n x n x layers` lattice points, spacing `d` (m), jittered by `jitter` d.
    fn block(n: usize, layers: usize, d: f64, jitter: f64) -> Vec<Vector3<f64>> {
        let mut rng = Rng::new(3);
        let mut points = Vec::new();
        for a in 0..n {
            for b in 0..n {
                for c in 0..layers {
                    let p = Vector3::new(a as f64, b as f64, c as f64) * d;
                    points.push(p + rng.vector() * jitter * d);
                }
            }
        }
        points
    }

    fn corrected(
        def: &Deficiency,
        sph: &Sph,
        y: &[Vector3<f64>],
        csr: (&[u32], &[u32]),
        masses: &[f64],
    ) -> Vec<f64> {
        (0..y.len())
            .map(|i| {
                let rho = sph.density(i, y, csr.0, csr.1, masses);
                def.corrected(rho, &def.moment(sph, i, y, csr, masses), masses[i])
            })
            .collect()
    }

    /// On a 9 x 9 x 7 rest lattice the corrected density of the top layer's middle (away from
    /// the sides) equals the interior's `m / d^3` to 1e-12, where the plain sum is 15 % short;
    /// the interior (M = 0) is not changed; the second layer is within 0.1 %.
    #[test]
    fn the_top_of_a_rest_lattice_has_the_rest_density() {
        let (d, m) = (0.01, 1e-3);
        let sph = Sph::on_lattice(Kernel::Spiky, 2.2 * d, d).unwrap();
        let def = Deficiency::on_lattice(&sph, d, m);
        let y = block(9, 7, d, 0.0);
        let found = find_horizons(&y, sph.radius).unwrap();
        let csr = (&found.offsets[..], &found.indices[..]);
        let masses = vec![m; y.len()];
        let rho = corrected(&def, &sph, &y, csr, &masses);
        let exact = m / d.powi(3);
        let middle = |p: &Vector3<f64>| {
            (3.0..=5.0).contains(&(p.x / d).round()) && (3.0..=5.0).contains(&(p.y / d).round())
        };
        for (i, p) in y.iter().enumerate().filter(|(_, p)| middle(p)) {
            let layer = (p.z / d).round() as i64;
            let plain = sph.density(i, &y, csr.0, csr.1, &masses);
            match layer {
                6 => {
                    assert!((rho[i] / exact - 1.0).abs() < 1e-12, "{}", rho[i]);
                    assert!(plain / exact < 0.86, "{plain}");
                }
                5 => assert!((rho[i] / exact - 1.0).abs() < 1e-3, "{}", rho[i]),
                3 => assert!((rho[i] / exact - 1.0).abs() < 1e-12, "{}", rho[i]),
                _ => {}
            }
        }
    }

    /// The gradient matches central differences of `rho~` (relative 1e-6 of the largest
    /// entry) on a jittered block with unequal masses, for every particle and neighbour.
    #[test]
    fn the_gradient_matches_finite_differences() {
        let (d, m) = (0.01, 1e-3);
        let sph = Sph::on_lattice(Kernel::Spiky, 2.2 * d, d).unwrap();
        let def = Deficiency::on_lattice(&sph, d, m);
        let y = block(4, 4, d, 0.15);
        let found = find_horizons(&y, sph.radius * 1.05).unwrap();
        let csr = (&found.offsets[..], &found.indices[..]);
        let mut rng = Rng::new(8);
        let masses: Vec<f64> = (0..y.len())
            .map(|_| m * (1.0 + 0.2 * rng.vector().x))
            .collect();
        let eps = 1e-7 * d;
        for i in 0..y.len() {
            let row = &csr.1[csr.0[i] as usize..csr.0[i + 1] as usize];
            let mut out = vec![Vector3::zeros(); row.len()];
            let mi = def.moment(&sph, i, &y, csr, &masses);
            let own = def.gradient(&sph, i, &y, csr, &masses, &mi, &mut out);
            let at = |z: &[Vector3<f64>]| {
                let rho = sph.density(i, z, csr.0, csr.1, &masses);
                def.corrected(rho, &def.moment(&sph, i, z, csr, &masses), masses[i])
            };
            let scale = own
                .norm()
                .max(out.iter().map(|g| g.norm()).fold(0.0, f64::max));
            for (k, analytic) in row.iter().map(|&j| j as usize).zip(&out).chain([(i, &own)]) {
                for a in 0..3 {
                    let (mut plus, mut minus) = (y.clone(), y.clone());
                    plus[k][a] += eps;
                    minus[k][a] -= eps;
                    let numeric = (at(&plus) - at(&minus)) / (2.0 * eps);
                    assert!(
                        (numeric - analytic[a]).abs() < 1e-6 * scale,
                        "{i} by {k}.{a}: {numeric} against {}",
                        analytic[a]
                    );
                }
            }
        }
    }
}
