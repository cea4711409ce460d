//! Smoothed-particle hydrodynamics (SPH) sums over a particle neighbourhood: the kernels, the
//! density of every particle and its gradient with respect to the positions. Used by the
//! fluids' density constraints (Macklin and Mueller 2013, "Position Based Fluids"; He et al.
//! 2017, section 6) and the granular density (He et al. 2017, eq. 25).
//!
//! Kernels (Mueller, Charypar and Gross 2003; support radius `h` in m, both integrate to 1
//! over the ball of radius `h`, values in 1/m^3):
//! - [`Kernel::Poly6`]: `W(r) = 315 / (64 pi h^9) (h^2 - r^2)^3`, smooth at `r = 0`: the
//!   usual density kernel;
//! - [`Kernel::Spiky`]: `W(r) = 15 / (pi h^6) (h - r)^3`, whose gradient does not vanish as
//!   `r -> 0` (so pressure-like forces keep close particles apart): the kernel of the
//!   redistribution constraint (He et al. 2017, eq. 21) and of position-based fluids'
//!   gradients.
//!
//! Density (kg/m^3): `rho_i = s (m_i W(0) + sum_j m_j W(|y_i - y_j|))`, the self term included,
//! `j` over the CSR neighbour lists (which must hold every `j != i` closer than `h`; farther
//! ones add nothing). Its gradient is the exact derivative of that sum. The scale `s` is 1 for
//! the continuous normalisation, or the **lattice normalisation** of [`Sph::on_lattice`]:
//! `s = 1 / (d^3 sum_{p in d Z^3} W(|p|))`, so that the interior of a simple cubic lattice of
//! spacing `d` and particle mass `m` has exactly the density `m / d^3` (the discrete sum of a
//! kernel only a few spacings wide misses its integral by a few per cent).
//!
//! Every particle's sum runs alone, in its neighbour order: the results are the same for any
//! number of threads.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::lattice::lattice_sum;
use crate::error::{check_param, invalid, Result};
use crate::parallel::GRAIN;
use crate::real::Real;

/// An SPH kernel (see the module's doc for the formulas).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// `315 / (64 pi h^9) (h^2 - r^2)^3`.
    Poly6,
    /// `15 / (pi h^6) (h - r)^3`.
    Spiky,
}

/// A kernel with its support radius and scale: evaluates `s W` and `s grad W`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sph {
    /// The kernel.
    pub kernel: Kernel,
    /// Support radius `h` (m): the kernel vanishes at and beyond it.
    pub radius: f64,
    /// Scale `s` applied to the kernel (1 for the continuous normalisation).
    pub scale: f64,
}

impl Sph {
    /// The kernel with support radius `radius` (m), continuously normalised (`s = 1`).
    /// Errors: a radius that is not finite and positive (with a normal ninth power).
    pub fn new(kernel: Kernel, radius: f64) -> Result<Self> {
        let radius = check_param(
            "the SPH support radius",
            radius,
            |h| h > 0.0 && h.powi(9).is_normal(),
            "a finite length in m with a normal ninth power (about 1e-34 to 1e34 m)",
        )?;
        Ok(Self {
            kernel,
            radius,
            scale: 1.0,
        })
    }

    /// The kernel with support radius `radius` (m), normalised on the simple cubic lattice of
    /// spacing `spacing` (m): `s = 1 / (spacing^3 sum_p W(|p|))` over the lattice points `p`.
    /// Errors: a bad radius or spacing, or a radius above 50 spacings (the sum would be long).
    pub fn on_lattice(kernel: Kernel, radius: f64, spacing: f64) -> Result<Self> {
        let unit = Self::new(kernel, radius)?;
        let spacing = check_param(
            "the lattice spacing",
            spacing,
            |d| d > 0.0 && (d * d * d).is_normal(),
            "a finite length in m with a normal cube",
        )?;
        if radius > 50.0 * spacing {
            return Err(invalid!(
                "the SPH support radius {radius} m is more than 50 lattice spacings ({spacing} m)"
            ));
        }
        let sum = unit.lattice_sum(spacing);
        Ok(Self {
            scale: 1.0 / (spacing.powi(3) * sum),
            ..unit
        })
    }

