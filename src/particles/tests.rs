//! Tests of the particle model: lattice sums against the closed form, rigid motion, balance,
//! finite differences where the force is a gradient, precision.

use nalgebra::{Matrix3, Vector3};

use super::*;

/// A block of `n[0] x n[1] x n[2]` particles on a cubic lattice of `spacing` (m) from the origin.
pub(crate) fn lattice(n: [usize; 3], spacing: f64) -> Vec<Vector3<f64>> {
    let mut out = Vec::with_capacity(n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                out.push(Vector3::new(i as f64, j as f64, k as f64) * spacing);
            }
        }
    }
    out
}

fn body(n: [usize; 3], spacing: f64, mu: f64, lam: f64) -> Particles {
    let params = ParticleParams {
        spacing,
        density: 1000.0,
        horizon: None,
        material: Elastic::Paper { mu, lam },
    };
    Particles::new(lattice(n, spacing), params).unwrap()
}

fn deformed(body: &mut Particles, map: impl Fn(&Vector3<f64>) -> Vector3<f64>) {
    let y = body.reference().iter().map(map).collect();
    body.set_positions(y).unwrap();
}

/// `V sum_j V w_j (mu + lam / 2) (|F xi_j| / |xi_j| - 1)^2` over the lattice vectors `xi_j`
/// inside the horizon, enumerated here without horizons, rest data or kernel: the energy of
/// an interior particle under the affine map `F` (J).
fn closed_form(f: &Matrix3<f64>, spacing: f64, delta: f64, mu: f64, lam: f64) -> f64 {
    let v = spacing.powi(3);
    let reach = (delta / spacing).ceil() as i64;
    let mut sum = 0.0;
    for a in -reach..=reach {
        for b in -reach..=reach {
            for c in -reach..=reach {
                let xi = Vector3::new(a as f64, b as f64, c as f64) * spacing;
                let r = xi.norm();
                if r == 0.0 || r >= delta {
                    continue;
                }
                let strain = (f * xi).norm() / r - 1.0;
                sum += v * influence(r, delta) * (mu + lam / 2.0) * strain * strain;
            }
        }
    }
    v * sum
}

/// The centre of a 9^3 block (a full horizon of 2.2 spacings, and every neighbour with a
/// full one too) under a small affine strain stores the lattice sum's energy (1e-9), and to
/// second order the energy density of the stiffness tensor `C11`, `C12 = C44` of
/// [`lattice_moduli`] (1e-5 at strains of 1e-6), for uniaxial, shear and mixed strains.
#[test]
fn an_interior_particle_stores_the_lattice_sum_of_an_affine_strain() {
    let (spacing, mu, lam) = (0.01, 3000.0, 5000.0);
    let mut b = body([9, 9, 9], spacing, mu, lam);
    let centre = 4 + 9 * 4 + 81 * 4;
    let delta = b.horizon();
    let unit = lattice_moduli(spacing, delta).unwrap();
    let c = mu + lam / 2.0;
    let v = spacing.powi(3);
    let e = 1e-6;
    let cases = [
        (
            Matrix3::new(e, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
            0.5 * unit.c11 * e * e,
        ),
        (
            Matrix3::new(0.0, e, 0.0, e, 0.0, 0.0, 0.0, 0.0, 0.0),
            2.0 * unit.c12 * e * e,
        ),
        (
            Matrix3::new(e, 0.0, 0.0, 0.0, -0.5 * e, 0.0, 0.0, 0.0, 0.0),
            0.5 * unit.c11 * 1.25 * e * e - unit.c12 * 0.5 * e * e,
        ),
    ];
    for (strain, density) in cases {
        let f = Matrix3::identity() + strain;
        // A rotation on top changes nothing.
        let rot = nalgebra::Rotation3::from_euler_angles(0.3, -0.2, 0.7);
        let map = rot * f;
        deformed(&mut b, |x| map * x + Vector3::new(0.1, 0.2, -0.3));
        let energy = b.particle_energies().unwrap()[centre];
        let exact = closed_form(&f, spacing, delta, mu, lam);
        assert!(
            (energy - exact).abs() <= 1e-9 * exact,
            "kernel {energy:e} against lattice sum {exact:e}"
        );
        let quadratic = c * density * v;
        assert!(
            (energy - quadratic).abs() <= 1e-5 * quadratic,
            "{energy:e} against C : eps : eps / 2 = {quadratic:e}"
        );
    }
}

/// A rotated and translated block feels no force: every force below 1e-9 of the forces of a
/// 1 % stretch.
#[test]
fn rigid_motion_is_force_free() {
    let mut b = body([6, 5, 4], 0.02, 1e4, 2e4);
    deformed(&mut b, |x| Vector3::new(1.01 * x.x, x.y, x.z));
    let scale = b
        .internal_forces()
        .unwrap()
        .iter()
        .map(|f| f.norm())
        .fold(0.0, f64::max);
    let rot = nalgebra::Rotation3::from_euler_angles(1.1, 0.4, -2.0);
    deformed(&mut b, |x| rot * x + Vector3::new(3.0, -1.0, 0.5));
    let worst = b
        .internal_forces()
        .unwrap()
        .iter()
        .map(|f| f.norm())
        .fold(0.0, f64::max);
    assert!(
        scale > 0.0 && worst < 1e-9 * scale,
        "{worst:e} against {scale:e}"
    );
}

/// A smooth random-looking deformation (large, with an inverted corner): the internal forces
/// sum to zero (1e-12 of their magnitudes).
fn wavy(x: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        x.x + 0.03 * (40.0 * x.y).sin(),
        x.y * (1.0 + 0.2 * (30.0 * x.z).cos()),
        -x.z + 0.02 * (25.0 * x.x).sin(),
    )
}

