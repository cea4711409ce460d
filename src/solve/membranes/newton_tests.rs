//! Tests of the Newton method: its Hessian model against central differences of the exact
//! gradient (per vertex and assembled), positive semi-definiteness, and the solver: the same
//! implicit Euler solution as SISSM (alone, with a collider, with contact), an energy that
//! never rises, bit-identical threads, f32 against f64.

use nalgebra::{Rotation3, Vector3};

use super::evaluate::evaluate;
use super::hessian_model::VertexModel;
use super::jacobi::jacobi_block;
use super::newton::NewtonState;
use super::system::MembraneSystem;
use crate::collider::{Collider, Shape};
use crate::contact::ContactParams;
use crate::material::Material;
use crate::membrane::RestData;
use crate::membrane::{bond_vectors, vertex_kernel, Membrane, MembraneParams, Preconditioner};
use crate::mesh::TriangleMesh;
use crate::real::Real;
use crate::solve::point_system::PointSystem;
use crate::solve::{Acceleration, Method, Solver, SolverParams};
use crate::test_rng::Rng;

fn params(material: Material, bending: f64, hourglass: f64, neighbors: usize) -> MembraneParams {
    MembraneParams {
        thickness: 1e-3,
        density: 300.0,
        material,
        bending,
        hourglass,
        neighbors,
    }
}

fn materials() -> [Material; 2] {
    [
        Material::stretch_a3(2e4).unwrap(),
        Material::neo_hookean(4.8e7, 1.2e7).unwrap(),
    ]
}

/// A 7 x 6 sheet mapped by `map` (rest positions in, deformed out).
fn deformed(p: MembraneParams, mut map: impl FnMut(Vector3<f64>) -> Vector3<f64>) -> Membrane {
    let mut m = Membrane::new(TriangleMesh::grid(7, 6, 0.3, 0.25).unwrap(), p).unwrap();
    let y = m.positions().iter().map(|x| map(*x)).collect();
    m.set_positions(y).unwrap();
    m
}

/// A rotated, sheared in-plane stretch (every principal stretch above 1: all stresses and
/// curvatures of the energy positive).
fn stretched(x: Vector3<f64>) -> Vector3<f64> {
    let rot = Rotation3::from_scaled_axis(Vector3::new(0.3, -0.2, 0.5));
    rot * Vector3::new(1.12 * x.x + 0.04 * x.y, 0.03 * x.x + 1.07 * x.y, x.z)
}

/// A vertex, the model's product with bond displacements, and the difference of the gradient.
type VertexProducts = (usize, Vec<Vector3<f64>>, Vec<Vector3<f64>>);

/// Per vertex of `m` at its positions: the model's product with random bond displacements
/// `dx`, and the central difference of the exact bond gradient along `dx`; yields
/// `(vertex, model, difference)` with the bond rows stacked.
fn model_and_difference(m: &Membrane, rng: &mut Rng) -> Vec<VertexProducts> {
    let nb = m.neighborhood().clone();
    let mut rest = RestData::<f64>::empty();
    rest.extend_from(&m.rest_source().unwrap(), true).unwrap();
    let y = m.positions();
    (0..y.len())
        .map(|i| {
            let stencil = rest.stencil(&nb, i);
            let n = nb.of(i).len();
            let mut edges = vec![Vector3::zeros(); n];
            bond_vectors(i, y, nb.of(i), &mut edges);
            let model = VertexModel::of(&stencil, &edges);
            let dx: Vec<Vector3<f64>> = (0..n).map(|_| rng.vector() * 0.01).collect();
            let mut product = dx.clone();
            model.apply(&stencil, &mut product);
            let eps = 1e-6;
            let gradient = |s: f64| {
                let mut e: Vec<Vector3<f64>> =
                    edges.iter().zip(&dx).map(|(e, d)| e + d * s).collect();
                vertex_kernel(&stencil, Preconditioner::Tangent, &mut e);
                e
            };
            let (plus, minus) = (gradient(eps), gradient(-eps));
            let difference = plus
                .iter()
                .zip(&minus)
                .map(|(a, b)| (a - b) / (2.0 * eps))
                .collect();
            (i, product, difference)
        })
        .collect()
}