    /// `sum_p W(|p|)` (1/m^3, unscaled) over the points `p` of the simple cubic lattice of
    /// spacing `spacing` (m), the origin included.
    pub fn lattice_sum(&self, spacing: f64) -> f64 {
        let unit = Self {
            scale: 1.0,
            ..*self
        };
        lattice_sum(self.radius, spacing, |p| unit.value(p.norm()))
    }

    /// `s W(r)` (1/m^3) at the distance `r >= 0` (m).
    #[inline]
    pub fn value<T: Real>(&self, r: T) -> T {
        let h = T::of(self.radius);
        if r >= h {
            return T::zero();
        }
        let pi = T::of(std::f64::consts::PI);
        let s = T::of(self.scale);
        match self.kernel {
            Kernel::Poly6 => {
                let q = h * h - r * r;
                s * T::of(315.0 / 64.0) / (pi * h.powi(9)) * q * q * q
            }
            Kernel::Spiky => {
                let q = h - r;
                s * T::of(15.0) / (pi * h.powi(6)) * q * q * q
            }
        }
    }

    /// `s grad W(d)` (1/m^4), the gradient of the kernel with respect to the separation
    /// `d = y_i - y_j` (m). The spiky kernel's gradient is taken as zero at `d = 0`, where
    /// it has no direction.
    #[inline]
    pub fn gradient<T: Real>(&self, d: &Vector3<T>) -> Vector3<T> {
        let h = T::of(self.radius);
        let r2 = d.norm_squared();
        if r2 >= h * h {
            return Vector3::zeros();
        }
        let pi = T::of(std::f64::consts::PI);
        let s = T::of(self.scale);
        match self.kernel {
            Kernel::Poly6 => {
                let q = h * h - r2;
                d * (-s * T::of(945.0 / 32.0) / (pi * h.powi(9)) * q * q)
            }
            Kernel::Spiky => {
                let r = r2.sqrt();
                if r == T::zero() {
                    return Vector3::zeros();
                }
                let q = h - r;
                d * (-s * T::of(45.0) / (pi * h.powi(6)) * q * q / r)
            }
        }
    }

    /// `s` times the Hessian of the kernel with respect to the separation `d` (1/m^5): for
    /// poly6 `-6 c ((H^2 - r^2)^2 I - 4 (H^2 - r^2) d d^T)`, `c = 315 / (64 pi H^9)`; for spiky
    /// `W'' u u^T + W' / r (I - u u^T)`, `u = d / r`, `W' = -3 c (H - r)^2`,
    /// `W'' = 6 c (H - r)`, `c = 15 / (pi H^6)` (zero at `d = 0`, where it is unbounded).
    #[inline]
    pub fn hessian<T: Real>(&self, d: &Vector3<T>) -> Matrix3<T> {
        let h = T::of(self.radius);
        let r2 = d.norm_squared();
        if r2 >= h * h {
            return Matrix3::zeros();
        }
        let pi = T::of(std::f64::consts::PI);
        let s = T::of(self.scale);
        let outer = d * d.transpose();
        match self.kernel {
            Kernel::Poly6 => {
                let c = s * T::of(315.0 / 64.0) / (pi * h.powi(9));
                let q = h * h - r2;
                (Matrix3::identity() * poly6_slope(h, r2) - outer * (T::of(4.0) * q))
                    * (-T::of(6.0) * c)
            }
            Kernel::Spiky => {
                let r = r2.sqrt();
                if r == T::zero() {
                    return Matrix3::zeros();
                }
                let c = s * T::of(15.0) / (pi * h.powi(6));
                let q = h - r;
                let first = -T::of(3.0) * c * q * q;
                let second = T::of(6.0) * c * q;
                let uu = outer / r2;
                uu * second + (Matrix3::identity() - uu) * (first / r)
            }
        }
    }