#[test]
fn internal_forces_balance() {
    let mut b = body([6, 5, 4], 0.02, 1e4, 2e4);
    deformed(&mut b, wavy);
    let f = b.internal_forces().unwrap();
    let total: Vector3<f64> = f.iter().sum();
    let size: f64 = f.iter().map(|f| f.norm()).sum();
    assert!(
        size > 0.0 && total.norm() < 1e-12 * size,
        "{total:?} of {size:e}"
    );
}

/// The isotropic term's force is the exact negative gradient of its energy (`mu = 0`): central
/// differences with a step of 1e-7 m agree to 1e-6 of the largest force component. (The
/// deviatoric force of eq. 10 drops the derivative of `F_i` and is no gradient: no such
/// test for it.)
#[test]
fn the_isotropic_force_is_minus_the_gradient_of_its_energy() {
    let mut b = body([5, 4, 4], 0.02, 0.0, 2e4);
    // Large and smooth, no bond through zero length (where `|Y|` has a kink).
    deformed(&mut b, |x| wavy(x) * 0.3 + x * 0.7);
    let f = b.internal_forces().unwrap();
    let y0 = b.positions().to_vec();
    let scale = f.iter().map(|f| f.amax()).fold(0.0, f64::max);
    let step = 1e-7;
    for i in [0, 7, 23, 41, 79] {
        for c in 0..3 {
            let mut energy_at = |d: f64| {
                let mut y = y0.clone();
                y[i][c] += d;
                b.set_positions(y).unwrap();
                b.elastic_energy().unwrap()
            };
            let fd = -(energy_at(step) - energy_at(-step)) / (2.0 * step);
            assert!(
                (fd - f[i][c]).abs() < 1e-6 * scale,
                "particle {i}, axis {c}: {fd:e} against {:e}",
                f[i][c]
            );
        }
    }
}

/// f32 and f64 from one code path: the forces of a deformed block agree to 1e-4 of the
/// largest.
#[test]
fn single_precision_forces_match_double() {
    let mut b = body([6, 5, 4], 0.02, 1e4, 2e4);
    deformed(&mut b, wavy);
    let r64 = ParticleRest::<f64>::of_bodies(&[&b]).unwrap();
    let r32 = ParticleRest::<f32>::of_bodies(&[&b]).unwrap();
    let y32: Vec<Vector3<f32>> = b.positions().iter().map(|p| p.map(|c| c as f32)).collect();
    let mut g64 = vec![Vector3::zeros(); r64.indices.len()];
    let mut g32 = vec![Vector3::zeros(); r32.indices.len()];
    let (mut e64, mut e32) = (vec![0.0; y32.len()], vec![0.0f32; y32.len()]);
    evaluate_particles(&r64, b.positions(), &mut g64, &mut e64);
    evaluate_particles(&r32, &y32, &mut g32, &mut e32);
    let f64s: Vec<_> = (0..y32.len())
        .map(|i| particle_force(i, &r64, &g64))
        .collect();
    let scale = f64s.iter().map(|f| f.amax()).fold(0.0, f64::max);
    for (i, f64) in f64s.iter().enumerate() {
        let f32 = particle_force(i, &r32, &g32).map(f64::from);
        assert!((f32 - f64).amax() < 1e-4 * scale, "particle {i}");
    }
}