fn largest(v: &[Vector3<f64>]) -> f64 {
    v.iter().map(|x| x.amax()).fold(0.0, f64::max)
}

/// Where the model is exact it equals the central difference of the kernel's exact gradient
/// (itself tested against differences of the energy), within 1e-6 of the largest entry, at
/// every vertex of a 7 x 6 sheet, both materials, 1-ring and 2-ring stencils:
/// - stretching alone (no bending, no hourglass) at a randomly perturbed stretch: the
///   projected Hessian is the exact one wherever its six eigenvalues are positive;
/// - stretching, bending and hourglass at an affine stretch of the flat sheet, where the
///   non-affine residuals vanish and Gauss-Newton is exact.
#[test]
fn the_model_is_the_exact_hessian_where_it_should_be() {
    let mut rng = Rng::new(0x44);
    for material in materials() {
        for neighbors in [1, 2] {
            let mut noise = Rng::new(7);
            let stretch_only = deformed(params(material, 0.0, 0.0, neighbors), |x| {
                stretched(x) + noise.vector() * 2e-4
            });
            let bending = 100.0 * material.shear_modulus() * 1e-9;
            let all_terms = deformed(params(material, bending, 0.5, neighbors), stretched);
            for (case, m) in [("stretch", &stretch_only), ("affine", &all_terms)] {
                for (i, product, difference) in model_and_difference(m, &mut rng) {
                    let scale = largest(&difference);
                    let error = product
                        .iter()
                        .zip(&difference)
                        .map(|(a, b)| (a - b).amax())
                        .fold(0.0, f64::max);
                    assert!(
                        scale > 0.0 && error <= 1e-6 * scale,
                        "{material:?} {neighbors}-ring {case} vertex {i}: error {error:e} of \
                         {scale:e}"
                    );
                }
            }
        }
    }
}

/// The model is positive semi-definite: `dx . H dx >= 0` (to round-off) at randomly
/// compressed, stretched and crumpled states, where the exact Hessian is indefinite; and at
/// compression the exact one is indefinite somewhere, so the projection is exercised.
#[test]
fn the_model_is_positive_semidefinite() {
    let mut rng = Rng::new(0x45);
    for material in materials() {
        for scale in [0.7, 0.95, 1.2] {
            let mut noise = Rng::new(11);
            let m = deformed(params(material, 1e-5, 0.5, 1), |x| {
                stretched(x) * scale + noise.vector() * 0.02
            });
            let mut indefinite = 0;
            let nb = m.neighborhood().clone();
            let mut rest = RestData::<f64>::empty();
            rest.extend_from(&m.rest_source().unwrap(), true).unwrap();
            for i in 0..m.num_vertices() {
                let stencil = rest.stencil(&nb, i);
                let n = nb.of(i).len();
                let mut edges = vec![Vector3::zeros(); n];
                bond_vectors(i, m.positions(), nb.of(i), &mut edges);
                let model = VertexModel::of(&stencil, &edges);
                for _ in 0..20 {
                    let dx: Vec<Vector3<f64>> = (0..n).map(|_| rng.vector()).collect();
                    let mut product = dx.clone();
                    model.apply(&stencil, &mut product);
                    let form: f64 = dx.iter().zip(&product).map(|(a, b)| a.dot(b)).sum();
                    let size: f64 = product.iter().map(|p| p.norm()).sum::<f64>()
                        * dx.iter().map(|d| d.norm()).fold(0.0, f64::max);
                    assert!(
                        form >= -1e-12 * size,
                        "{material:?} x{scale} vertex {i}: {form:e}"
                    );
                    // The exact second derivative along dx, by differences of the gradient.
                    let eps = 1e-6;
                    let gradient = |s: f64| {
                        let mut e: Vec<Vector3<f64>> =
                            edges.iter().zip(&dx).map(|(e, d)| e + d * s).collect();
                        vertex_kernel(&stencil, Preconditioner::Tangent, &mut e);
                        e
                    };
                    let (plus, minus) = (gradient(eps), gradient(-eps));
                    let exact: f64 = dx
                        .iter()
                        .zip(plus.iter().zip(&minus))
                        .map(|(d, (a, b))| d.dot(&((a - b) / (2.0 * eps))))
                        .sum();
                    if exact < -1e-6 * size {
                        indefinite += 1;
                    }
                }
            }
            if scale < 1.0 {
                assert!(
                    indefinite > 0,
                    "{material:?} x{scale}: exact Hessian never indefinite"
                );
            }
        }
    }
}

