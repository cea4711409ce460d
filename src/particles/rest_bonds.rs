//! The reference bonds of a particle body when they can change: every particle's neighbours
//! in compressed rows, each bond's reference vector `X<xi>` and the length its weight was set
//! at, and each particle's accumulated plastic strain (He et al. 2017, sections 5 and eq. 20).
//!
//! An elastic body's bonds are `x_j - x_i` of its reference positions for ever, and it stores
//! none of this. A plastic body's return (eq. 18-19, [`super::plasticity`]) moves the vectors
//! `X`, and its neighbour rebuild ([`super::neighbour_rebuild`]) adds and drops bonds: the
//! body keeps the result, so a new solver goes on from the dents the last one left.
//!
//! **What a bond keeps from its birth.** A bond's influence weight `w(|xi|) V_j` and its
//! spring constants (`V_i V_j w / |xi|^2` times `mu`, `lam`: [`super::bond`]) are set from
//! its reference length when it forms (`born`) and kept while the return moves `X`: the
//! global matrix of eq. 12 then stays constant until the neighbours change, so the direct
//! solver refactors only then. For an elastic body `born = |X|` and nothing differs. A body
//! whose return keeps the rest volume (a cone without friction: a flow) has its bonds born
//! again at `|X|` after every step's returns and rebuild
//! ([`super::plasticity::PlasticLaw::reanchor`]): its flow moves the reference far from the
//! lengths its bonds were born at.

use nalgebra::Vector3;

use crate::error::{invalid, Result};
use crate::geometry::Horizons;

/// The volume ratios [`RestBonds::volume`] a particle's reference bonds may be given
/// (dimensionless): `MIN_STRETCH^3` to its inverse, the bounds the neighbour rebuild's inverse
/// map puts on a neighbourhood's stretches ([`super::neighbour_rebuild::MIN_STRETCH`], 0.1
/// in each direction). A ratio beyond them says the reference bonds span almost no volume
/// (or their neighbourhood is nearly flat at the positions), where `det F_i` measures that
/// flatness rather than the particle's volume.
pub const VOLUME_RATIOS: (f64, f64) = (1e-3, 1e3);

/// A body's current reference bonds (see the module's doc).
#[derive(Debug, PartialEq)]
pub struct RestBonds {
    /// Bond `b` of particle `i` (`offsets[i] <= b < offsets[i + 1]`) goes to `indices[b]`,
    /// the neighbours of each particle in increasing order (so the bonds are symmetric:
    /// `j` is a neighbour of `i` exactly when `i` is one of `j`).
    pub offsets: Vec<u32>,
    pub indices: Vec<u32>,
    /// Per bond its reference vector `X<xi>` (m).
    pub xi: Vec<Vector3<f64>>,
    /// Per bond the reference length (m) its weight and springs were set at.
    pub born: Vec<f64>,
    /// Per particle the accumulated plastic strain (dimensionless; the weighted RMS of the
    /// bond strains each return took away), which hardening raises the cohesion with.
    pub plastic_strain: Vec<f64>,
    /// Per particle the volume its reference bonds span over its rest volume,
    /// `R_i = J_i / det F_i` (dimensionless; 1 for the bonds of the reference positions):
    /// `J_i` the particle's volume over its rest volume, carried from step to step, and `F_i`
    /// its deformation gradient from these bonds. A return that keeps the rest volume
    /// ([`super::cone`]) reads `J_i = R_i det F_i` from it.
    pub volume: Vec<f64>,
}

