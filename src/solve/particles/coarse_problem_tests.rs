//! Known answers of the coarse problem's projected Gauss-Seidel ([`super::Coarse::solve`]):
//! analytic solutions of small problems, the KKT conditions (of translations and of affine
//! fields) and the `M`-norm bound.

use approx::assert_relative_eq;
use nalgebra::{Matrix3, Vector3};

use super::{Coarse, Contact};

/// A problem of bodies of masses `mass` (kg) and net residuals `force` (kg m) with `contacts`,
/// solved from `t0 = F / M` as [`super::super::coarse`] starts it.
fn solved(mass: &[f64], force: &[Vector3<f64>], contacts: Vec<Contact>) -> Coarse {
    let mut coarse = Coarse::new(vec![true; mass.len()]);
    for (b, (&m, f)) in mass.iter().zip(force).enumerate() {
        coarse.inverse_mass[b] = 1.0 / m;
        coarse.force[b] = *f;
        coarse.translation[b] = f / m;
    }
    coarse.contacts = contacts;
    coarse.solve();
    coarse
}

fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

/// `n . (u_a(l_a) - u_b(l_b))` of contact `c`, `u_b(l) = t_b + A_b l`.
fn relative(coarse: &Coarse, c: &Contact) -> f64 {
    let u = |b: usize, l: &Vector3<f64>| coarse.translation[b] + coarse.affine[b] * l;
    c.n.dot(&(u(c.a, &c.lever_a) - c.b.map_or(Vector3::zeros(), |b| u(b, &c.lever_b))))
}

/// Asserts the KKT conditions to `1e-10` relative, the bodies' affine stiffnesses
/// `stiffness` (kg m^2; zero for translations only): stationarity `M_b t_b - F_b = sum_c
/// lambda_c n_c` and `A_b K_b - R_b = sum_c lambda_c n_c l_c^T` (`+` where `b` is the
/// contact's `a`, `-` where it is its `b`), feasibility, `lambda >= 0` of an inequality and
/// complementarity `lambda_c (n . (u_a - u_b) - bound) = 0`.
fn assert_kkt(coarse: &Coarse, stiffness: &[Matrix3<f64>]) {
    let n = coarse.translation.len();
    let scale_t = (0..n)
        .map(|b| {
            let t0 = coarse.force[b] * coarse.inverse_mass[b];
            let a0 = coarse.moment[b] * coarse.compliance[b];
            t0.norm() + a0.norm() * coarse.radius[b]
        })
        .fold(0.0, f64::max);
    let scale_f = coarse.force.iter().map(|f| f.norm()).fold(0.0, f64::max);
    let scale_r = coarse.moment.iter().map(|r| r.norm()).fold(0.0, f64::max);
    let mut reaction = vec![Vector3::zeros(); n];
    let mut moment = vec![Matrix3::zeros(); n];
    for c in &coarse.contacts {
        reaction[c.a] += c.n * c.lambda;
        moment[c.a] += c.n * c.lever_a.transpose() * c.lambda;
        if let Some(b) = c.b {
            reaction[b] -= c.n * c.lambda;
            moment[b] -= c.n * c.lever_b.transpose() * c.lambda;
        }
        let slack = relative(coarse, c) - c.bound;
        if c.equality {
            assert!(slack.abs() <= 1e-10 * scale_t, "equality off by {slack}");
        } else {
            assert!(slack >= -1e-10 * scale_t, "contact violated by {slack}");
            assert!(c.lambda >= 0.0, "negative multiplier {}", c.lambda);
            assert!(
                (c.lambda * slack).abs() <= 1e-10 * scale_f * scale_t,
                "complementarity {} x {slack}",
                c.lambda
            );
        }
    }
    for (b, reaction) in reaction.iter().enumerate() {
        let m = 1.0 / coarse.inverse_mass[b];
        let stationarity = coarse.translation[b] * m - coarse.force[b] - reaction;
        assert!(
            stationarity.norm() <= 1e-10 * scale_f,
            "body {b}: stationarity off by {stationarity}"
        );
        let affine = coarse.affine[b] * stiffness[b] - coarse.moment[b] - moment[b];
        assert!(
            affine.norm() <= 1e-10 * scale_r.max(scale_f * coarse.radius[b]),
            "body {b}: affine stationarity off by {affine}"
        );
    }
}

/// `sum_b M_b |t_b|^2` (kg m^2).
fn m_norm2(mass: &[f64], t: &[Vector3<f64>]) -> f64 {
    mass.iter().zip(t).map(|(m, t)| m * t.norm_squared()).sum()
}