    /// Particle `i`'s density (kg/m^3) at the positions `y` (m) with masses `masses` (kg),
    /// the neighbours `indices[offsets[i]..offsets[i + 1]]`.
    #[inline]
    pub fn density<T: Real>(
        &self,
        i: usize,
        y: &[Vector3<T>],
        offsets: &[u32],
        indices: &[u32],
        masses: &[T],
    ) -> T {
        let mut rho = masses[i] * self.value(T::zero());
        for &j in &indices[offsets[i] as usize..offsets[i + 1] as usize] {
            let j = j as usize;
            rho += masses[j] * self.value((y[i] - y[j]).norm());
        }
        rho
    }

    /// Every particle's density (kg/m^3) into `out` (see [`Sph::density`]), in parallel.
    pub fn densities<T: Real>(
        &self,
        y: &[Vector3<T>],
        offsets: &[u32],
        indices: &[u32],
        masses: &[T],
        out: &mut [T],
    ) {
        out.par_iter_mut()
            .with_min_len(GRAIN)
            .enumerate()
            .for_each(|(i, rho)| *rho = self.density(i, y, offsets, indices, masses));
    }

    /// The gradient of particle `i`'s density with respect to the positions (kg/m^4): writes
    /// `d rho_i / d y_j` for each neighbour `j` (in list order) into `out` and returns
    /// `d rho_i / d y_i`, which is minus their sum.
    #[inline]
    pub fn density_gradient<T: Real>(
        &self,
        i: usize,
        y: &[Vector3<T>],
        offsets: &[u32],
        indices: &[u32],
        masses: &[T],
        out: &mut [Vector3<T>],
    ) -> Vector3<T> {
        let mut own = Vector3::zeros();
        let row = &indices[offsets[i] as usize..offsets[i + 1] as usize];
        for (&j, g) in row.iter().zip(out) {
            let j = j as usize;
            let grad = self.gradient(&(y[i] - y[j])) * masses[j];
            own += grad;
            *g = -grad;
        }
        own
    }
}

