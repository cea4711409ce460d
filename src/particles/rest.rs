//! The rest data of particle bodies in the simulation's precision: horizons in compressed
//! rows with each bond's reverse, per-bond constants, per-particle inverse shape matrices and
//! the constant weights of the global matrix (He et al. 2017, eq. 4, 8 and 12).

use nalgebra::Matrix3;

use crate::error::{invalid, Result};
use crate::real::Real;

use super::body::Particles;
use super::bond::BondRest;
use super::deformation::{flat_neighbourhood, shape_inverse};
use super::influence::influence;

/// The rest data of a list of particle bodies, concatenated in one particle range.
#[derive(Debug, Clone, Default)]
pub struct ParticleRest<T: Real> {
    /// Bond `b` of particle `i` (`offsets[i] <= b < offsets[i + 1]`) goes to `indices[b]`; its
    /// reverse bond (from `indices[b]` back to `i`) is `reverse[b]`.
    pub offsets: Vec<u32>,
    pub indices: Vec<u32>,
    pub reverse: Vec<u32>,
    pub bonds: Vec<BondRest<T>>,
    /// `K_i^-1 = (sum_j w V_j xi xi^T)^-1` (1/m^2).
    pub shape_inverse: Vec<Matrix3<T>>,
    /// `9 kappa V_i` (J) per particle: the dilatation term's energy is half of it times the
    /// square of the weighted mean bond strain ([`super::bond`]).
    pub dilatation: Vec<T>,
    /// The global matrix `L` (eq. 12, `(M + h^2 L) y = M y* + h^2 b`): per bond its
    /// off-diagonal weight `k_dev + k_iso` of the bond and of its reverse, with the dilatation
    /// term's share (N/m), per particle
    /// the diagonal, the sum over its bonds (N/m). Constant while the bonds are.
    pub coupling: Vec<T>,
    pub stiffness: Vec<T>,
    /// Mass (kg) and collider margin (m) per particle.
    pub mass: Vec<T>,
    pub margin: Vec<T>,
    /// False for a ghost particle: no collider acts on it.
    pub collides: Vec<bool>,
}

impl<T: Real> ParticleRest<T> {
    /// The rest data of `bodies`, in their order. Fails, naming the particle, where a shape
    /// matrix is singular.
    pub fn of_bodies(bodies: &[&Particles]) -> Result<Self> {
        let mut rest = Self {
            offsets: vec![0],
            ..Self::default()
        };
        for body in bodies {
            rest.add(body)?;
        }
        Ok(rest)
    }

    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of particle `i` and their bonds' range.
    #[inline(always)]
    pub fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }

    /// Appends one body's particles and bonds (computed in f64, stored in `T`).
    ///
    /// With a surface correction (the moduli's `bulk_weight` `A`), particle `i` with the
    /// weight sum `A_i = sum_j w V_j` over its bonds gets the factor `g_i = A / A_i` (1 in the
    /// interior, about 2 on a flat face), and each bond's springs are scaled by
    /// `(g_i + g_j) / 2`: under a uniform dilation every particle then stores the bulk's
    /// energy density, so a thin body is not softer than a thick one.
    fn add(&mut self, body: &Particles) -> Result<()> {
        let base = self.len() as u32;
        let bond_base = self.indices.len() as u32;
        let horizons = body.horizons();
        let x = body.reference();
        let moduli = body.moduli();
        let (volume, delta) = (body.volume(), body.horizon());
        let weight = |i: usize, j: u32| influence((x[j as usize] - x[i]).norm(), delta) * volume;
        let weight_sums: Vec<f64> = (0..x.len())
            .map(|i| horizons.of(i).iter().map(|&j| weight(i, j)).sum())
            .collect();
        let factor = |i: usize| moduli.bulk_weight.map_or(1.0, |bulk| bulk / weight_sums[i]);
        // The extra stiffness of the dilatation term in the global matrix (N/m per bond).
        let mut matrix_extra = Vec::new();
        for i in 0..x.len() {
            let neighbors = horizons.of(i);
            let mut shape = Matrix3::<f64>::zeros();
            for &j in neighbors {
                let xi = x[j as usize] - x[i];
                let length = xi.norm();
                let weight = weight(i, j);
                shape += xi * xi.transpose() * weight;
                // V_i V_j w / |xi|^2 (m): times mu or lam (Pa), a stiffness in N/m.
                let k =
                    volume * weight / (length * length) * (0.5 * (factor(i) + factor(j as usize)));
                self.bonds.push(BondRest {
                    xi: xi.map(T::of),
                    length: T::of(length),
                    weight: T::of(weight),
                    k_dev: T::of(2.0 * moduli.mu * k),
                    k_iso: T::of(moduli.lam * k),
                    share: T::of(weight / (weight_sums[i] * length)),
                });
                // The dilatation term's Hessian is the rank-one `9 kappa V_i a a^T` over the
                // bonds' extensions (`a_j = w V_j / (A_i |xi_j|)`); its bond-diagonal part
                // scaled by `A_i / (w V_j)` bounds it from above (Jensen) and equals it
                // under a uniform dilation. A negative `kappa` only softens: nothing added.
                matrix_extra.push(
                    9.0 * moduli.kappa.max(0.0) * volume * weight
                        / (weight_sums[i] * length * length),
                );
                self.indices.push(j + base);
                let back = horizons.of(j as usize).binary_search(&(i as u32));
                let back = back.map_err(|_| invalid!("horizons are not symmetric"))?;
                self.reverse
                    .push(bond_base + horizons.offsets[j as usize] + back as u32);
            }
            self.offsets.push(self.indices.len() as u32);
            let inverse = shape_inverse(&shape)
                .ok_or_else(|| flat_neighbourhood(i, neighbors.len(), delta))?;
            self.shape_inverse.push(inverse.map(T::of));
            self.dilatation.push(T::of(9.0 * moduli.kappa * volume));
            self.mass.push(T::of(body.density() * volume));
            self.margin.push(T::of(body.margin()));
            self.collides.push(!body.is_ghost(i));
        }
        // The global matrix's weights, once every reverse bond is there.
        let first = bond_base as usize;
        for b in first..self.bonds.len() {
            let r = self.reverse[b] as usize;
            let (a, c) = (&self.bonds[b], &self.bonds[r]);
            let extra = matrix_extra[b - first] + matrix_extra[r - first];
            self.coupling
                .push(a.k_dev + a.k_iso + c.k_dev + c.k_iso + T::of(extra));
        }
        for i in base as usize..self.len() {
            let row = self.row(i);
            self.stiffness
                .push(self.coupling[row].iter().fold(T::zero(), |s, &c| s + c));
        }
        Ok(())
    }
}