/// The assembled product `K x = M x + h^2 sum_i G_i^T H_i G_i x` equals
/// `M x - h^2 (f(y + eps x) - f(y - eps x)) / (2 eps)` from the exact total force
/// ([`Membrane::internal_forces`]) at an affine stretch (where the model is exact), within
/// 1e-6 of its largest entry, pinned rows zero: the gather over every stencil that holds a
/// vertex, and the signs of its bonds, are right.
#[test]
fn the_assembled_product_matches_differences_of_the_force() {
    let mut rng = Rng::new(0x46);
    for neighbors in [1, 2] {
        let material = Material::neo_hookean(2e5, 1e5).unwrap();
        let mut m = deformed(params(material, 1e-5, 0.5, neighbors), stretched);
        m.pin(&[0, 5], None).unwrap();
        let mut sys = MembraneSystem::<f64>::build(&[&mut m], true).unwrap();
        sys.points.load(&[&mut m]);
        let mut state = NewtonState::<f64>::new(&[&mut m]).unwrap();
        let y = m.positions().to_vec();
        state.build_models(&sys, &y);
        let n = y.len();
        let x: Vec<Vector3<f64>> = (0..n)
            .map(|k| {
                if k == 0 || k == 5 {
                    Vector3::zeros()
                } else {
                    rng.vector() * 0.01
                }
            })
            .collect();
        let h2 = 1e-4;
        let mut out = vec![Vector3::zeros(); n];
        state.product(&sys, h2, &x, &mut out);
        let eps = 1e-6;
        let force = |s: f64, m: &mut Membrane| {
            let moved = y.iter().zip(&x).map(|(y, x)| y + x * s).collect();
            m.set_positions(moved).unwrap();
            m.internal_forces().unwrap()
        };
        let (plus, minus) = (force(eps, &mut m), force(-eps, &mut m));
        let masses = m.masses();
        let reference: Vec<Vector3<f64>> = (0..n)
            .map(|k| x[k] * masses[k] - (plus[k] - minus[k]) / (2.0 * eps) * h2)
            .collect();
        let scale = largest(&reference);
        for k in 0..n {
            if k == 0 || k == 5 {
                assert_eq!(out[k], Vector3::zeros());
                continue;
            }
            let error = (out[k] - reference[k]).amax();
            assert!(
                error <= 1e-6 * scale,
                "{neighbors}-ring vertex {k}: {error:e} of {scale:e}"
            );
        }
    }
}

/// The collider of [`hanging`]: none, a frictionless sphere or a frictionless floor that the
/// swinging cloth runs into.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Obstacle {
    None,
    Sphere,
    Floor,
}

/// A 10 x 10 cloth of 0.5 m pinned along one edge, on `threads` threads, one step of `dt`
/// under gravity with a collider as asked; the positions and stats.
fn hanging<T: Real>(
    material: Material,
    dt: f64,
    params: SolverParams,
    collider: Obstacle,
    threads: Option<usize>,
) -> (Vec<Vector3<f64>>, crate::solve::StepStats) {
    let mut body = Membrane::new(
        TriangleMesh::grid(10, 10, 0.5, 0.5).unwrap(),
        params_for(material),
    )
    .unwrap();
    body.pin(&(0..10).collect::<Vec<i64>>(), None).unwrap();
    // A small initial swing, so the step starts away from its solution.
    body.set_velocities(vec![Vector3::new(0.0, 0.4, -1.0); 100])
        .unwrap();
    let mut solver = Solver::<T>::new(
        SolverParams {
            dt,
            gravity: [0.0, -9.81, -3.0],
            ..params
        },
        threads,
    )
    .unwrap();
    let shape = match collider {
        Obstacle::None => None,
        Obstacle::Sphere => Some(Shape::sphere([0.25, 0.3, -0.13], 0.12).unwrap()),
        // 1 cm below the cloth, which moves down by 2 cm in a soft step.
        Obstacle::Floor => Some(Shape::plane([0.0, 0.0, -0.01], [0.0, 0.0, 1.0]).unwrap()),
    };
    if let Some(shape) = shape {
        solver.add_collider(Collider::fixed(shape)).unwrap();
    }
    let stats = solver.step(&mut [(&mut body).into()]).unwrap();
    (body.positions().to_vec(), stats)
}

