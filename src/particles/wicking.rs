//! Capillary wicking: the water held in wet sand moves from grain to grain (a departure: He
//! et al. 2017 keep the saturation `theta` of eq. 27 a constant of the material; the liquid's
//! uptake at a wetted face is [`super::wet_sand`]).
//!
//! **Held water.** Grain `i` holds the water volume `w_i = theta_i n V` (m^3): `theta_i` its
//! saturation (dimensionless, in [0, 1]), `V` the particle volume (m^3) and `n` =
//! [`POROSITY`] the share of the sand's bulk volume its pores take, the same for every grain
//! of a body. Moving `w` conserves `sum_i theta_i` exactly as it conserves the water.
//!
//! **Equation.** The linearised Richards equation of capillary flow in unsaturated sand,
//! `d theta / dt = D lap theta` (Philip 1969, "Theory of infiltration", eq. 8 with a constant
//! diffusivity), `D` (m^2/s) the sand's capillary diffusivity [`super::Granular::wicking`].
//! Gravity drainage is left out (capillarity dominates over a few grains: the capillary rise
//! of sand, 0.1 to 0.3 m, exceeds the scenes' depths).
//!
//! **Discretisation (conservative).** The SPH Laplacian of Brookshaw's form over the
//! neighbours `j` of the body's bonds at the current positions,
//! `lap theta_i = sum_j G_ij (theta_j - theta_i)`, with the weight
//! `G_ij = s (delta^2 - r_ij^2)^2 (c_i + c_j) / 2` (1/m^2) for `r_ij < delta`, else 0:
//! `(delta^2 - r^2)^2` is `-W'(r) / r` of the poly6 kernel up to a constant, `delta` the
//! horizon (m). The scale `s` (1/m^6) makes the sum exact for a quadratic inside the simple
//! cubic lattice of the body's spacing (`sum_p s (delta^2 - |p|^2)^2 p_x^2 / 2 = 1`), so the
//! sampled interior diffuses at `D` rather than at the few per cent off that the discrete
//! kernel sum gives. `c_i` corrects the kernel's deficiency beside a free surface: the
//! lattice's second moment `sum_p (delta^2 - |p|^2)^2 |p|^2` over grain `i`'s own
//! `sum_j (delta^2 - r_ij^2)^2 r_ij^2` (1 inside, 1.48 on a flat face, 2.22 on an edge,
//! 3.42 at a corner, at most [`MAX_CORRECTION`]): a grain of a flat face passes water along
//! the face at 1.13 `D` (0.77 `D` uncorrected), one of an edge along it at 1.30 `D` (0.59),
//! and a bar three grains thick wicks at about 1.2 `D`. The weight is symmetric
//! (`G_ij = G_ji` bit for bit: the distance of `y_i - y_j` and of its negation are equal),
//! so grain `j` gains to the last bit what grain `i` loses: the held water is conserved to
//! the round-off of the sums, and no water leaves the body (its free surfaces are closed).
//!
//! **Time step (explicit, with substeps).** Forward Euler on `n_s` equal substeps of the
//! step `h`: `theta_i += (h / n_s) D sum_j G_ij (theta_j - theta_i)`, with
//! `n_s = ceil(2 h D max_i sum_j G_ij)`, so that `(h / n_s) D sum_j G_ij <= 1/2` at every
//! grain: each new saturation is a convex combination of the old ones (no new extremes, the
//! saturations stay in [0, 1]) and no mode flips sign. Explicit rather than implicit because
//! it conserves the water to round-off (an iterative implicit solve conserves it only to
//! its tolerance) and at the default `D` a step of a few ms on a cm lattice needs one
//! substep (inside the lattice `sum_j G_ij` = 3.42 / spacing^2, so `2 h D sum G` = 0.0014
//! at `h` = 2 ms, 1 cm); the count grows as `D h / spacing^2` (10 at the largest `D`, 10 ms
//! steps and a 1 cm lattice). Every grain's sum runs alone in its neighbour order:
//! bit-identical for any number of threads.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::rest_bonds::RestBonds;

/// The porosity `n` of the sand (dimensionless): the share of its bulk volume the pores
/// take, so that a saturated grain of volume `V` holds `n V` of water. 0.4: randomly packed
/// quartz sand (grains of 2650 kg/m^3 at the bulk density 1600 kg/m^3 the sand tests sample
/// at: `1 - 1600 / 2650` = 0.40).
pub const POROSITY: f64 = 0.4;

/// The default capillary diffusivity `D` (m^2/s) of sand: `K_s h_c / n` of fine sand (a
/// saturated conductivity `K_s` of 5e-5 m/s and a capillary rise `h_c` of 0.1 m, `n` =
/// [`POROSITY`]), whose sorptivity `2 n sqrt(D / pi)` = 1.4 mm/s^1/2 is the order measured
/// for sands: a wetting front advances about `sqrt(D t)` = 3 mm in a second.
pub const DEFAULT_WICKING: f64 = 1e-5;

