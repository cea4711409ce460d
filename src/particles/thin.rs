//! Shells and rods as particles (He et al. 2017, section 4, Fig. 5 and 6): a single layer of
//! real particles on a surface, or a line of them along a curve, and ghost particles beside
//! them that give every neighbourhood three dimensions (a single layer's shape matrix `K_i` is
//! singular) and the body its bending stiffness. Ghosts are ordinary particles of the body in
//! its elasticity, mass and pins (a pinned particle's ghosts are pinned with it), but no
//! collider acts on them (the paper: "they do not participate in collision handling").
//!
//! **Where the ghosts go (beyond the paper, which gives no rule).** They are placed so that
//! the discrete section has the continuum's second moment of area, the quantity bending
//! stiffness is proportional to (Euler-Bernoulli: `E I`):
//! - a shell of thickness `t` gets two ghost layers at `+-t / sqrt 8` along the normal: three
//!   layers of `t / 3` each have `I = 2 (t / 3) (t^2 / 8) = t^3 / 12` per unit width, the
//!   plate's;
//! - a rod of radius `r` gets four ghosts per particle on a ring of radius `r sqrt(5 / 8)` in
//!   the plane across the line (two perpendicular diameters, carried along the curve by
//!   parallel transport): five particles of `A / 5` each have
//!   `I = 2 (A / 5) (5 r^2 / 8) = A r^2 / 4`, the disk's (and the polar moment `A r^2 / 2`).
//!
//! Each particle stands for an equal share of the body's volume (area times thickness, or
//! `pi r^2` times length), so the mass is exact; the surface correction of
//! [`Elastic::Young`](super::Elastic) gives each particle the bulk's energy density under a
//! uniform dilation, so the stretching stiffness follows the thickness too. Bending and
//! twisting of a rod cannot be set apart (the paper's stated limitation). A particle keeps
//! half the thickness (a shell) or the radius (a rod) from a collider's surface.

use nalgebra::{Rotation3, Vector3};

use crate::error::{check_param, invalid, Result};

use super::body::{ParticleParams, Particles};
use super::sampling::sample_surface_with_normals;

/// Largest thickness of a shell, and diameter of a rod, in spacings: beyond it the ghosts
/// stand farther from their owner than the spacing, and a solid sampled with
/// [`super::sample_volume`] is the better model.
pub const MAX_SECTION: f64 = 2.0;

/// Checks a section size (m): finite, positive, at most [`MAX_SECTION`] spacings.
fn check_section(name: &str, value: f64, limit: f64) -> Result<f64> {
    check_param(
        name,
        value,
        |v| v > 0.0 && v <= limit,
        &format!("a finite length in (0, {limit}] m ({MAX_SECTION} spacings across)"),
    )
}

impl Particles {
    /// A shell of `thickness` (m) on the surface `vertices` (m) / `triangles` (closed or open,
    /// as [`super::sample_surface`] takes it): real particles sampled on the surface at least
    /// `params.spacing` apart (seeded by `seed`), then two ghost layers at
    /// `+-thickness / sqrt 8` along each particle's triangle normal (see the module's notes).
    /// Particles `0..n` are the real ones, `n..2n` the ghosts on the normal's side and
    /// `2n..3n` those on the other, ghost `n + k` and `2n + k` belonging to particle `k`.
    ///
    /// Errors (naming the culprit): a bad parameter or surface; `thickness` not in
    /// `(0, 2 spacing]`; a neighbourhood that stays flat (a horizon too short to reach a
    /// neighbour: sample more densely or widen the horizon).
    pub fn shell(
        vertices: Vec<[f64; 3]>,
        triangles: Vec<[i64; 3]>,
        thickness: f64,
        seed: u64,
        params: ParticleParams,
    ) -> Result<Self> {
        params.validate()?;
        let thickness = check_section("thickness", thickness, MAX_SECTION * params.spacing)?;
        let sample = sample_surface_with_normals(vertices, triangles, params.spacing, seed)?;
        let n = sample.points.len();
        let offset = thickness / 8f64.sqrt();
        let mut reference = sample.points.clone();
        for side in [1.0, -1.0] {
            reference.extend(
                sample
                    .points
                    .iter()
                    .zip(&sample.normals)
                    .map(|(x, normal)| x + normal * (side * offset)),
            );
        }
        let owners = (0..2 * n).map(|k| (k % n) as u32).collect();
        let volume = sample.area * thickness / (3 * n) as f64;
        let mut body = Self::with_ghosts(reference, owners, volume, 0.5 * thickness, params)?;
        body.fold_deviatoric();
        Ok(body)
    }