fn params_for(material: Material) -> MembraneParams {
    params(material, 1e-5, 0.5, 1)
}

fn gap(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max)
}

fn tight(method: Method) -> SolverParams {
    SolverParams {
        method,
        tol: 1e-11,
        max_iters: 30000,
        acceleration: match method {
            Method::Sissm => Acceleration::Chebyshev {
                rho: 0.99,
                delay: 3,
            },
            _ => Acceleration::None,
        },
        ..SolverParams::default()
    }
}

/// Newton converges to SISSM's implicit Euler solution within 1e-9 m (f64, both run to the
/// residual measure 1e-11 m), on a soft and on the paper's stiff cloth; Newton in far fewer
/// iterations.
#[test]
fn newton_reaches_the_implicit_euler_solution_of_sissm() {
    same_solution_as_sissm(Obstacle::None);
}

/// The same with the cloth swinging into a frictionless floor (a flat collider: the
/// reaction's normal does not depend on the pushed-in point, so both methods' fixed points are
/// the constrained energy minimum).
#[test]
fn newton_on_a_floor_reaches_the_implicit_euler_solution_of_sissm() {
    same_solution_as_sissm(Obstacle::Floor);
}

/// The same with the cloth swinging into a frictionless sphere: both fixed points are the
/// constrained minimum because the collider's push in the system metric ends where its
/// reaction is normal to the surface ([`crate::collider::ColliderModel::push_out`]; with the
/// normal taken where the push started, SISSM's fixed point was tilted from Newton's by
/// `|D^-1 r|_t / R`, 7.6e-5 m here).
#[test]
fn newton_with_a_collider_reaches_the_implicit_euler_solution_of_sissm() {
    same_solution_as_sissm(Obstacle::Sphere);
}

fn same_solution_as_sissm(collider: Obstacle) {
    for (material, dt) in [
        (Material::stretch_a3(1e4).unwrap(), 0.02),
        (Material::neo_hookean(4.8e7, 1.2e7).unwrap(), 5e-3),
    ] {
        {
            let (reference, sissm) =
                hanging::<f64>(material, dt, tight(Method::Sissm), collider, None);
            let (newton, stats) =
                hanging::<f64>(material, dt, tight(Method::Newton), collider, None);
            assert!(
                sissm.converged && stats.converged,
                "{material:?} collider {collider:?}: SISSM {} ({} it), Newton {} ({} it, {:?})",
                sissm.converged,
                sissm.iterations,
                stats.converged,
                stats.iterations,
                &stats.residuals[stats.residuals.len().saturating_sub(5)..]
            );
            let gap = gap(&reference, &newton);
            assert!(
                gap < 1e-9,
                "{material:?} collider {collider:?}: {gap:e} m apart ({} vs {} iterations)",
                sissm.iterations,
                stats.iterations
            );
            // On the floor most vertices rest on the collider and take their Jacobi move, as
            // in SISSM: Newton's iterations are not fewer there.
            assert!(
                collider != Obstacle::None || stats.iterations * 5 < sissm.iterations,
                "{} vs {}",
                stats.iterations,
                sissm.iterations
            );
        }
    }
}

/// The variational energy of the Newton iterates never rises (beyond the line search's
/// round-off allowance, 1e-12 relative) on the stiff cloth, with and without the sphere, and
/// it comes down.
#[test]
fn newton_energy_never_rises() {
    for collider in [Obstacle::None, Obstacle::Sphere] {
        let (_, stats) = hanging::<f64>(
            Material::neo_hookean(4.8e7, 1.2e7).unwrap(),
            5e-3,
            SolverParams {
                method: Method::Newton,
                tol: 0.0,
                max_iters: 15,
                record_energy: true,
                ..SolverParams::default()
            },
            collider,
            None,
        );
        let e = &stats.energies;
        assert_eq!(e.len(), 16);
        for pair in e.windows(2) {
            assert!(
                pair[1] <= pair[0] + 1e-12 * pair[0].abs(),
                "rose {} -> {}",
                pair[0],
                pair[1]
            );
        }
        assert!(e[15] < e[0] - 1e-3 * e[0].abs(), "{} -> {}", e[0], e[15]);
    }
}

