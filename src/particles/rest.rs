//! The rest data of particle bodies in the simulation's precision: horizons in compressed
//! rows with each bond's reverse, per-bond constants, per-particle inverse shape matrices and
//! the constant weights of the global matrix (He et al. 2017, eq. 4, 8 and 12).

use nalgebra::{Matrix3, Vector3};

use crate::error::{invalid, Result};
use crate::real::Real;

use super::body::Particles;
use super::bond::BondRest;
use super::calibration::Moduli;
use super::cone::Cone;
use super::deformation::{flat_neighbourhood, shape_inverse};
use super::granular::Granular;
use super::influence::influence;
use super::plasticity::PlasticLaw;
use super::rest_bonds::RestBonds;
use super::surface::{axis_factors, bond_factor, strain_shares};

/// What the rest data of a body needs besides its bonds.
#[derive(Debug, Clone, Copy)]
pub(crate) struct RestConstants {
    pub moduli: Moduli,
    /// Particle volume (m^3), horizon (m), density (kg/m^3) and collider margin (m).
    pub volume: f64,
    pub delta: f64,
    pub density: f64,
    pub margin: f64,
    /// The body's particles that are not ghosts (`0..num_real`; ghosts, which no collider
    /// acts on, come after them).
    pub num_real: usize,
    /// Whether the body is plastic (its neighbourhoods may degenerate: see
    /// [`ParticleRest::add_bonds`]).
    pub plastic: bool,
    /// The granular material, whose stiffness follows each particle's density.
    pub granular: Option<Granular>,
    /// Whether the body has fluid and solid particles ([`Particles::fluid_mask`]): its fluid
    /// particles have no bonds and `K^-1 = 0`.
    pub mixed: bool,
}