#[test]
fn body_pushed_into_a_plane_stops_at_the_gap_and_keeps_its_tangential_move() {
    // A body of 2 kg, 1 m above a plane z = 0, asked to move by (1, 0.5, -4) m.
    let force = [v(1.0, 0.5, -4.0) * 2.0];
    let plane = Contact::new(0, None, Vector3::z(), -1.0, false);
    let coarse = solved(&[2.0], &force, vec![plane]);
    assert_relative_eq!(coarse.translation[0], v(1.0, 0.5, -1.0), epsilon = 1e-12);
    // The plane pushes with `lambda = M (t_n - t0_n) = 2 x 3` (N s^2).
    assert_relative_eq!(coarse.contacts[0].lambda, 6.0, epsilon = 1e-12);
    assert_kkt(&coarse, &[Matrix3::zeros(); 4]);

    // Moving away from the plane, the contact is idle.
    let force = [v(1.0, 0.5, 4.0) * 2.0];
    let coarse = solved(&[2.0], &force, vec![plane]);
    assert_eq!(coarse.translation[0], v(1.0, 0.5, 4.0));
    assert_eq!(coarse.contacts[0].lambda, 0.0);
}

#[test]
fn two_free_bodies_pressed_together_keep_their_momentum_and_close_the_gap() {
    // Body 0 (1 kg) lies 0.5 m along +x of body 1 (3 kg); the normal points from 1 to 0.
    let mass = [1.0, 3.0];
    let force = [v(-2.0, 1.0, 0.0), v(1.0, 0.0, 0.0) * 3.0];
    let pair = Contact::new(0, Some(1), Vector3::x(), -0.5, false);
    let coarse = solved(&mass, &force, vec![pair]);
    let t = &coarse.translation;
    // Momentum along x: t_0 + 3 t_1 = -2 + 3 with t_0 - t_1 = -0.5.
    assert_relative_eq!(t[0], v(-0.125, 1.0, 0.0), epsilon = 1e-12);
    assert_relative_eq!(t[1], v(0.375, 0.0, 0.0), epsilon = 1e-12);
    let momentum = t[0] * mass[0] + t[1] * mass[1];
    assert_relative_eq!(momentum, force[0] + force[1], epsilon = 1e-12);
    assert_relative_eq!(
        relative(&coarse, &coarse.contacts[0]),
        -0.5,
        epsilon = 1e-12
    );
    assert_kkt(&coarse, &[Matrix3::zeros(); 4]);
}

#[test]
fn frictional_equalities_hold_the_tangential_translation_at_zero() {
    // A body resting on a frictional plane (gap 0): normal contact and two tangential
    // equalities, as `gather_contacts` builds them.
    let contacts = vec![
        Contact::new(0, None, Vector3::z(), 0.0, false),
        Contact::new(0, None, Vector3::x(), 0.0, true),
        Contact::new(0, None, Vector3::y(), 0.0, true),
    ];
    // Pushed into the plane and along it: it does not move; the equalities pull back against
    // +x (a negative multiplier) and push against -y.
    let coarse = solved(&[4.0], &[v(3.0, -2.0, -1.0) * 4.0], contacts.clone());
    assert_relative_eq!(coarse.translation[0], Vector3::zeros(), epsilon = 1e-12);
    assert_relative_eq!(coarse.contacts[1].lambda, -12.0, epsilon = 1e-12);
    assert_relative_eq!(coarse.contacts[2].lambda, 8.0, epsilon = 1e-12);
    assert_kkt(&coarse, &[Matrix3::zeros(); 4]);
    // Lifted off it: only the normal move remains.
    let coarse = solved(&[4.0], &[v(3.0, -2.0, 5.0) * 4.0], contacts);
    assert_relative_eq!(coarse.translation[0], v(0.0, 0.0, 5.0), epsilon = 1e-12);
    assert_kkt(&coarse, &[Matrix3::zeros(); 4]);
}

/// A deterministic value in `[-1, 1]` of `k`.
fn wave(k: usize) -> f64 {
    (k as f64 * 12.9898 + 0.3).sin()
}

/// A unit vector that is `axis` tilted by up to about 0.3 rad, varying with `k`.
fn tilted(axis: Vector3<f64>, k: usize) -> Vector3<f64> {
    (axis + v(wave(3 * k), wave(3 * k + 1), wave(3 * k + 2)) * 0.3).normalize()
}