/// One and two threads give the same positions and stats bit for bit (with the sphere), in
/// both precisions.
#[test]
fn newton_is_bit_identical_across_threads() {
    fn check<T: Real>() {
        let run = |threads| {
            hanging::<T>(
                Material::neo_hookean(4.8e7, 1.2e7).unwrap(),
                5e-3,
                SolverParams {
                    method: Method::Newton,
                    max_iters: 8,
                    tol: 0.0,
                    ..SolverParams::default()
                },
                Obstacle::Sphere,
                Some(threads),
            )
        };
        let (a, sa) = run(1);
        let (b, sb) = run(2);
        assert!(a.iter().zip(&b).all(|(p, q)| p == q), "{}", T::NAME);
        assert_eq!(sa.residuals, sb.residuals);
        assert_eq!(sa.moves, sb.moves);
    }
    check::<f32>();
    check::<f64>();
}

/// f32 Newton lands within 2e-5 m of the f64 solution on the soft cloth swinging into the
/// sphere (steps of centimetres; f32 resolves positions of 0.5 m to about 3e-8 m), and
/// converges to the f32-sized tolerance 1e-5 m. (On the stiff cloth f32 residuals do not fall
/// below about 3e-4 m for any method: `h^2 f` cancels against `m (y* - y)` in f32.)
#[test]
fn newton_f32_agrees_with_f64() {
    let run = |tol| SolverParams {
        method: Method::Newton,
        tol,
        max_iters: 200,
        ..SolverParams::default()
    };
    let material = Material::stretch_a3(1e4).unwrap();
    let (wide, _) = hanging::<f64>(material, 0.02, run(1e-11), Obstacle::Sphere, None);
    let (narrow, stats) = hanging::<f32>(material, 0.02, run(1e-5), Obstacle::Sphere, None);
    assert!(stats.converged, "{:?}", stats.residuals);
    let gap = gap(&wide, &narrow);
    assert!(gap < 2e-5, "{gap:e} m");
}

/// The first-order condition of a step with membrane contact at the positions the step left
/// (its last local step's result `y`), as a move (m): the largest over the free vertices of
/// `|D_k^-1 (r_k + d p_k)|`, with `r_k = m_k (y*_k - y_k) + h^2 f_k(y)` (kg m), `p_k` the
/// barrier's push `-mu grad_k B` at `y` (m) and `d` the mean of `trace(D_k) / 3` (kg): the
/// stationarity of `E + d mu B / h^2` (docs/model.md, "Membrane contact"); for a vertex on the
/// floor `z = 0` the part along its normal that the floor can carry (pointing into it) is
/// dropped. Also the same measure without the barrier, `|D_k^-1 r_k|`, so a caller can see
/// that the barrier carries a load.
fn contact_first_order(solver: &mut Solver<f64>) -> (f64, f64) {
    let (mode, h2) = (solver.params().preconditioner, solver.params().dt.powi(2));
    let (sys, contact) = solver.membranes_and_contact();
    let (sys, contact) = (sys.unwrap(), contact.unwrap());
    evaluate(sys, mode);
    let free: Vec<usize> = (0..sys.points.y.len())
        .filter(|&k| !sys.points.pinned[k])
        .collect();
    let d = free
        .iter()
        .map(|&k| jacobi_block(sys, k, h2).diagonal.iter().sum::<f64>() / 3.0)
        .sum::<f64>()
        / free.len() as f64;
    let push = contact.push();
    let (mut with_barrier, mut without) = (0.0f64, 0.0f64);
    for &k in &free {
        let local = PointSystem::of(sys, k, h2);
        let mut balance = local.residual + push[k] * d;
        if sys.points.y[k].z - sys.rest.vertices[k].half_thickness < 1e-6 {
            balance.z = balance.z.max(0.0);
        }
        with_barrier = with_barrier.max(local.inverse.mul_vector(&balance).norm());
        without = without.max(local.inverse.mul_vector(&local.residual).norm());
    }
    (with_barrier, without)
}

