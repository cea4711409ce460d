//! The cell search against brute force on random, clustered and lattice clouds; thread-count
//! and input-order invariance; edge cases.

use nalgebra::Vector3;

use super::*;
use crate::test_rng::Rng;

/// Every `j != i` with [`within`], by testing all pairs.
fn brute_force(x: &[Vector3<f64>], delta: f64) -> Vec<Vec<u32>> {
    let p: Vec<[f64; 3]> = x.iter().map(|v| [v.x, v.y, v.z]).collect();
    (0..p.len())
        .map(|i| {
            (0..p.len())
                .filter(|&j| j != i && within(&p[i], &p[j], delta * delta))
                .map(|j| j as u32)
                .collect()
        })
        .collect()
}

fn lists(h: &Horizons) -> Vec<Vec<u32>> {
    (0..h.len()).map(|i| h.of(i).to_vec()).collect()
}

/// Checks the CSR's shape and the order's being a permutation.
fn check_shape(h: &Horizons, n: usize) {
    assert_eq!(h.offsets.len(), n + 1);
    assert_eq!(h.offsets[0], 0);
    assert_eq!(*h.offsets.last().unwrap() as usize, h.indices.len());
    let mut seen = vec![false; n];
    for &i in &h.order {
        assert!(!seen[i as usize], "point {i} twice in the order");
        seen[i as usize] = true;
    }
    assert!(seen.iter().all(|&s| s));
    for i in 0..n {
        assert!(
            h.of(i).windows(2).all(|w| w[0] < w[1]),
            "list {i} not increasing"
        );
    }
}

fn matches_brute_force(x: &[Vector3<f64>], delta: f64) -> Horizons {
    let h = find_horizons(x, delta).unwrap();
    check_shape(&h, x.len());
    assert_eq!(lists(&h), brute_force(x, delta));
    h
}

fn uniform(n: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = Rng::new(seed);
    (0..n).map(|_| rng.vector()).collect()
}

/// A few tight clusters of very different sizes plus scattered points.
fn clustered(n: usize, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = Rng::new(seed);
    let centres: Vec<(Vector3<f64>, f64)> = (0..5)
        .map(|k| (rng.vector() * 3.0, 10f64.powi(-k)))
        .collect();
    (0..n)
        .map(|i| {
            if i % 10 == 0 {
                rng.vector() * 4.0
            } else {
                let (c, r) = centres[i % 5];
                c + rng.vector() * r
            }
        })
        .collect()
}

/// Lattice points `spacing (i, j, k)` for `i, j, k < m`.
fn lattice(m: usize, spacing: f64) -> Vec<Vector3<f64>> {
    let mut x = Vec::new();
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                x.push(Vector3::new(i as f64, j as f64, k as f64) * spacing);
            }
        }
    }
    x
}

#[test]
fn uniform_clouds_match_brute_force() {
    for (n, delta) in [(2000, 0.3), (3000, 0.05), (500, 5.0), (1500, 1e-3)] {
        let h = matches_brute_force(&uniform(n, n as u64), delta);
        if delta == 0.3 {
            // About 2000 (4 pi / 3) 0.3^3 / 8 ~ 28 neighbours each, fewer at the faces.
            let mean = h.indices.len() as f64 / n as f64;
            assert!((15.0..30.0).contains(&mean), "mean {mean}");
        }
    }
}

#[test]
fn clustered_clouds_match_brute_force() {
    for delta in [1e-3, 0.02, 0.5] {
        matches_brute_force(&clustered(3000, 7), delta);
    }
}