/// The largest capillary diffusivity accepted (m^2/s): a hundred times that of coarse sand
/// (1e-4 m^2/s); the substeps grow with `D`.
pub const MAX_WICKING: f64 = 1e-2;

/// The largest surface correction `c_i` (a grain at a cube's corner takes 3.42; a lone pair
/// of grains far more, which would only cost substeps).
pub const MAX_CORRECTION: f64 = 4.0;

/// The wicking of one sand body (see the module's doc): its constants and buffers.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Wicking {
    /// `D` (m^2/s).
    diffusivity: f64,
    /// The horizon `delta` (m).
    horizon: f64,
    /// The lattice scale `s` (1/m^6).
    scale: f64,
    /// The lattice's second moment `sum_p (delta^2 - |p|^2)^2 |p|^2` (m^6).
    moment: f64,
    /// Per grain its correction `c_i` and its next saturation (reused).
    correction: Vec<f64>,
    next: Vec<f64>,
}

impl Wicking {
    /// The wicking at the diffusivity `diffusivity` (m^2/s) for a body of horizon `horizon`
    /// and lattice spacing `spacing` (m), or `None` when `diffusivity` is 0.
    pub fn new(diffusivity: f64, horizon: f64, spacing: f64) -> Option<Self> {
        if diffusivity == 0.0 {
            return None;
        }
        let reach = (horizon / spacing).ceil() as i64;
        let (mut along, mut moment) = (0.0, 0.0);
        for a in -reach..=reach {
            for b in -reach..=reach {
                for c in -reach..=reach {
                    let p = Vector3::new(a as f64, b as f64, c as f64) * spacing;
                    let w = weight(horizon, p.norm_squared());
                    along += w * p.x * p.x / 2.0;
                    moment += w * p.norm_squared();
                }
            }
        }
        Some(Self {
            diffusivity,
            horizon,
            scale: 1.0 / along,
            moment,
            correction: Vec::new(),
            next: Vec::new(),
        })
    }

    /// Moves the held water of the saturations `theta` (one per grain) over the step `h` (s)
    /// along the bonds `bonds` at the positions `y` (m); returns the substeps taken.
    pub fn wick(
        &mut self,
        bonds: &RestBonds,
        y: &[Vector3<f64>],
        theta: &mut [f64],
        h: f64,
    ) -> usize {
        let delta = self.horizon;
        let moment = self.moment;
        let n = theta.len();
        self.correction.resize(n, 0.0);
        self.next.resize(n, 0.0);
        let neighbours = |i: usize| {
            bonds.indices[bonds.row(i)].iter().map(move |&j| {
                (
                    j as usize,
                    weight(delta, (y[i] - y[j as usize]).norm_squared()),
                )
            })
        };
        self.correction
            .par_iter_mut()
            .enumerate()
            .for_each(|(i, c)| {
                let own: f64 = bonds.indices[bonds.row(i)]
                    .iter()
                    .map(|&j| {
                        let r2 = (y[i] - y[j as usize]).norm_squared();
                        weight(delta, r2) * r2
                    })
                    .sum();
                *c = if own * MAX_CORRECTION > moment {
                    moment / own
                } else {
                    MAX_CORRECTION
                };
            });
        let (c, rate) = (&self.correction, self.diffusivity * self.scale);
        let rows = (0..n)
            .into_par_iter()
            .map(|i| {
                neighbours(i)
                    .map(|(j, w)| w * (c[i] + c[j]) / 2.0)
                    .sum::<f64>()
            })
            .reduce(|| 0.0, f64::max);
        let substeps = (2.0 * h * rate * rows).ceil().max(1.0);
        let factor = rate * h / substeps;
        for _ in 0..substeps as usize {
            let old = &*theta;
            self.next.par_iter_mut().enumerate().for_each(|(i, next)| {
                let gain: f64 = neighbours(i)
                    .map(|(j, w)| factor * (w * (c[i] + c[j]) / 2.0) * (old[j] - old[i]))
                    .sum();
                *next = (old[i] + gain).clamp(0.0, 1.0);
            });
            theta.copy_from_slice(&self.next);
        }
        substeps as usize
    }
}

/// `(delta^2 - r^2)^2` (m^4) at the squared distance `r2` (m^2) within the horizon `delta`
/// (m), else 0.
#[inline]
fn weight(delta: f64, r2: f64) -> f64 {
    let q = delta * delta - r2;
    if q > 0.0 {
        q * q
    } else {
        0.0
    }
}

#[cfg(test)]
#[path = "wicking_tests.rs"]
mod tests;
