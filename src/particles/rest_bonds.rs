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
//! solver refactors only then. For an elastic body `born = |X|` and nothing differs.

use nalgebra::Vector3;

use crate::geometry::Horizons;

/// A body's current reference bonds (see the module's doc).
#[derive(Debug, Clone, PartialEq)]
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
}

impl RestBonds {
    /// The bonds of the reference positions `x` (m) with their `horizons`: `X = x_j - x_i`,
    /// born at `|X|`, no plastic strain.
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

    /// The neighbours of particle `i`, increasing.
    #[inline(always)]
    pub fn of(&self, i: usize) -> &[u32] {
        &self.indices[self.row(i)]
    }

    /// Whether the bonds join the same pairs as `other`'s.
    pub fn same_pairs(&self, other: &Self) -> bool {
        self.offsets == other.offsets && self.indices == other.indices
    }
}
