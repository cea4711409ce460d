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
use crate::geometry::{find_horizons, Horizons};
use crate::parallel::for_each_vertex;

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
    let Horizons {
        offsets, indices, ..
    } = found;
    // Each new bond's vector and birth length, in place in rows of the new pairs (no copy of
    // the bonds beyond the result).
    let mut xi = vec![Vector3::zeros(); indices.len()];
    let mut born = vec![0.0; indices.len()];
    let mut unused = vec![(); bonds.len()];
    for_each_vertex(&offsets, &mut xi, &mut unused, &|i,
                                                      row: &mut [Vector3<
        f64,
    >]| {
        let (old, new) = (bonds.of(i), &indices[offsets[i] as usize..]);
        let mut inverse = None;
        for (x, &j) in row.iter_mut().zip(new) {
            *x = match old.binary_search(&j) {
                Ok(k) => bonds.xi[bonds.offsets[i] as usize + k],
                Err(_) => {
                    let map =
                        *inverse.get_or_insert_with(|| clamped_inverse(bonds, i, y, delta, volume));
                    map * (y[j as usize] - y[i])
                }
            };
        }
    });
    for_each_vertex(&offsets, &mut born, &mut unused, &|i, row: &mut [f64]| {
        let (old, new) = (bonds.of(i), &indices[offsets[i] as usize..]);
        let first = offsets[i] as usize;
        for (k, (length, &j)) in row.iter_mut().zip(new).enumerate() {
            *length = match old.binary_search(&j) {
                Ok(m) => bonds.born[bonds.offsets[i] as usize + m],
                Err(_) => xi[first + k].norm(),
            };
        }
    });
    let mut rebuilt = RestBonds {
        offsets,
        indices,
        xi,
        born,
        plastic_strain: bonds.plastic_strain.clone(),
        volume: bonds.volume.clone(),
    };
    drop_coincident(&mut rebuilt, y);
    Ok((!rebuilt.same_pairs(bonds)).then_some(rebuilt))
}

/// Drops the bonds between coincident particles (which the search counts as neighbours): a
/// bond would have no direction. Moves nothing when there are none (the usual case).
fn drop_coincident(bonds: &mut RestBonds, y: &[Vector3<f64>]) {
    let coincident = |i: usize, b: usize| y[bonds.indices[b] as usize] == y[i];
    if !(0..bonds.len())
        .into_par_iter()
        .any(|i| bonds.row(i).any(|b| coincident(i, b)))
    {
        return;
    }
    let mut keep = Vec::with_capacity(bonds.indices.len());
    let mut offsets = vec![0u32];
    for i in 0..bonds.len() {
        let before = keep.len();
        keep.extend(bonds.row(i).map(|b| !coincident(i, b)));
        let kept = keep[before..].iter().filter(|&&k| k).count() as u32;
        offsets.push(offsets[i] + kept);
    }
    let mut flags = keep.iter();
    bonds
        .indices
        .retain(|_| *flags.next().expect("one flag a bond"));
    let mut flags = keep.iter();
    bonds.xi.retain(|_| *flags.next().expect("one flag a bond"));
    let mut flags = keep.iter();
    bonds
        .born
        .retain(|_| *flags.next().expect("one flag a bond"));
    bonds.offsets = offsets;
}
