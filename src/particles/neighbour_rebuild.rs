//! Changing neighbourhoods of plastic bodies (He et al. 2017, section 5, eq. 20): the
//! neighbours searched anew on the deformed positions, the bonds that stay kept as they are,
//! and the reference vectors of new neighbours from the particle's clamped inverse map.
//!
//! A new neighbour `j` of particle `i` gets `X = F~^-1 (y_j - y_i)`, where `F~` is `F_i`
//! from the bonds the particle had, with its singular values clamped to
//! `[1 + e_iso - ||e_dev||, 1 + e_iso + ||e_dev||]` (the stretches its bonds show,
//! [`super::plasticity`]), and below by [`MIN_STRETCH`] so that a squashed neighbourhood
//! does not throw new neighbours far out; a particle without a three-dimensional weighted
//! neighbourhood maps new neighbours as they are (`F~ = I`). The new bond is born at `|X|`.
//! A bond whose particles have moved a horizon apart is dropped.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::error::Result;
use crate::geometry::find_horizons;

use super::plasticity::local_strain;
use super::rest_bonds::RestBonds;

/// Smallest singular value (stretch) the inverse map of eq. 20 uses.
pub const MIN_STRETCH: f64 = 0.1;

/// `F~^-1` of particle `i` (see the module's doc).
fn clamped_inverse(
    bonds: &RestBonds,
    i: usize,
    y: &[Vector3<f64>],
    delta: f64,
    volume: f64,
) -> Matrix3<f64> {
    let Some(local) = local_strain(bonds, i, y, delta, volume) else {
        return Matrix3::identity();
    };
    let svd = local.f.svd(true, true);
    let (Some(u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let low = (1.0 + local.iso - local.dev).max(MIN_STRETCH);
    let high = (1.0 + local.iso + local.dev).max(low);
    let inverse = svd.singular_values.map(|s| 1.0 / s.clamp(low, high));
    v_t.transpose() * Matrix3::from_diagonal(&inverse) * u.transpose()
}

/// The bonds of a body at its deformed positions `y` (m) for the horizon `delta` (m) and the
/// particle volume `volume` (m^3): the old ones where the pair is still within the horizon,
/// new ones by eq. 20 (see the module's doc). `None` when the pairs are the same as before
/// (nothing to change).
pub fn rebuild(
    bonds: &RestBonds,
    y: &[Vector3<f64>],
    delta: f64,
    volume: f64,
) -> Result<Option<RestBonds>> {
    let found = find_horizons(y, delta)?;
    if found.offsets == bonds.offsets && found.indices == bonds.indices {
        return Ok(None);
    }
    // Coincident particles (which the search counts as neighbours) get no bond: it would have
    // no direction.
    let rows: Vec<Vec<(u32, Vector3<f64>, f64)>> = (0..bonds.len())
        .into_par_iter()
        .map(|i| {
            let old = bonds.of(i);
            let mut inverse = None;
            found
                .of(i)
                .iter()
                .filter(|&&j| y[j as usize] != y[i])
                .map(|&j| match old.binary_search(&j) {
                    Ok(k) => {
                        let b = bonds.offsets[i] as usize + k;
                        (j, bonds.xi[b], bonds.born[b])
                    }
                    Err(_) => {
                        let map = *inverse
                            .get_or_insert_with(|| clamped_inverse(bonds, i, y, delta, volume));
                        let x = map * (y[j as usize] - y[i]);
                        (j, x, x.norm())
                    }
                })
                .collect()
        })
        .collect();
    let mut offsets = Vec::with_capacity(rows.len() + 1);
    offsets.push(0u32);
    for row in &rows {
        offsets.push(offsets[offsets.len() - 1] + row.len() as u32);
    }
    let flat: Vec<(u32, Vector3<f64>, f64)> = rows.into_iter().flatten().collect();
    let rebuilt = RestBonds {
        offsets,
        indices: flat.iter().map(|p| p.0).collect(),
        xi: flat.iter().map(|p| p.1).collect(),
        born: flat.iter().map(|p| p.2).collect(),
        plastic_strain: bonds.plastic_strain.clone(),
    };
    Ok((!rebuilt.same_pairs(bonds)).then_some(rebuilt))
}