/// A stack of four bodies on a floor against a wall, one contact per pair, with tilted
/// normals, gaps `> 0` (bounds `< 0`) and unconstrained moves that press the stack down and
/// sideways. (With several contacts per pair, as one per particle, the solve leaves gaps
/// violated by up to 1e-2 of the move at its cap of [`super::MAX_SWEEPS`] sweeps: it needs
/// thousands to reach its tolerance there.)
fn stack() -> (Vec<f64>, Vec<Vector3<f64>>, Vec<Contact>) {
    let mass = vec![2.0, 1.0, 3.0, 0.5];
    let force: Vec<Vector3<f64>> = (0..4)
        .map(|b| {
            v(
                0.7 + 0.2 * wave(b),
                0.3 * wave(b + 7),
                -1.0 - 0.5 * b as f64,
            ) * mass[b]
        })
        .collect();
    let floor = Contact::new(
        0,
        None,
        tilted(Vector3::z(), 1),
        -0.05 * (1.0 + wave(1)),
        false,
    );
    let mut contacts = vec![floor];
    for b in 1..4 {
        let gap = 0.02 * (1.0 + wave(b + 1));
        contacts.push(Contact::new(
            b,
            Some(b - 1),
            tilted(Vector3::z(), b + 1),
            -gap,
            false,
        ));
    }
    contacts.push(Contact::new(2, None, tilted(-Vector3::x(), 5), 0.0, false));
    (mass, force, contacts)
}

#[test]
fn stack_meets_the_kkt_conditions() {
    let (mass, force, contacts) = stack();
    let coarse = solved(&mass, &force, contacts);
    assert_kkt(&coarse, &[Matrix3::zeros(); 4]);
    // The floor and the contacts within the stack act.
    assert!(coarse.contacts[0].lambda > 0.0);
}

#[test]
fn solution_is_no_longer_in_the_mass_norm_than_the_unconstrained_move() {
    let (mass, force, contacts) = stack();
    let t0: Vec<_> = force.iter().zip(&mass).map(|(f, m)| f / *m).collect();
    let coarse = solved(&mass, &force, contacts);
    let (solution, free) = (m_norm2(&mass, &coarse.translation), m_norm2(&mass, &t0));
    assert!(solution <= free, "{solution} > {free}");
    assert!(
        solution < 0.9 * free,
        "the contacts must cut the move: {solution} vs {free}"
    );
}

/// Two affine bodies of 2 and 1 kg, the lower one on a floor at four corners, the upper one on
/// the lower at four corners, tilted normals and gaps `>= 0`, pressed down, compressed and
/// sheared: the solve meets the KKT conditions, the floor and the pairs act, and the floor
/// pushing up at its bottom and the upper body pressing on its top compress the lower body
/// further (its `A_zz` falls below the unconstrained one).
#[test]
fn affine_bodies_on_a_floor_meet_the_kkt_conditions() {
    let mass = [2.0, 1.0];
    let stiffness = [
        Matrix3::new(0.02, 0.003, 0.0, 0.003, 0.03, 0.001, 0.0, 0.001, 0.025),
        Matrix3::new(0.012, 0.0, 0.002, 0.0, 0.01, 0.0, 0.002, 0.0, 0.015),
    ];
    let force = [v(0.3, -0.1, -2.0) * mass[0], v(-0.2, 0.1, -3.0) * mass[1]];
    let moment = [
        Matrix3::new(0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0, -0.03) * 0.02,
        Matrix3::new(0.0, 0.004, 0.0, 0.0, 0.0, 0.0, 0.01, 0.0, -0.02) * 0.01,
    ];
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    let mut contacts = Vec::new();
    for (k, &(x, y)) in corners.iter().enumerate() {
        let bottom = v(0.1 * x, 0.1 * y, -0.1);
        let floor = Contact::new(
            0,
            None,
            tilted(Vector3::z(), k),
            -0.01 * (1.0 + wave(k)),
            false,
        );
        contacts.push(floor.at(bottom, Vector3::zeros()));
        let top = v(0.1 * x, 0.1 * y, 0.1);
        let pair = Contact::new(
            1,
            Some(0),
            tilted(Vector3::z(), k + 4),
            -0.005 * (1.0 + wave(k + 4)),
            false,
        );
        contacts.push(pair.at(bottom * 0.8, top));
    }
    let mut coarse = Coarse::new(vec![true; 2]);
    for b in 0..2 {
        coarse.inverse_mass[b] = 1.0 / mass[b];
        coarse.force[b] = force[b];
        coarse.translation[b] = force[b] / mass[b];
        coarse.compliance[b] = stiffness[b].try_inverse().unwrap();
        coarse.moment[b] = moment[b];
        coarse.affine[b] = moment[b] * coarse.compliance[b];
        coarse.radius[b] = 0.1 * 3f64.sqrt();
    }
    let free_compression = coarse.affine[0][(2, 2)];
    coarse.contacts = contacts;
    coarse.solve();
    assert_kkt(&coarse, &stiffness);
    let acting = |b: Option<usize>| {
        coarse
            .contacts
            .iter()
            .filter(|c| c.b == b && c.lambda > 0.0)
            .count()
    };
    assert!(
        acting(None) >= 2 && acting(Some(0)) >= 2,
        "{:?}",
        coarse.contacts
    );
    assert!(
        coarse.affine[0][(2, 2)] < free_compression,
        "A_zz {} against {free_compression} unconstrained",
        coarse.affine[0][(2, 2)]
    );
}