/// `clone_from` copies into the vectors at hand (the solver writes a plastic body's bonds
/// back every step: a fresh copy each time left the old one to the allocator at the peak).
impl Clone for RestBonds {
    fn clone(&self) -> Self {
        Self {
            offsets: self.offsets.clone(),
            indices: self.indices.clone(),
            xi: self.xi.clone(),
            born: self.born.clone(),
            plastic_strain: self.plastic_strain.clone(),
            volume: self.volume.clone(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        self.offsets.clone_from(&source.offsets);
        self.indices.clone_from(&source.indices);
        self.xi.clone_from(&source.xi);
        self.born.clone_from(&source.born);
        self.plastic_strain.clone_from(&source.plastic_strain);
        self.volume.clone_from(&source.volume);
    }
}

/// The bonds of one particle: neighbours, reference vectors `X` (m) and birth lengths (m).
#[derive(Debug, Clone, Copy)]
pub(crate) struct BondRow<'a> {
    pub indices: &'a [u32],
    pub xi: &'a [Vector3<f64>],
    pub born: &'a [f64],
}

impl RestBonds {
    /// The bonds of the reference positions `x` (m) with their `horizons`: `X = x_j - x_i`,
    /// born at `|X|`, no plastic strain, at the rest volume.
    pub fn from_reference(x: &[Vector3<f64>], horizons: &Horizons) -> Self {
        let mut xi = Vec::with_capacity(horizons.indices.len());
        for i in 0..horizons.len() {
            xi.extend(horizons.of(i).iter().map(|&j| x[j as usize] - x[i]));
        }
        Self {
            offsets: horizons.offsets.clone(),
            indices: horizons.indices.clone(),
            born: xi.iter().map(|v| v.norm()).collect(),
            xi,
            plastic_strain: vec![0.0; horizons.len()],
            volume: vec![1.0; horizons.len()],
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.offsets.len() - 1
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The bonds of particle `i`.
    #[inline(always)]
    pub fn row(&self, i: usize) -> std::ops::Range<usize> {
        self.offsets[i] as usize..self.offsets[i + 1] as usize
    }

    /// The bonds of particle `i` as one view.
    #[inline(always)]
    pub(crate) fn bonds_of(&self, i: usize) -> BondRow<'_> {
        let row = self.row(i);
        BondRow {
            indices: &self.indices[row.clone()],
            xi: &self.xi[row.clone()],
            born: &self.born[row],
        }
    }

    /// The neighbours of particle `i`, increasing.
    #[inline(always)]
    pub fn of(&self, i: usize) -> &[u32] {
        &self.indices[self.row(i)]
    }

    /// Checks bonds given from outside (a restored state) for a body of `n` particles, naming
    /// the first culprit: `n + 1` offsets from 0, non-decreasing, to the bond count; per bond
    /// a neighbour in `[0, n)` other than the particle, increasing within each row, with the
    /// reverse bond present; a finite nonzero vector `X` (m) and a finite length > 0 (m) it
    /// was born at; per particle a finite plastic strain >= 0 and a volume ratio within
    /// [`VOLUME_RATIOS`] (the bounds the solver keeps it in, so a restored state is one a body
    /// could have stepped to).
    pub fn check(&self, n: usize) -> Result<()> {
        let bonds = self.indices.len();
        if self.offsets.len() != n + 1 {
            return Err(invalid!(
                "bond offsets must hold {} entries (particles + 1), got {}",
                n + 1,
                self.offsets.len()
            ));
        }
        if self.offsets[0] != 0 || self.offsets[n] as usize != bonds {
            return Err(invalid!(
                "bond offsets must run from 0 to the bond count {bonds}, got {} to {}",
                self.offsets[0],
                self.offsets[n]
            ));
        }
        if let Some(i) = (0..n).find(|&i| self.offsets[i] > self.offsets[i + 1]) {
            return Err(invalid!(
                "bond offsets decrease at particle {i}: {} then {}",
                self.offsets[i],
                self.offsets[i + 1]
            ));
        }
        if self.xi.len() != bonds || self.born.len() != bonds {
            return Err(invalid!(
                "bond vectors and lengths must hold one entry per bond ({bonds}), got {} and {}",
                self.xi.len(),
                self.born.len()
            ));
        }
        if self.plastic_strain.len() != n {
            return Err(invalid!(
                "the plastic strain must hold one entry per particle ({n}), got {}",
                self.plastic_strain.len()
            ));
        }
        if self.volume.len() != n {
            return Err(invalid!(
                "the volume ratios must hold one entry per particle ({n}), got {}",
                self.volume.len()
            ));
        }
        for i in 0..n {
            let row = self.of(i);
            for (k, &j) in row.iter().enumerate() {
                let b = self.offsets[i] as usize + k;
                if j as usize >= n || j as usize == i {
                    return Err(invalid!(
                        "bond {b} of particle {i} goes to {j}, not another particle of [0, {n})"
                    ));
                }
                if k > 0 && row[k - 1] >= j {
                    return Err(invalid!(
                        "the neighbours of particle {i} are not increasing at bond {b}"
                    ));
                }
                if self.of(j as usize).binary_search(&(i as u32)).is_err() {
                    return Err(invalid!(
                        "bond {b} joins particle {i} to {j}, but {j} has no bond back to {i}"
                    ));
                }
                let x = self.xi[b];
                if !(x.iter().all(|c| c.is_finite()) && x.norm() > 0.0) {
                    return Err(invalid!(
                        "the vector of bond {b} must be finite and nonzero, got {:?}",
                        x.as_slice()
                    ));
                }
                if !(self.born[b].is_finite() && self.born[b] > 0.0) {
                    return Err(invalid!(
                        "the birth length of bond {b} must be finite and > 0 m, got {}",
                        self.born[b]
                    ));
                }
            }
            let p = self.plastic_strain[i];
            if !(p.is_finite() && p >= 0.0) {
                return Err(invalid!(
                    "the plastic strain of particle {i} must be finite and >= 0, got {p}"
                ));
            }
            let v = self.volume[i];
            let (low, high) = VOLUME_RATIOS;
            if !(low..=high).contains(&v) {
                return Err(invalid!(
                    "the volume ratio of particle {i} must lie within [{low}, {high}], got {v}"
                ));
            }
        }
        Ok(())
    }

    /// Whether the bonds join the same pairs as `other`'s.
    pub fn same_pairs(&self, other: &Self) -> bool {
        self.offsets == other.offsets && self.indices == other.indices
    }
}