/// With membrane contact (a sheet falling onto one resting on the ground plane), Newton's
/// global step followed by the contact local step converges to the residual measure 1e-11 m
/// every step, as SISSM does; at each step's end both satisfy the first-order condition of
/// `E + d mu B / h^2` ([`contact_first_order`]) to 1e-10 m (measured 7e-12 m) where the
/// residual without the barrier is 2e-3 m; and the positions after six steps agree within
/// 1e-9 m (measured 3e-11 m; 3.5e-6 m while Newton's local step took its proximal metric at
/// the line search's trial instead of the iterate).
#[test]
fn newton_with_contact_reaches_sissms_solution() {
    let run = |method: Method| {
        let soft = params(Material::stretch_a3(1e4).unwrap(), 1e-5, 0.5, 1);
        let mut lower = Membrane::new(TriangleMesh::grid(6, 6, 0.5, 0.5).unwrap(), soft).unwrap();
        let mut upper = Membrane::new(TriangleMesh::grid(6, 6, 0.5, 0.5).unwrap(), soft).unwrap();
        let lifted = upper
            .positions()
            .iter()
            .map(|p| p + Vector3::new(0.02, 0.03, 0.006))
            .collect();
        upper.set_positions(lifted).unwrap();
        upper
            .set_velocities(vec![Vector3::new(0.0, 0.0, -1.0); 36])
            .unwrap();
        let mut solver = Solver::<f64>::new(
            SolverParams {
                dt: 2e-3,
                contact: Some(ContactParams {
                    thickness: 2e-3,
                    d_hat: 4e-3,
                    ..ContactParams::default()
                }),
                ..tight(method)
            },
            None,
        )
        .unwrap();
        solver
            .add_collider(Collider::fixed(
                Shape::plane([0.0; 3], [0.0, 0.0, 1.0]).unwrap(),
            ))
            .unwrap();
        let mut loaded = 0.0f64;
        for step in 0..6 {
            let stats = solver
                .step(&mut [(&mut lower).into(), (&mut upper).into()])
                .unwrap();
            assert!(stats.converged, "{method:?}: {:?}", stats.residuals.last());
            let (balance, without) = contact_first_order(&mut solver);
            assert!(balance < 1e-10, "{method:?} step {step}: {balance:e} m");
            if stats.contact.active_pairs > 0 {
                loaded = loaded.max(without);
            }
        }
        assert!(loaded > 1e-4, "{method:?}: the barrier carried no load");
        let mut y = lower.positions().to_vec();
        y.extend_from_slice(upper.positions());
        y
    };
    let gap = gap(&run(Method::Sissm), &run(Method::Newton));
    assert!(gap < 1e-9, "{gap:e} m");
}

/// A stiff 30 x 30 sheet of 0.6 m (the paper's neo-Hookean, 1 mm), stretched by 5 % and
/// pinned along one edge, loaded into a system and evaluated, with its Newton state; the
/// Newton matrix at `h = 1 ms`.
fn stiff_sheet() -> (Membrane, MembraneSystem<f64>, NewtonState<f64>, f64) {
    let material = Material::neo_hookean(4.8e7, 1.2e7).unwrap();
    let mut m = Membrane::new(
        TriangleMesh::grid(30, 30, 0.6, 0.6).unwrap(),
        params(material, 1e-5, 0.5, 1),
    )
    .unwrap();
    let y = m.positions().iter().map(|x| stretched(*x)).collect();
    m.set_positions(y).unwrap();
    m.pin(&(0..30).collect::<Vec<i64>>(), None).unwrap();
    let mut sys = MembraneSystem::<f64>::build(&[&mut m], true).unwrap();
    sys.points.load(&[&mut m]);
    sys.points.y = sys.points.y_start.clone();
    evaluate(&mut sys, Preconditioner::Tangent);
    let state = NewtonState::<f64>::new(&[&mut m]).unwrap();
    (m, sys, state, 1e-6)
}