/// `(H^2 - r^2)^2` (m^4) at the squared distance `r2` (m^2) inside the support radius `h`
/// (m), else 0: the poly6 kernel's `-W'(r) / r` over its constant `945 / (32 pi H^9)`, the
/// shape of its Hessian's isotropic part and the pair weight of the sand's wicking
/// ([`super::wicking`]).
#[inline]
pub(crate) fn poly6_slope<T: Real>(h: T, r2: T) -> T {
    let q = h * h - r2;
    if q > T::zero() {
        q * q
    } else {
        T::zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::find_horizons;
    use crate::test_rng::Rng;

    /// A simple cubic block of `n^3` points, spacing `d` (m), rotated by `angles` (rad about
    /// x, y, z) and shifted by `shift`.
    fn block(n: usize, d: f64, angles: [f64; 3], shift: Vector3<f64>) -> Vec<Vector3<f64>> {
        let rot = nalgebra::Rotation3::from_euler_angles(angles[0], angles[1], angles[2]);
        let mut points = Vec::new();
        for a in 0..n {
            for b in 0..n {
                for c in 0..n {
                    let p = Vector3::new(a as f64, b as f64, c as f64) * d;
                    points.push(rot * p + shift);
                }
            }
        }
        points
    }

    /// Densities of `points` (mass `m` each) with neighbour lists found for `sph.radius`.
    fn densities_of<T: Real>(sph: &Sph, points: &[Vector3<f64>], m: f64) -> Vec<T> {
        let found = find_horizons(points, sph.radius).unwrap();
        let y: Vec<Vector3<T>> = points.iter().map(|p| p.map(T::of)).collect();
        let masses = vec![T::of(m); y.len()];
        let mut out = vec![T::zero(); y.len()];
        sph.densities(&y, &found.offsets, &found.indices, &masses, &mut out);
        out
    }

    /// The points at least `margin` (m) inside the block of side `(n - 1) d` around `centre`.
    fn interior(points: &[Vector3<f64>], centre: Vector3<f64>, half: f64) -> Vec<usize> {
        (0..points.len())
            .filter(|&i| (points[i] - centre).amax() < half)
            .collect()
    }

    /// Both kernels integrate to 1: a Riemann sum on a lattice 50 points per radius wide
    /// (an error of order `(d / h)^2` at most; measured below 1e-4).
    #[test]
    fn kernels_integrate_to_one() {
        for kernel in [Kernel::Poly6, Kernel::Spiky] {
            let h = 0.03;
            let d = h / 50.0;
            let sph = Sph::new(kernel, h).unwrap();
            // A lattice offset by half a spacing, so that the spiky cusp at 0 is not sampled.
            let reach = 51i64;
            let mut sum = 0.0;
            for a in -reach..reach {
                for b in -reach..reach {
                    for c in -reach..reach {
                        let p =
                            (Vector3::new(a as f64, b as f64, c as f64) + Vector3::repeat(0.5)) * d;
                        sum += sph.value(p.norm());
                    }
                }
            }
            let integral = sum * d.powi(3);
            assert!((integral - 1.0).abs() < 1e-3, "{kernel:?}: {integral}");
        }
    }

    /// The lattice-normalised density of the interior of a cubic block is `m / d^3` to
    /// round-off (1e-12 in f64, 1e-5 in f32), at any support of 1.5 to 3 spacings; the
    /// continuously normalised one is off by the kernel's discretisation error, stated as
    /// below 8 % for poly6 and 80 % for spiky (whose self term `15 / (pi h^3)` outweighs its
    /// few neighbours at 1.5 spacings) at these supports. The same scale holds on a rotated and shifted block to
    /// 2 % (a lattice's sum depends little on its orientation at 2.5 spacings).
    #[test]
    fn lattice_density_is_mass_over_volume() {
        let (d, m): (f64, f64) = (0.01, 1000.0 * 1e-6);
        let exact = m / d.powi(3);
        let n = 12;
        let centre = Vector3::repeat(0.5 * (n - 1) as f64 * d);
        for kernel in [Kernel::Poly6, Kernel::Spiky] {
            for support in [1.5, 2.0, 2.5, 3.0] {
                let h = support * d;
                let points = block(n, d, [0.0; 3], Vector3::zeros());
                let inside = interior(&points, centre, 0.5 * (n - 1) as f64 * d - h);
                assert!(!inside.is_empty());
                let sph = Sph::on_lattice(kernel, h, d).unwrap();
                let rho64 = densities_of::<f64>(&sph, &points, m);
                let rho32 = densities_of::<f32>(&sph, &points, m);
                let plain = densities_of::<f64>(&Sph::new(kernel, h).unwrap(), &points, m);
                for &i in &inside {
                    assert!((rho64[i] / exact - 1.0).abs() < 1e-12, "{}", rho64[i]);
                    assert!((rho32[i] as f64 / exact - 1.0).abs() < 1e-5, "{}", rho32[i]);
                    let off = (plain[i] / exact - 1.0).abs();
                    let bound = if kernel == Kernel::Poly6 { 0.08 } else { 0.8 };
                    assert!(off < bound, "{kernel:?} at {support}: {off}");
                }
            }
            let h = 2.5 * d;
            let sph = Sph::on_lattice(kernel, h, d).unwrap();
            let shift = Vector3::new(0.3, -0.2, 0.1);
            let turned = block(n, d, [0.3, -0.5, 0.7], shift);
            let centre = nalgebra::Rotation3::from_euler_angles(0.3, -0.5, 0.7) * centre + shift;
            let rho = densities_of::<f64>(&sph, &turned, m);
            let inside = interior(&turned, centre, 0.5 * (n - 1) as f64 * d / 3f64.sqrt() - h);
            assert!(!inside.is_empty());
            for &i in &inside {
                assert!(
                    (rho[i] / exact - 1.0).abs() < 0.02,
                    "{kernel:?}: {}",
                    rho[i]
                );
            }
        }
    }

    /// The density gradient matches central differences of the density (relative 1e-6) on a
    /// jittered block with unequal masses, for every particle and each of its neighbours.
    #[test]
    fn density_gradient_matches_finite_differences() {
        let d = 0.01;
        let mut rng = Rng::new(7);
        let points: Vec<Vector3<f64>> = block(5, d, [0.0; 3], Vector3::zeros())
            .into_iter()
            .map(|p| p + rng.vector() * 0.3 * d)
            .collect();
        let masses: Vec<f64> = (0..points.len())
            .map(|_| 1e-3 * (1.0 + 0.5 * rng.uniform()))
            .collect();
        for kernel in [Kernel::Poly6, Kernel::Spiky] {
            let sph = Sph::on_lattice(kernel, 2.2 * d, d).unwrap();
            let found = find_horizons(&points, sph.radius).unwrap();
            let (offsets, indices) = (&found.offsets, &found.indices);
            let mut grads = vec![Vector3::zeros(); indices.len()];
            let step = 1e-7;
            let mut worst: f64 = 0.0;
            for i in 0..points.len() {
                let row = offsets[i] as usize..offsets[i + 1] as usize;
                let own = sph.density_gradient(
                    i,
                    &points,
                    offsets,
                    indices,
                    &masses,
                    &mut grads[row.clone()],
                );
                let wrt: Vec<(usize, Vector3<f64>)> = std::iter::once((i, own))
                    .chain(row.map(|b| (indices[b] as usize, grads[b])))
                    .collect();
                let scale = own.norm().max(1.0);
                for (k, g) in wrt {
                    for c in 0..3 {
                        let mut y = points.clone();
                        y[k][c] += step;
                        let up = sph.density(i, &y, offsets, indices, &masses);
                        y[k][c] -= 2.0 * step;
                        let down = sph.density(i, &y, offsets, indices, &masses);
                        let fd = (up - down) / (2.0 * step);
                        worst = worst.max((fd - g[c]).abs() / scale);
                    }
                }
            }
            assert!(worst < 1e-6, "{kernel:?}: {worst}");
        }
    }

    /// The kernel's Hessian matches central differences of its gradient (relative 1e-6) at
    /// separations across the support, for both kernels.
    #[test]
    fn hessian_matches_finite_differences() {
        let mut rng = Rng::new(11);
        for kernel in [Kernel::Poly6, Kernel::Spiky] {
            let sph = Sph::new(kernel, 0.02).unwrap();
            for _ in 0..50 {
                let d = rng.vector() * 0.011;
                let hess = sph.hessian(&d);
                let step = 1e-8;
                for c in 0..3 {
                    let mut e = Vector3::zeros();
                    e[c] = step;
                    let fd = (sph.gradient(&(d + e)) - sph.gradient(&(d - e))) / (2.0 * step);
                    let err = (fd - hess.column(c)).norm() / hess.norm();
                    assert!(err < 1e-6, "{kernel:?} at {d:?}: {err}");
                }
            }
        }
    }

    /// The densities are bit-identical on 1 and 2 threads.
    #[test]
    fn densities_do_not_depend_on_threads() {
        let d = 0.01;
        let mut rng = Rng::new(3);
        let points: Vec<Vector3<f64>> = block(14, d, [0.0; 3], Vector3::zeros())
            .into_iter()
            .map(|p| p + rng.vector() * 0.2 * d)
            .collect();
        let sph = Sph::on_lattice(Kernel::Poly6, 2.0 * d, d).unwrap();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| densities_of::<f64>(&sph, &points, 1e-3))
        };
        let (one, two) = (run(1), run(2));
        assert!(one
            .iter()
            .zip(&two)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
    }

    /// Bad radii and spacings are refused, naming the value.
    #[test]
    fn bad_parameters_are_refused() {
        for h in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let err = Sph::new(Kernel::Poly6, h).unwrap_err().to_string();
            assert!(err.contains("radius"), "{err}");
        }
        let err = Sph::on_lattice(Kernel::Spiky, 0.02, 0.0)
            .unwrap_err()
            .to_string();
        assert!(err.contains("spacing"), "{err}");
        let err = Sph::on_lattice(Kernel::Spiky, 1.0, 0.01)
            .unwrap_err()
            .to_string();
        assert!(err.contains("50 lattice spacings"), "{err}");
    }
}