/// The kernel at `y` against the local step taken one bond at a time in bond order (`F_i`,
/// the mean strain, then [`bond_force`] per bond): the same bits, forces and energies.
fn assert_kernel_is_bondwise<T: crate::real::Real>(rest: &ParticleRest<T>, y: &[Vector3<T>]) {
    let mut g = vec![Vector3::zeros(); rest.indices.len()];
    let mut energy = vec![T::zero(); y.len()];
    evaluate_particles(rest, y, &mut g, &mut energy);
    for i in 0..y.len() {
        let row = rest.row(i);
        let (mut sum, mut strain) = (Matrix3::zeros(), T::zero());
        for b in row.clone() {
            let (bond, d) = (&rest.bonds[b], y[rest.indices[b] as usize] - y[i]);
            sum += (d * bond.weight) * bond.xi.transpose();
            strain += bond.share * (d.norm() - bond.length);
        }
        let f = uninverted(sum * rest.shape_inverse[i]);
        let pressure = rest.dilatation[i] * strain;
        let mut e_i = T::of(0.5) * pressure * strain;
        for b in row {
            let d = y[rest.indices[b] as usize] - y[i];
            let (g_b, e) = bond_force(&rest.bonds[b], &f, &d, pressure);
            e_i += e;
            assert_eq!(g[b], g_b, "{} bond {b} of particle {i}", T::NAME);
        }
        assert_eq!(energy[i], e_i, "{} energy of particle {i}", T::NAME);
    }
}

/// The kernel's SIMD packs of bonds (eight f32 or four f64 lanes) give bit for bit the local
/// step of one bond at a time, in both precisions: on a deformed block whose rows have every
/// length (corners, edges, faces), with a collapsed bond (`Y = 0`, no direction) in a pack.
#[test]
fn packed_bonds_match_one_bond_at_a_time_bit_for_bit() {
    let mut b = young_body([6, 5, 4], 0.02, 2e5, 0.3);
    deformed(&mut b, wavy);
    let mut y = b.positions().to_vec();
    y[7] = y[8];
    let r64 = ParticleRest::<f64>::of_bodies(&[&b]).unwrap();
    let r32 = ParticleRest::<f32>::of_bodies(&[&b]).unwrap();
    assert!(
        r64.row(7).any(|k| r64.indices[k] == 8),
        "7 and 8 are bonded"
    );
    let y32: Vec<Vector3<f32>> = y.iter().map(|p| p.map(|c| c as f32)).collect();
    assert_kernel_is_bondwise(&r64, &y);
    assert_kernel_is_bondwise(&r32, &y32);
}

/// A single layer has no three-dimensional neighbourhood: refused, naming a particle.
#[test]
fn a_flat_layer_is_refused_naming_a_particle() {
    let params = ParticleParams {
        spacing: 0.01,
        density: 1000.0,
        horizon: None,
        material: Elastic::Paper { mu: 1.0, lam: 1.0 },
    };
    let err = Particles::new(lattice([5, 5, 1], 0.01), params).unwrap_err();
    assert!(err.to_string().contains("particle 0"), "{err}");
}

fn young_body(n: [usize; 3], spacing: f64, e: f64, nu: f64) -> Particles {
    let params = ParticleParams {
        spacing,
        density: 1000.0,
        horizon: None,
        material: Elastic::Young { e, nu },
    };
    Particles::new(lattice(n, spacing), params).unwrap()
}

/// The elastic constants measured on the centre of a 9^3 block (a full horizon, every
/// neighbour with a full one), from its energy under small affine strains: `C11` from a
/// uniaxial strain, `C11 + C12` from an equal biaxial one, then Young's modulus and Poisson's
/// ratio along the lattice axes. They match what `Elastic::Young` asked for within 1e-4
/// (the issue asks 5 %) for nu from 0 to 0.45, through the dilatation term.
#[test]
fn the_bulk_has_the_asked_young_modulus_and_poisson_ratio() {
    let (spacing, e_asked) = (0.01f64, 2e5);
    let centre = 4 + 9 * 4 + 81 * 4;
    let v = spacing.powi(3);
    for nu in [0.0, 0.1, 0.25, 0.4, 0.45] {
        let mut b = young_body([9, 9, 9], spacing, e_asked, nu);
        let eps = 1e-6;
        let mut density = |strain: Matrix3<f64>| {
            let f = Matrix3::identity() + strain;
            deformed(&mut b, |x| f * x);
            b.particle_energies().unwrap()[centre] / v
        };
        let c11 = 2.0 * density(Matrix3::from_diagonal(&Vector3::new(eps, 0.0, 0.0))) / (eps * eps);
        let biaxial = density(Matrix3::from_diagonal(&Vector3::new(eps, eps, 0.0))) / (eps * eps);
        let c12 = biaxial - c11;
        let young = (c11 - c12) * (c11 + 2.0 * c12) / (c11 + c12);
        let poisson = c12 / (c11 + c12);
        assert!((young / e_asked - 1.0).abs() < 1e-4, "nu {nu}: E {young:e}");
        assert!((poisson - nu).abs() < 1e-4, "nu {nu}: measured {poisson}");
    }
}