/// Every entry's mirror is the reverse pair, and the mirror of the mirror is the entry.
#[test]
fn each_entry_finds_its_mirror() {
    let h = find_horizons(&clustered(2000, 3), 0.02).unwrap();
    let mut mirror = Vec::new();
    h.mirrors_into(&mut mirror);
    assert_eq!(mirror.len(), h.indices.len());
    for i in 0..h.len() {
        for e in h.offsets[i] as usize..h.offsets[i + 1] as usize {
            let m = mirror[e] as usize;
            let j = h.indices[e] as usize;
            assert!((h.offsets[j] as usize..h.offsets[j + 1] as usize).contains(&m));
            assert_eq!(h.indices[m] as usize, i);
            assert_eq!(mirror[m] as usize, e);
        }
    }
}

/// Lists that are not symmetric (made by hand: 1 in 0's list, 0 not in 1's) are refused.
#[test]
#[should_panic(expected = "not symmetric: 1 in 0's list")]
fn asymmetric_lists_have_no_mirrors() {
    let h = Horizons {
        offsets: vec![0, 1, 1],
        indices: vec![1],
        order: vec![0, 1],
    };
    h.mirrors_into(&mut Vec::new());
}

#[test]
fn lattices_exclude_pairs_exactly_at_the_horizon() {
    // Integer coordinates: every distance is exact. Offsets with |d|^2 in {1, 2, 3} are inside
    // a horizon of 2, those at 2 exactly (|d|^2 = 4) are not: 6 + 12 + 8 = 26 at an interior
    // point; with a horizon just above 2 the 6 at distance 2 join.
    let x = lattice(7, 1.0);
    let centre = 3 + 7 * (3 + 7 * 3);
    let h = matches_brute_force(&x, 2.0);
    assert_eq!(h.of(centre).len(), 26);
    let h = matches_brute_force(&x, 2.0 * (1.0 + f64::EPSILON));
    assert_eq!(h.of(centre).len(), 32);
    // Spacings that are not exact in binary: the coordinates' round-off decides pairs near the
    // horizon, the same way for the search and the brute force, and symmetrically.
    for (spacing, delta) in [(0.1, 0.2), (0.1, 0.3), (1e-3 / 3.0, 2e-3 / 3.0), (0.7, 1.4)] {
        let h = matches_brute_force(&lattice(9, spacing), delta);
        for i in 0..h.len() {
            for &j in h.of(i) {
                assert!(h.of(j as usize).binary_search(&(i as u32)).is_ok());
            }
        }
    }
    // A lattice far from the origin (coordinates round at about 1e-9 m).
    let far: Vec<_> = lattice(6, 0.01)
        .iter()
        .map(|p| p + Vector3::new(1e7, -3e7, 5e6))
        .collect();
    matches_brute_force(&far, 0.02);
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    // Clustered: cells found by binary search; uniform: in the dense table.
    for (x, delta) in [(clustered(20_000, 3), 0.05), (uniform(20_000, 3), 0.15)] {
        let runs: Vec<Horizons> = [1, 2, 4]
            .iter()
            .map(|&threads| {
                rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap()
                    .install(|| find_horizons(&x, delta).unwrap())
            })
            .collect();
        assert!(runs[0].indices.len() > 100_000);
        assert_eq!(runs[0], runs[1]);
        assert_eq!(runs[0], runs[2]);
    }
}

#[test]
fn results_do_not_depend_on_the_input_order() {
    let x = uniform(4000, 11);
    let h = find_horizons(&x, 0.2).unwrap();
    // A random permutation: y[k] = x[perm[k]].
    let mut rng = Rng::new(5);
    let mut perm: Vec<usize> = (0..x.len()).collect();
    for k in (1..perm.len()).rev() {
        let r = ((rng.uniform() + 1.0) * 0.5 * (k + 1) as f64) as usize;
        perm.swap(k, r.min(k));
    }
    let y: Vec<_> = perm.iter().map(|&i| x[i]).collect();
    let g = find_horizons(&y, 0.2).unwrap();
    let mut inverse = vec![0u32; perm.len()];
    for (k, &i) in perm.iter().enumerate() {
        inverse[i] = k as u32;
    }
    for (k, &i) in perm.iter().enumerate() {
        let mut mapped: Vec<u32> = h.of(i).iter().map(|&i| inverse[i as usize]).collect();
        mapped.sort_unstable();
        assert_eq!(g.of(k), &mapped[..], "point {k}");
    }
}

