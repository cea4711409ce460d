//! Known answers of the coarse problem's projected Gauss-Seidel ([`super::Coarse::solve`]):
//! analytic solutions of small problems, the KKT conditions and the `M`-norm bound.

use approx::assert_relative_eq;
use nalgebra::Vector3;

use super::{Coarse, Contact, Friction};

/// A problem of bodies of masses `mass` (kg) and net residuals `force` (kg m) with `contacts`,
/// solved from `t0 = F / M` as [`super::super::coarse`] starts it.
fn solved(mass: &[f64], force: &[Vector3<f64>], contacts: Vec<Contact>) -> Coarse {
    solved_with_friction(mass, force, contacts, Vec::new())
}

/// [`solved`] with Coulomb `frictions` at the contacts.
fn solved_with_friction(
    mass: &[f64],
    force: &[Vector3<f64>],
    contacts: Vec<Contact>,
    frictions: Vec<Friction>,
) -> Coarse {
    let mut coarse = Coarse::new(vec![true; mass.len()]);
    for (b, (&m, f)) in mass.iter().zip(force).enumerate() {
        coarse.inverse_mass[b] = 1.0 / m;
        coarse.force[b] = *f;
        coarse.translation[b] = f / m;
    }
    coarse.contacts = contacts;
    coarse.frictions = frictions;
    coarse.solve();
    coarse
}

fn v(x: f64, y: f64, z: f64) -> Vector3<f64> {
    Vector3::new(x, y, z)
}

/// `n . (t_a - t_b)` of contact `c`.
fn relative(coarse: &Coarse, c: &Contact) -> f64 {
    let t = &coarse.translation;
    c.n.dot(&(t[c.a] - c.b.map_or(Vector3::zeros(), |b| t[b])))
}