    /// A rod of `radius` (m) along the polyline `points` (m, at least two, consecutive points
    /// distinct): real particles at equal arc-length steps of at most `params.spacing`, both
    /// ends included, each with four ghosts on a ring of radius `radius sqrt(5 / 8)` across the
    /// line (see the module's notes). Particles `0..n` are the real ones; ghosts
    /// `n + 4 k .. n + 4 k + 4` belong to particle `k`.
    ///
    /// Errors (naming the culprit): a bad parameter; fewer than two points, a non-finite
    /// point, two equal consecutive points, or a turn by 180 degrees; `radius` not in
    /// `(0, spacing]`.
    pub fn rod(points: &[Vector3<f64>], radius: f64, params: ParticleParams) -> Result<Self> {
        params.validate()?;
        let radius = check_section("radius", radius, 0.5 * MAX_SECTION * params.spacing)?;
        let line = resample(points, params.spacing)?;
        let n = line.len();
        let length = (n - 1) as f64 * (line[1] - line[0]).norm();
        let ring = radius * (5.0f64 / 8.0).sqrt();
        let mut reference = line.clone();
        let mut owners = Vec::with_capacity(4 * n);
        for (k, (x, (u, v))) in line.iter().zip(transported_frames(&line)?).enumerate() {
            for d in [u, -u, v, -v] {
                reference.push(x + d * ring);
                owners.push(k as u32);
            }
        }
        let volume = std::f64::consts::PI * radius * radius * length / (5 * n) as f64;
        let mut body = Self::with_ghosts(reference, owners, volume, radius, params)?;
        body.fold_deviatoric();
        Ok(body)
    }
}

/// Points at equal arc-length steps of at most `spacing` (m) along the polyline `points`,
/// both ends included.
fn resample(points: &[Vector3<f64>], spacing: f64) -> Result<Vec<Vector3<f64>>> {
    if points.len() < 2 {
        return Err(invalid!(
            "a rod needs at least 2 points, got {}",
            points.len()
        ));
    }
    if let Some(i) = points.iter().position(|x| !x.iter().all(|c| c.is_finite())) {
        return Err(invalid!(
            "rod point {i} is not finite: {:?}",
            points[i].as_slice()
        ));
    }
    if let Some(i) = points.windows(2).position(|w| w[0] == w[1]) {
        return Err(invalid!(
            "rod points {i} and {} are equal: {:?}",
            i + 1,
            points[i].as_slice()
        ));
    }
    let lengths: Vec<f64> = points.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
    let total: f64 = lengths.iter().sum();
    let steps = (total / spacing).ceil().max(1.0);
    if steps > super::MAX_PARTICLES as f64 {
        return Err(invalid!(
            "the rod would have {steps:.3e} particles (length {total} m / spacing {spacing} m), more than {}",
            super::MAX_PARTICLES
        ));
    }
    let steps = steps as usize;
    let step = total / steps as f64;
    let (mut segment, mut start) = (0, 0.0);
    let mut line = Vec::with_capacity(steps + 1);
    for k in 0..=steps {
        let s = k as f64 * step;
        while segment + 1 < lengths.len() && s > start + lengths[segment] {
            start += lengths[segment];
            segment += 1;
        }
        let t = ((s - start) / lengths[segment]).clamp(0.0, 1.0);
        line.push(points[segment].lerp(&points[segment + 1], t));
    }
    Ok(line)
}

/// Two unit vectors across the line at each of its points, carried from one point to the
/// next by the smallest rotation that takes one tangent to the next (parallel transport, so
/// a straight or planar line keeps a constant frame and the ghosts do not twist).
fn transported_frames(line: &[Vector3<f64>]) -> Result<Vec<(Vector3<f64>, Vector3<f64>)>> {
    let n = line.len();
    let tangent = |k: usize| (line[(k + 1).min(n - 1)] - line[k.saturating_sub(1)]).normalize();
    let t0 = tangent(0);
    let axis = Vector3::ith(t0.iamin(), 1.0);
    let mut u = t0.cross(&axis).normalize();
    let mut previous = t0;
    let mut frames = Vec::with_capacity(n);
    for k in 0..n {
        let t = tangent(k);
        if !t.iter().all(|c| c.is_finite()) {
            return Err(invalid!("the rod turns back on itself at its point {k}"));
        }
        let turn = Rotation3::rotation_between(&previous, &t)
            .ok_or_else(|| invalid!("the rod turns back on itself at its point {k}"))?;
        u = turn * u;
        u = (u - t * t.dot(&u)).normalize();
        frames.push((u, t.cross(&u)));
        previous = t;
    }
    Ok(frames)
}