#[test]
fn the_order_groups_cells_and_reordered_data_keeps_the_bonds() {
    let x = uniform(3000, 2);
    let h = find_horizons(&x, 0.1).unwrap();
    // Positions stored in the order give the same horizons, renumbered.
    let y: Vec<_> = h.order.iter().map(|&i| x[i as usize]).collect();
    let g = find_horizons(&y, 0.1).unwrap();
    assert_eq!(g.order, (0..3000).collect::<Vec<u32>>());
    for (k, &i) in h.order.iter().enumerate() {
        let back: Vec<u32> = g.of(k).iter().map(|&j| h.order[j as usize]).collect();
        let mut back = back;
        back.sort_unstable();
        assert_eq!(back, h.of(i as usize));
    }
}

#[test]
fn f32_positions_give_the_horizons_of_their_f64_values() {
    let x = uniform(2000, 9);
    let x32: Vec<Vector3<f32>> = x.iter().map(|p| p.cast::<f32>()).collect();
    let x64: Vec<Vector3<f64>> = x32.iter().map(|p| p.cast::<f64>()).collect();
    assert_eq!(
        find_horizons(&x32, 0.25).unwrap(),
        find_horizons(&x64, 0.25).unwrap()
    );
}

#[test]
fn empty_single_and_coincident_sets() {
    let h = find_horizons::<f64>(&[], 1.0).unwrap();
    assert_eq!((h.offsets, h.indices.len(), h.order.len()), (vec![0], 0, 0));
    assert!(find_horizons::<f64>(&[], 1.0).unwrap().is_empty());
    let h = find_horizons(&[Vector3::new(1.0, 2.0, 3.0)], 1.0).unwrap();
    assert_eq!(
        (h.offsets, h.indices, h.order),
        (vec![0, 0], vec![], vec![0])
    );
    let mut x = vec![Vector3::new(0.5, 0.5, 0.5); 5];
    x.push(Vector3::new(9.0, 0.5, 0.5));
    let h = matches_brute_force(&x, 1e-6);
    assert_eq!(h.of(0), &[1, 2, 3, 4]);
    assert_eq!(h.of(4), &[0, 1, 2, 3]);
    assert!(h.of(5).is_empty());
}

#[test]
fn huge_and_tiny_coordinates_neither_panic_nor_lose_pairs() {
    let mut x = clustered(1000, 4);
    x.extend([
        Vector3::new(f64::MAX, 0.0, 0.0),
        Vector3::new(f64::MAX, 0.0, 0.0),
        Vector3::new(-f64::MAX, -f64::MAX, f64::MAX),
        Vector3::new(1e300, 1e300, 1e300),
        Vector3::new(1e300, 1e300, 1e300 * (1.0 + f64::EPSILON)),
        Vector3::new(5e-324, 0.0, 0.0),
    ]);
    for delta in [1e-3, 0.1, 1e100, 1e150] {
        let h = matches_brute_force(&x, delta);
        assert_eq!(h.of(1000), &[1001]);
    }
    // Cells of delta across the box would need more than 2^42 per axis: they widen.
    let h = matches_brute_force(&x, 1.5e-154);
    assert_eq!(h.of(1000), &[1001]);
}

#[test]
fn bad_input_names_the_culprit() {
    let x = uniform(10, 1);
    for delta in [0.0, -1.0, f64::NAN, f64::INFINITY, 1e-200, 1e160] {
        let e = find_horizons(&x, delta).unwrap_err().to_string();
        assert!(e.contains("horizon delta"), "{e}");
    }
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let mut y = x.clone();
        y[7].y = bad;
        y[9].x = bad;
        let e = find_horizons(&y, 0.1).unwrap_err().to_string();
        assert!(e.contains("point 7 "), "{e}");
    }
}