/// The coarse matrix is the Galerkin product `A_c = P^T K P`: for random aggregate
/// translations `u`, the coarse correction of `K P u` (the assembled product, itself tested
/// against differences of the force) gives back `P u` within 1e-9 of its size, pinned
/// vertices untouched; and there are far fewer aggregates than vertices.
#[test]
fn the_coarse_matrix_is_the_galerkin_product() {
    let (_m, sys, mut state, h2) = stiff_sheet();
    let coarse = &mut state.coarse_level(&sys, h2);
    let n = sys.points.y.len();
    assert!(
        coarse.aggregates() * 20 < n && coarse.aggregates() > 4,
        "{}",
        coarse.aggregates()
    );
    let mut rng = Rng::new(0x47);
    let u: Vec<Vector3<f64>> = (0..coarse.aggregates()).map(|_| rng.vector()).collect();
    let free: Vec<bool> = sys.points.pinned.iter().map(|p| !p).collect();
    let x: Vec<Vector3<f64>> = (0..n)
        .map(|k| {
            if free[k] {
                u[coarse.aggregate_of(k)]
            } else {
                Vector3::zeros()
            }
        })
        .collect();
    let mut kx = vec![Vector3::zeros(); n];
    state.product(&sys, h2, &x, &mut kx);
    let mut z = vec![Vector3::zeros(); n];
    coarse.correct(&free, &kx, &mut z);
    let error = gap(&z, &x);
    assert!(error < 1e-9 * largest(&x), "{error:e}");
}

/// The two-level preconditioner `M^-1 = D^-1 + P A_c^-1 P^T` is symmetric positive definite
/// on the free vertices: `r . M^-1 r > 0` for random `r`, and `a . M^-1 b = b . M^-1 a` to
/// 1e-12 relative.
#[test]
fn the_two_level_preconditioner_is_symmetric_positive_definite() {
    let (_m, sys, mut state, h2) = stiff_sheet();
    let n = sys.points.y.len();
    let mut rng = Rng::new(0x48);
    let mut random = || -> Vec<Vector3<f64>> {
        (0..n)
            .map(|k| {
                if sys.points.pinned[k] {
                    Vector3::zeros()
                } else {
                    rng.vector()
                }
            })
            .collect()
    };
    let dot = |a: &[Vector3<f64>], b: &[Vector3<f64>]| -> f64 {
        a.iter().zip(b).map(|(a, b)| a.dot(b)).sum()
    };
    for _ in 0..5 {
        let (a, b) = (random(), random());
        let (ma, mb) = (
            state.preconditioned(&sys, h2, &a),
            state.preconditioned(&sys, h2, &b),
        );
        assert!(dot(&a, &ma) > 0.0);
        let (ab, ba) = (dot(&a, &mb), dot(&b, &ma));
        assert!(
            (ab - ba).abs() <= 1e-12 * dot(&a, &ma).max(dot(&b, &mb)),
            "{ab:e} {ba:e}"
        );
    }
}

/// On the stiff sheet, under a smooth load (gravity's `m g`), the coarse level cuts the CG's
/// Hessian products to the forcing term by at least 3x against block Jacobi alone, and both
/// directions agree in energy norm to the forcing term's accuracy (5 % of `|d|_K` each).
#[test]
fn the_coarse_level_cuts_the_cg_products() {
    let (m, sys, mut state, h2) = stiff_sheet();
    let masses = m.masses();
    let load: Vec<Vector3<f64>> = masses
        .iter()
        .map(|mass| Vector3::new(0.0, -9.81, -3.0) * (mass * h2))
        .collect();
    let (with, d_with) = state.linear_solve(&sys, h2, &load, true);
    let (without, d_without) = state.linear_solve(&sys, h2, &load, false);
    assert!(with * 3 <= without, "{with} vs {without} products");
    let n = load.len();
    let diff: Vec<Vector3<f64>> = (0..n).map(|k| d_with[k] - d_without[k]).collect();
    let (mut kd, mut kdiff) = (vec![Vector3::zeros(); n], vec![Vector3::zeros(); n]);
    state.product(&sys, h2, &d_without, &mut kd);
    state.product(&sys, h2, &diff, &mut kdiff);
    let norm = |a: &[Vector3<f64>], b: &[Vector3<f64>]| -> f64 {
        a.iter().zip(b).map(|(a, b)| a.dot(b)).sum::<f64>().sqrt()
    };
    let (size, apart) = (norm(&d_without, &kd), norm(&diff, &kdiff));
    assert!(apart < 0.2 * size, "{apart:e} of {size:e}");
}