/// With the deviatoric springs taken out (`k_dev = 0`), the force of a calibrated body (its
/// isotropic springs with the surface correction, and the dilatation term, nu = 0.4 and 0.1:
/// `kappa` of either sign) is minus the gradient of its energy: central differences with a
/// step of 1e-7 m agree to 1e-6 of the largest force component.
#[test]
fn the_dilatation_force_is_minus_the_gradient_of_its_energy() {
    for nu in [0.4, 0.1] {
        let b = young_body([5, 4, 4], 0.02, 1e5, nu);
        assert!(b.moduli().kappa != 0.0);
        let mut rest = ParticleRest::<f64>::of_bodies(&[&b]).unwrap();
        for bond in &mut rest.bonds {
            bond.k_dev = 0.0;
        }
        let n = b.num_particles();
        let mut bonds = vec![Vector3::zeros(); rest.indices.len()];
        let mut energy = vec![0.0; n];
        let y0: Vec<_> = b
            .reference()
            .iter()
            .map(|x| wavy(x) * 0.3 + x * 0.7)
            .collect();
        let mut at = |y: &[Vector3<f64>]| {
            evaluate_particles(&rest, y, &mut bonds, &mut energy);
            let f: Vec<_> = (0..n).map(|i| particle_force(i, &rest, &bonds)).collect();
            (energy.iter().sum::<f64>(), f)
        };
        let (_, f) = at(&y0);
        let scale = f.iter().map(|f| f.amax()).fold(0.0, f64::max);
        let step = 1e-7;
        for i in [0, 7, 23, 41, 79] {
            for c in 0..3 {
                let mut energy_at = |d: f64| {
                    let mut y = y0.clone();
                    y[i][c] += d;
                    at(&y).0
                };
                let fd = -(energy_at(step) - energy_at(-step)) / (2.0 * step);
                assert!(
                    (fd - f[i][c]).abs() < 1e-6 * scale,
                    "nu {nu}, particle {i}, axis {c}: {fd:e} against {:e}",
                    f[i][c]
                );
            }
        }
    }
}

/// A calibrated body (dilatation term, surface correction) moved rigidly feels no force (1e-9
/// of the forces of a 1 % stretch), and its forces balance under a large deformation (1e-12).
#[test]
fn a_calibrated_body_is_force_free_in_rigid_motion_and_balanced() {
    let mut b = young_body([6, 5, 4], 0.02, 1e5, 0.4);
    deformed(&mut b, |x| Vector3::new(1.01 * x.x, x.y, x.z));
    let largest = |b: &Particles| {
        let f = b.internal_forces().unwrap();
        f.iter().map(|f| f.norm()).fold(0.0, f64::max)
    };
    let scale = largest(&b);
    let rot = nalgebra::Rotation3::from_euler_angles(1.1, 0.4, -2.0);
    deformed(&mut b, |x| rot * x + Vector3::new(3.0, -1.0, 0.5));
    let worst = largest(&b);
    assert!(
        scale > 0.0 && worst < 1e-9 * scale,
        "{worst:e} against {scale:e}"
    );
    deformed(&mut b, wavy);
    let f = b.internal_forces().unwrap();
    let total: Vector3<f64> = f.iter().sum();
    let size: f64 = f.iter().map(|f| f.norm()).sum();
    assert!(total.norm() < 1e-12 * size, "{total:?} of {size:e}");
}

/// Poisson ratios outside [0, 0.45] and a non-finite position are refused by name.
#[test]
fn bad_materials_and_positions_are_refused_by_name() {
    for nu in [-0.1, 0.46, f64::NAN] {
        let err = Elastic::Young { e: 1e5, nu }.validate().unwrap_err();
        assert!(err.to_string().contains("nu"), "{err}");
    }
    let mut x = lattice([3, 3, 3], 0.01);
    x[5].y = f64::INFINITY;
    let params = ParticleParams {
        spacing: 0.01,
        density: 1000.0,
        horizon: None,
        material: Elastic::Young { e: 1e5, nu: 0.3 },
    };
    let err = Particles::new(x, params).unwrap_err();
    assert!(err.to_string().contains("particle 5"), "{err}");
}