/// Asserts the KKT conditions to `1e-10` relative: stationarity `M_b t_b - F_b = sum_c
/// lambda_c n_c + sum_f phi_f` (`+` where `b` is the contact's `a`, `-` where it is its `b`),
/// feasibility, `lambda >= 0` and complementarity `lambda_c (n . (t_a - t_b) - bound) = 0`,
/// and Coulomb's law at each friction: `|phi| <= mu lambda`, the slip `s + t_a` zero inside
/// the cone and opposed by `phi` on its edge.
fn assert_kkt(coarse: &Coarse) {
    let n = coarse.translation.len();
    let scale_t = coarse
        .force
        .iter()
        .zip(&coarse.inverse_mass)
        .map(|(f, w)| (f * *w).norm())
        .fold(0.0, f64::max);
    let scale_f = coarse.force.iter().map(|f| f.norm()).fold(0.0, f64::max);
    let mut reaction = vec![Vector3::zeros(); n];
    for c in &coarse.contacts {
        reaction[c.a] += c.n * c.lambda;
        if let Some(b) = c.b {
            reaction[b] -= c.n * c.lambda;
        }
        let slack = relative(coarse, c) - c.bound;
        assert!(slack >= -1e-10 * scale_t, "contact violated by {slack}");
        assert!(c.lambda >= 0.0, "negative multiplier {}", c.lambda);
        assert!(
            (c.lambda * slack).abs() <= 1e-10 * scale_f * scale_t,
            "complementarity {} x {slack}",
            c.lambda
        );
    }
    for f in &coarse.frictions {
        let phi = f.reaction();
        reaction[f.a] += phi;
        let bound = f.bound(coarse.contacts[f.normal].lambda);
        assert!(
            phi.norm() <= bound * (1.0 + 1e-12),
            "outside the cone: {phi}"
        );
        let t = &coarse.translation[f.a];
        let slip = f.tangents[0] * (f.slip[0] + f.tangents[0].dot(t))
            + f.tangents[1] * (f.slip[1] + f.tangents[1].dot(t));
        if phi.norm() < bound * (1.0 - 1e-9) {
            assert!(slip.norm() <= 1e-10 * scale_t, "sticks but slips {slip}");
        } else if slip.norm() > 1e-10 * scale_t {
            let opposed = phi + slip.normalize() * bound;
            assert!(
                opposed.norm() <= 1e-9 * scale_f,
                "slides along {slip}, friction {phi}"
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
    let plane = Contact::new(0, None, Vector3::z(), -1.0);
    let coarse = solved(&[2.0], &force, vec![plane]);
    assert_relative_eq!(coarse.translation[0], v(1.0, 0.5, -1.0), epsilon = 1e-12);
    // The plane pushes with `lambda = M (t_n - t0_n) = 2 x 3` (N s^2).
    assert_relative_eq!(coarse.contacts[0].lambda, 6.0, epsilon = 1e-12);
    assert_kkt(&coarse);

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
    let pair = Contact::new(0, Some(1), Vector3::x(), -0.5);
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
    assert_kkt(&coarse);
}

/// A body of 4 kg resting on a plane `z = 0` with friction 0.5 at one particle whose slip
/// over the step so far is `slip` (m), asked to move by `t0` (m).
fn on_a_rough_plane(t0: Vector3<f64>, slip: Vector3<f64>) -> Coarse {
    let plane = Contact::new(0, None, Vector3::z(), 0.0);
    let friction = Friction::new(0, 0, &Vector3::z(), &slip, 0.5, &Vector3::zeros());
    solved_with_friction(&[4.0], &[t0 * 4.0], vec![plane], vec![friction])
}

#[test]
fn friction_within_the_cone_stops_the_slip() {
    // Pushed into the plane by 1 m and along it by (0.3, -0.2) with a slip of (0.1, 0.05):
    // stopping it takes a tangential reaction 4 |(0.4, -0.15)| = 1.71 within 0.5 x 4.
    let coarse = on_a_rough_plane(v(0.3, -0.2, -1.0), v(0.1, 0.05, 0.0));
    assert_relative_eq!(coarse.translation[0], v(-0.1, -0.05, 0.0), epsilon = 1e-12);
    assert_relative_eq!(coarse.contacts[0].lambda, 4.0, epsilon = 1e-12);
    assert_relative_eq!(
        coarse.frictions[0].reaction(),
        v(-1.6, 0.6, 0.0),
        epsilon = 1e-12
    );
    assert_kkt(&coarse);
}

#[test]
fn friction_beyond_the_cone_slows_the_slide_by_mu_times_the_normal_move() {
    // A slide of 3 m along x pressed by 0.2 m: friction takes 0.5 x 0.2 off the slide and
    // nothing across it.
    let coarse = on_a_rough_plane(v(3.0, 0.0, -0.2), v(0.0, 0.0, 0.0));
    assert_relative_eq!(coarse.translation[0], v(2.9, 0.0, 0.0), epsilon = 1e-12);
    assert_kkt(&coarse);
    // Lifted off the plane it slides freely.
    let coarse = on_a_rough_plane(v(3.0, 1.0, 0.5), v(0.2, 0.0, 0.0));
    assert_relative_eq!(coarse.translation[0], v(3.0, 1.0, 0.5), epsilon = 1e-12);
    assert_kkt(&coarse);
}

#[test]
fn sticking_friction_holds_the_tangential_translation_at_zero() {
    // A granular body of 4 kg on a frictional plane (gap 0), as `gather_contacts` builds its
    // contact: the normal row and unbounded friction with no slip.
    let contacts = vec![Contact::new(0, None, Vector3::z(), 0.0)];
    let frictions = vec![Friction::sticking(0, 0, &Vector3::z())];
    // Pushed into the plane by 1 m and along it by (3, -2): it stays put, the plane pushes
    // back with M t0_n = 4 and the friction with -M t0_t = (-12, 8, 0) (N s^2).
    let force = [v(3.0, -2.0, -1.0) * 4.0];
    let coarse = solved_with_friction(&[4.0], &force, contacts.clone(), frictions.clone());
    assert_relative_eq!(coarse.translation[0], Vector3::zeros(), epsilon = 1e-12);
    assert_relative_eq!(coarse.contacts[0].lambda, 4.0, epsilon = 1e-12);
    assert_relative_eq!(
        coarse.frictions[0].reaction(),
        v(-12.0, 8.0, 0.0),
        epsilon = 1e-12
    );
    assert_kkt(&coarse);
    // Lifted off it (no normal reaction), the unbounded friction still holds the tangential
    // translation: only the normal move remains.
    let force = [v(3.0, -2.0, 5.0) * 4.0];
    let coarse = solved_with_friction(&[4.0], &force, contacts, frictions);
    assert_relative_eq!(coarse.translation[0], v(0.0, 0.0, 5.0), epsilon = 1e-12);
    assert_eq!(coarse.contacts[0].lambda, 0.0);
    assert_relative_eq!(
        coarse.frictions[0].reaction(),
        v(-12.0, 8.0, 0.0),
        epsilon = 1e-12
    );
    assert_kkt(&coarse);
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
    let floor = Contact::new(0, None, tilted(Vector3::z(), 1), -0.05 * (1.0 + wave(1)));
    let mut contacts = vec![floor];
    for b in 1..4 {
        let gap = 0.02 * (1.0 + wave(b + 1));
        contacts.push(Contact::new(
            b,
            Some(b - 1),
            tilted(Vector3::z(), b + 1),
            -gap,
        ));
    }
    contacts.push(Contact::new(2, None, tilted(-Vector3::x(), 5), 0.0));
    (mass, force, contacts)
}

#[test]
fn stack_meets_the_kkt_conditions() {
    let (mass, force, contacts) = stack();
    let coarse = solved(&mass, &force, contacts);
    assert_kkt(&coarse);
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
