//! Sums over the simple cubic lattice of a body's spacing, the rest state its particles are
//! sampled in: the normalisations that make the discrete SPH sums exact there (the density of
//! [`super::sph::Sph::on_lattice`], Brookshaw's Laplacian of the fluids' viscosity and of the
//! sand's wicking). A kernel only a few spacings wide misses its integral by a few per cent
//! when summed over the lattice, so each discrete operator is scaled by its own lattice sum.

use nalgebra::Vector3;

/// `sum_p term(p)` over the vectors `p` (m) of the simple cubic lattice of spacing `spacing`
/// (m) whose components are at most `ceil(radius / spacing)` spacings (the origin included),
/// in a fixed order (bit-identical wherever it runs). `radius` (m) is the support of `term`.
pub(crate) fn lattice_sum(
    radius: f64,
    spacing: f64,
    mut term: impl FnMut(Vector3<f64>) -> f64,
) -> f64 {
    let reach = (radius / spacing).ceil() as i64;
    let mut sum = 0.0;
    for a in -reach..=reach {
        for b in -reach..=reach {
            for c in -reach..=reach {
                sum += term(Vector3::new(a as f64, b as f64, c as f64) * spacing);
            }
        }
    }
    sum
}

/// The scale `s = 2 / sum_p V p_x^2 w(p)` that makes Brookshaw's SPH Laplacian
/// `lap f_i = s sum_j V w(y_i - y_j) (f_j - f_i)` exact for a quadratic field (`f = x^2`,
/// whose Laplacian is 2) inside the simple cubic lattice of spacing `spacing` (m), for the
/// pair weight `w` vanishing beyond `radius` (m) and the neighbours' common volume `V` =
/// `volume` (m^3; 1 where the scale absorbs it). The scale's units are the inverse of
/// `V w` over m^2.
pub(crate) fn brookshaw_scale(
    radius: f64,
    spacing: f64,
    volume: f64,
    weight: impl Fn(&Vector3<f64>) -> f64,
) -> f64 {
    2.0 / lattice_sum(radius, spacing, |p| volume * p.x * p.x * weight(&p))
}
