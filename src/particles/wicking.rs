//! Capillary wicking: the water held in wet sand moves from grain to grain (a departure: He
//! et al. 2017 keep the saturation `theta` of eq. 27 a constant of the material; the liquid's
//! uptake at a wetted face is [`super::wet_sand`]).
//!
//! **Held water.** Grain `i` holds the water volume `theta_i n V` (m^3): `theta_i` its
//! saturation (dimensionless, in [0, 1]), `V` the particle volume (m^3) and `n` the sand's
//! porosity, the same for every grain of a body: `n` and `V` cancel, so moving the water
//! moves the saturations and conserves `sum_i theta_i` exactly as it conserves the water.
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
//! `(delta^2 - r^2)^2` is `-W'(r) / r` of the poly6 kernel up to a constant
//! ([`super::sph::poly6_slope`]), `delta` the horizon (m). The scale `s` (1/m^6,
//! [`super::brookshaw_scale`]) makes the sum exact for a quadratic inside the simple cubic
//! lattice of the body's spacing, so the sampled interior diffuses at `D` rather than at the
//! few per cent off that the discrete kernel sum gives. `c_i` corrects the kernel's
//! deficiency beside a free surface, where a grain misses the neighbours beyond it: the
//! lattice's second moment `sum_p (delta^2 - |p|^2)^2 |p|^2` over grain `i`'s own
//! `sum_j (delta^2 - r_ij^2)^2 r_ij^2` (1 inside, more at a face, an edge, a corner; at most
//! [`MAX_CORRECTION`]), so that water moves along a free surface near the interior's rate.
//! The weight is symmetric (`G_ij = G_ji` bit for bit: the distance of `y_i - y_j` and of
//! its negation are equal), so grain `j` gains to the last bit what grain `i` loses: the held
//! water is conserved to the round-off of the sums, and no water leaves the body (its free
//! surfaces are closed).
//!
//! **Time step (explicit, with substeps).** Forward Euler on `n_s` equal substeps of the
//! step `h`: `theta_i += (h / n_s) D sum_j G_ij (theta_j - theta_i)`, with
//! `n_s = ceil(2 h D max_i sum_j G_ij)`, so that `(h / n_s) D sum_j G_ij <= 1/2` at every
//! grain: each new saturation is a convex combination of the old ones (no new extremes, the
//! saturations stay in [0, 1]) and no mode flips sign. Explicit rather than implicit because
//! it conserves the water to round-off (an iterative implicit solve conserves it only to
//! its tolerance). `n_s` grows as `D h / spacing^2` (inside the lattice `sum_j G_ij` is
//! about 3.4 / spacing^2) and with compaction; a step that would need more than
//! [`MAX_WICKING_SUBSTEPS`] is refused before any water moves, naming `wicking`. Every
//! grain's sum runs alone in its neighbour order: bit-identical for any number of threads.

use nalgebra::Vector3;
use rayon::prelude::*;

use super::lattice::{brookshaw_scale, lattice_sum};
use super::rest_bonds::RestBonds;
use super::sph::poly6_slope;
use crate::error::{invalid, Result};

/// The default capillary diffusivity `D` (m^2/s) of sand: `K_s h_c / n` of fine sand (a
/// saturated conductivity `K_s` of 5e-5 m/s, a capillary rise `h_c` of 0.1 m and a porosity
/// `n` of 0.4), whose sorptivity `2 n sqrt(D / pi)` = 1.4 mm/s^1/2 is the order measured
/// for sands: a wetting front advances about `sqrt(D t)` = 3 mm in a second.
pub const DEFAULT_WICKING: f64 = 1e-5;

/// The largest capillary diffusivity accepted (m^2/s): a hundred times that of coarse sand
/// (1e-4 m^2/s); the substeps grow with `D`.
pub const MAX_WICKING: f64 = 1e-2;

/// The most substeps of one step's wicking: each is a pass over the bonds, so beyond this
/// the wicking alone would cost about what the rest of the step does; a step that needs
/// more is refused (a smaller `wicking` or time step fits).
pub const MAX_WICKING_SUBSTEPS: usize = 100;

/// The largest surface correction `c_i` (a grain at a cube's corner takes about 3.4; a lone
/// pair of grains far more, which would only cost substeps).
pub const MAX_CORRECTION: f64 = 4.0;

/// The wicking of one sand body (see the module's doc): its constants and buffers.
pub(crate) struct Wicking {
    /// `D` (m^2/s).
    diffusivity: f64,
    /// The horizon `delta` (m).
    horizon: f64,
    /// The lattice spacing (m), named when a step is refused.
    spacing: f64,
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
        let weight = |p: &Vector3<f64>| poly6_slope(horizon, p.norm_squared());
        Some(Self {
            diffusivity,
            horizon,
            spacing,
            scale: brookshaw_scale(horizon, spacing, 1.0, weight),
            moment: lattice_sum(horizon, spacing, |p| weight(&p) * p.norm_squared()),
            correction: Vec::new(),
            next: Vec::new(),
        })
    }

    /// Moves the held water of the saturations `theta` (one per grain) over the step `h` (s)
    /// along the bonds `bonds` at the positions `y` (m); returns the substeps taken.
    /// Errors (naming `wicking`, `theta` left as it was): a step that needs more than
    /// [`MAX_WICKING_SUBSTEPS`].
    pub fn wick(
        &mut self,
        bonds: &RestBonds,
        y: &[Vector3<f64>],
        theta: &mut [f64],
        h: f64,
    ) -> Result<usize> {
        let delta = self.horizon;
        let moment = self.moment;
        let n = theta.len();
        self.correction.resize(n, 0.0);
        self.next.resize(n, 0.0);
        let neighbours = |i: usize| {
            bonds.indices[bonds.row(i)].iter().map(move |&j| {
                (
                    j as usize,
                    poly6_slope(delta, (y[i] - y[j as usize]).norm_squared()),
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
                        poly6_slope(delta, r2) * r2
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
        if substeps > MAX_WICKING_SUBSTEPS as f64 {
            return Err(invalid!(
                "Granular(wicking={}) m^2/s over the time step {h} s on the lattice spacing {} m \
                 needs {substeps} substeps of the explicit wicking, more than the \
                 {MAX_WICKING_SUBSTEPS} allowed (they grow as wicking * dt / spacing^2): lower \
                 wicking or the time step",
                self.diffusivity,
                self.spacing
            ));
        }
        let factor = rate * h / substeps;
        for _ in 0..substeps as usize {
            let old = &*theta;
            self.next.par_iter_mut().enumerate().for_each(|(i, next)| {
                let gain: f64 = neighbours(i)
                    .map(|(j, w)| factor * (w * (c[i] + c[j]) / 2.0) * (old[j] - old[i]))
                    .sum();
                *next = old[i] + gain;
                debug_assert!(
                    (0.0..=1.0).contains(next),
                    "a convex combination of saturations in [0, 1] left it: {next}"
                );
            });
            theta.copy_from_slice(&self.next);
        }
        Ok(substeps as usize)
    }
}

#[cfg(test)]
#[path = "wicking_tests.rs"]
mod tests;