impl RestConstants {
    pub fn of(body: &Particles) -> Self {
        Self {
            moduli: body.moduli(),
            volume: body.volume(),
            delta: body.horizon(),
            density: body.density(),
            margin: body.margin(),
            num_real: body.num_real(),
            plastic: body.plasticity().is_some(),
            granular: body.granular().copied(),
            mixed: body.fluid_mask().is_some(),
        }
    }
}

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
    /// Per particle the cone of its return within the local step (a granular body's,
    /// [`super::cone`]; `None` for other particles), or empty when no body has one.
    pub cones: Vec<Option<Cone<T>>>,
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

    /// Replaces the rest data by that of bodies given by their bonds and constants, in this
    /// order, in place: the vectors keep their allocations (a plastic family's rest data is
    /// rebuilt every step; building it beside the old one doubled its memory at the peak).
    /// `lam` per particle (Pa) replaces the moduli's for a granular body. On an error the
    /// rest data is partly filled and must not be used.
    pub(crate) fn refill(
        &mut self,
        bodies: &[(&RestBonds, RestConstants, Option<&[f64]>)],
    ) -> Result<()> {
        self.offsets.clear();
        self.offsets.push(0);
        self.indices.clear();
        self.reverse.clear();
        self.bonds.clear();
        self.shape_inverse.clear();
        self.dilatation.clear();
        self.coupling.clear();
        self.stiffness.clear();
        self.mass.clear();
        self.margin.clear();
        self.collides.clear();
        self.cones.clear();
        for (bonds, constants, lam) in bodies {
            self.add_bonds(bonds, constants, *lam)?;
        }
        Ok(())
    }

    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The Jacobi diagonal `D_i = m_i + h^2 L_ii` (kg) of particle `i` (eq. 12), `h2` the
    /// squared time step (s^2).
    #[inline(always)]
    pub fn diagonal(&self, i: usize, h2: T) -> T {
        self.mass[i] + h2 * self.stiffness[i]
    }

    /// The neighbours of particle `i` and their bonds' range.
    #[inline(always)]
    pub fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }

    /// Appends one body's particles and bonds (computed in f64, stored in `T`): its
    /// current reference bonds ([`Particles::rest_bonds`]) or those of its reference
    /// positions.
    fn add(&mut self, body: &Particles) -> Result<()> {
        let owned;
        let bonds = match body.rest_bonds() {
            Some(bonds) => bonds,
            None => {
                owned = RestBonds::from_reference(body.reference(), body.horizons());
                &owned
            }
        };
        let constants = RestConstants::of(body);
        let lam = constants
            .granular
            .map(|g| {
                let (y, delta, volume) = (body.positions(), constants.delta, constants.volume);
                match body.wetted() {
                    None => g.particle_stiffness(bonds, y, delta, volume),
                    Some(theta) => g.wet_particle_stiffness(bonds, y, delta, volume, theta),
                }
            })
            .transpose()?;
        let base = self.len();
        self.add_bonds(bonds, &constants, lam.as_deref())?;
        // Every plastic body returns within the local step ([`super::cone`]).
        if let Some(law) = PlasticLaw::of(body) {
            let cohesion = constants
                .granular
                .zip(body.wetted())
                .map(|(g, theta)| g.cohesions(theta));
            self.set_cones(base, &law, bonds, cohesion.as_deref());
        }
        Ok(())
    }

    /// The cones of the particles `base..base + n` (one body's: its law `law`, its `n`
    /// particles' plastic strains and volume ratios from its `bonds` and, for wetted sand,
    /// cohesions `cohesion` in Pa): the kernel returns them within the local step
    /// ([`super::cone`]).
    pub(crate) fn set_cones(
        &mut self,
        base: usize,
        law: &PlasticLaw,
        bonds: &RestBonds,
        cohesion: Option<&[f64]>,
    ) {
        self.cones.resize(self.len(), None);
        let particles = bonds.plastic_strain.iter().zip(&bonds.volume);
        for (k, (cone, (&eps, &volume))) in self.cones[base..].iter_mut().zip(particles).enumerate()
        {
            let c = cohesion.map_or(law.law.cohesion, |c| c[k]);
            let f = law.anchored_cone(c, eps, volume);
            *cone = Some(Cone {
                a: T::of(f.a),
                b: T::of(f.b),
                bulk9: T::of(f.bulk9),
                shear15: T::of(f.shear15),
                volume: f.volume.map(T::of),
                relaxation_time: T::of(f.relaxation_time),
                step: T::of(f.step),
            });
        }
    }

    /// Readies every cone for a step of `h` (s): a rate-dependent return relaxes over it
    /// ([`super::cone`]).
    pub(crate) fn set_step(&mut self, h: f64) {
        for cone in self.cones.iter_mut().flatten() {
            cone.step = T::of(h);
        }
    }

    /// Appends the particles of `bonds` with the body constants `c`.
    ///
    /// With a surface correction (the moduli's `bulk_moment`), each bond's springs are
    /// scaled by the factor of [`super::surface`] (1 in the interior, above 1 near a free
    /// surface, by direction): under a stretch along a lattice axis every particle then stores
    /// the bulk's energy density, so a thin body is neither softer nor stiffer than a thick
    /// one. Weights and springs
    /// come from the bonds' `born` lengths, so they, and the global matrix, stay as they are
    /// while a plastic return moves the vectors `X` (but a flowing body's bonds are born anew
    /// at each step's end: [`super::rest_bonds`]). A plastic body's
    /// bonds turn with each return, which would change direction-based factors (and the global
    /// matrix) at every step: its bonds are scaled by `(g_i + g_j) / 2` with `g_i = A / A_i`,
    /// the bulk lattice's weight sum over the particle's own, which depends on lengths only
    /// (exact under a uniform dilation, too stiff along a free surface: [`super::surface`]).
    /// So are a shell's or rod's, whose ghost layers are calibrated by their second moment
    /// (`super::thin`), not by direction factors.
    ///
    /// A singular shape matrix fails, naming the particle, unless `c.plastic`: a plastic
    /// body's particle that has lost its three-dimensional neighbourhood gets `K_i^-1 = 0`,
    /// so `F_i = 0` and its deviatoric springs pull along the bonds as the isotropic ones do.
    ///
    /// `lam`, per particle (Pa), replaces the moduli's `lam` for a granular body
    /// ([`super::granular`]): a bond's isotropic spring takes the mean of its two particles'.
    pub(crate) fn add_bonds(
        &mut self,
        bonds: &RestBonds,
        c: &RestConstants,
        lam: Option<&[f64]>,
    ) -> Result<()> {
        let base = self.len() as u32;
        let bond_base = self.indices.len() as u32;
        // Exact sizes: pushing would leave up to half of each vector's allocation unused.
        let (n, count) = (bonds.len(), bonds.indices.len());
        self.offsets.reserve_exact(n);
        self.indices.reserve_exact(count);
        self.reverse.reserve_exact(count);
        self.bonds.reserve_exact(count);
        self.coupling.reserve_exact(count);
        self.shape_inverse.reserve_exact(n);
        self.dilatation.reserve_exact(n);
        self.stiffness.reserve_exact(n);
        self.mass.reserve_exact(n);
        self.margin.reserve_exact(n);
        self.collides.reserve_exact(n);
        let moduli = c.moduli;
        let (volume, delta) = (c.volume, c.delta);
        let weight = |b: usize| influence(bonds.born[b], delta) * volume;
        let weight_sums: Vec<f64> = (0..bonds.len())
            .map(|i| bonds.row(i).map(weight).sum())
            .collect();
        // Thin bodies (shells and rods: ghost particles after the real ones) keep the
        // isotropic factors too: their few layers leave the direction moments along the
        // thickness far from the bulk's.
        let thin = c.num_real < bonds.len();
        let axes = moduli
            .bulk_moment
            .filter(|_| !c.plastic && !thin)
            .map(|bulk| {
                axis_factors(bonds.len(), bulk, |i| {
                    bonds.row(i).map(move |b| (bonds.xi[b], weight(b)))
                })
            });
        let bulk_weight = moduli.bulk_weight;
        let factor = |i: usize, j: usize, xi: &Vector3<f64>| match (&axes, bulk_weight) {
            (Some(g), _) => bond_factor(xi, &g[i], &g[j]),
            (None, Some(bulk)) if c.plastic || thin => {
                // A particle whose bonds all have weight 0 (new neighbours mapped beyond the
                // horizon by eq. 20) adds nothing, instead of an infinite factor.
                let g = |w: f64| if w > 0.0 { bulk / w } else { 0.0 };
                0.5 * (g(weight_sums[i]) + g(weight_sums[j]))
            }
            _ => 1.0,
        };
        // The corrected shares of the mean strain ([`super::surface`]), with the bodies'
        // direction-based factors.
        let shares = axes.as_ref().map(|_| {
            let mut all = Vec::with_capacity(bonds.indices.len());
            let (mut row, mut out) = (Vec::new(), Vec::new());
            for i in 0..bonds.len() {
                row.clear();
                row.extend(bonds.row(i).map(|b| (bonds.xi[b], weight(b))));
                strain_shares(&row, &mut out);
                all.extend_from_slice(&out);
            }
            all
        });
        // The extra stiffness of the dilatation term in the global matrix (N/m per bond).
        let mut matrix_extra = Vec::with_capacity(count);
        for (i, &weight_sum) in weight_sums.iter().enumerate() {
            let abs_sum: f64 = shares.as_ref().map_or(1.0, |a| {
                bonds.row(i).map(|b| a[b].abs() * bonds.xi[b].norm()).sum()
            });
            let neighbors = bonds.of(i);
            let mut shape = Matrix3::<f64>::zeros();
            for b in bonds.row(i) {
                let j = bonds.indices[b];
                let xi = bonds.xi[b];
                let (length, born) = (xi.norm(), bonds.born[b]);
                let weight = weight(b);
                shape += xi * xi.transpose() * weight;
                // V_i V_j w / |xi|^2 (m): times mu or lam (Pa), a stiffness in N/m.
                let k = volume * weight / (born * born) * factor(i, j as usize, &xi);
                // A particle without weighted bonds has no mean strain: its shares are 0.
                let share = shares.as_ref().map_or(
                    if weight_sum > 0.0 {
                        weight / (weight_sum * length)
                    } else {
                        0.0
                    },
                    |a| a[b],
                );
                self.bonds.push(BondRest {
                    xi: xi.map(T::of),
                    length: T::of(length),
                    weight: T::of(weight),
                    k_dev: T::of(2.0 * moduli.mu * k),
                    k_iso: T::of(lam.map_or(moduli.lam, |l| 0.5 * (l[i] + l[j as usize])) * k),
                    share: T::of(share),
                });
                // The dilatation term's Hessian is the rank-one `9 kappa V_i a a^T` over the
                // bonds' extensions; by Cauchy-Schwarz `(sum_j a_j e_j)^2 <= (sum_k |a_k|
                // |xi_k|) sum_j |a_j| e_j^2 / |xi_j|`, so the bond-diagonal
                // `9 kappa V_i (sum_k |a_k| |xi_k|) |a_j| / |xi_j|` bounds it from above and
                // equals it under a uniform dilation (with the uncorrected shares
                // `a_j = w V_j / (A_i |xi_j|)`, `sum_k a_k |xi_k| = 1`; lengths at birth there,
                // so that a plastic return leaves it as it is). A negative `kappa` only
                // softens: nothing added.
                let kappa = moduli.kappa.max(0.0);
                matrix_extra.push(match &shares {
                    Some(_) => 9.0 * kappa * volume * abs_sum * share.abs() / length,
                    None if weight_sum > 0.0 => {
                        9.0 * kappa * volume * weight / (weight_sum * born * born)
                    }
                    None => 0.0,
                });
                self.indices.push(j + base);
                let back = bonds.of(j as usize).binary_search(&(i as u32));
                let back = back.map_err(|_| invalid!("horizons are not symmetric"))?;
                self.reverse
                    .push(bond_base + bonds.offsets[j as usize] + back as u32);
            }
            self.offsets.push(self.indices.len() as u32);
            let inverse = match shape_inverse(&shape) {
                Some(inverse) => inverse,
                None if c.plastic || (c.mixed && neighbors.is_empty()) => Matrix3::zeros(),
                None => return Err(flat_neighbourhood(i, neighbors.len(), delta)),
            };
            self.shape_inverse.push(inverse.map(T::of));
            self.dilatation.push(T::of(9.0 * moduli.kappa * volume));
            self.mass.push(T::of(c.density * volume));
            self.margin.push(T::of(c.margin));
            self.collides.push(i < c.num_real);
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
