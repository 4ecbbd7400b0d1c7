//! The single-level evaluator (issue 10): `sum_k v_k phi_{J,k}(t)` from the one-level digit
//! recursion equals the multilevel evaluation `sum_a c_a Psi_a(t)` of `Psi(n, J - 1)` with
//! `c` the FWT analysis of `v`, at random points, the ends, the edge cells and dyadic points.

use rand::{Rng, SeedableRng};
use rkwave::basis::{fwt, minimum_level, BasisValue, CdvBasis, FilterFamily};
use rkwave::sampling::Domain;

/// Random points, both ends, points in the `2p - 1` edge cells at each end, dyadic points of
/// level `J` and `J + 3`, and the neighbours of 0 and 1 at ulp distance.
fn probes(level: u32, seed: u64) -> Vec<f64> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let cells = (1u64 << level) as f64;
    let mut t: Vec<f64> = (0..400).map(|_| rng.random::<f64>()).collect();
    t.extend((0..100).map(|_| 24.0 * rng.random::<f64>() / cells));
    t.extend((0..100).map(|_| 1.0 - 24.0 * rng.random::<f64>() / cells));
    t.extend((0..50).map(|_| (rng.random_range(0..=1u64 << level) as f64) / cells));
    t.extend((0..50).map(|_| (rng.random_range(0..=8u64 << level) as f64) / (8.0 * cells)));
    t.extend([0.0, 1.0, f64::from_bits(1), 1.0 - f64::EPSILON / 2.0, 0.5]);
    t.into_iter().map(|x| x.clamp(0.0, 1.0)).collect()
}

/// Agreement to 1e-13 relative to the larger of `sum_k |v_k phi_{J,k}(t)|` and
/// `sum_a |c_a Psi_a(t)|` (the sizes of the terms; the two sides sum different terms, so this
/// is the scale of their rounding), for `p = 1..10` and
/// levels from `j_min(p) + 1` to `j_min(p) + 6`. The single-level row also equals the
/// multilevel evaluator's scaling-function output of `V_J` to 1e-13 relative per entry (the
/// issue's target; the two digit recursions round in a different order).
#[test]
fn single_level_evaluation_agrees_with_multilevel() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(10);
    for p in 1..=10 {
        let family = FilterFamily::cdv_default(p);
        let n = minimum_level(p);
        for level in [n + 1, n + 3, n + 6] {
            let single = CdvBasis::new(p, family, level, level, Domain::UNIT).unwrap();
            let multi = CdvBasis::new(p, family, n, level - 1, Domain::UNIT).unwrap();
            let size = 1usize << level;
            let v: Vec<f64> = (0..size).map(|_| rng.random::<f64>() - 0.5).collect();
            let c = fwt::analysis(multi.bank(), n, level - 1, &v);
            let mut fast = single.single_level_evaluator();
            let mut slow = single.evaluator();
            let mut all = multi.evaluator();
            let mut out: Vec<BasisValue> = Vec::new();
            for t in probes(level, p as u64) {
                let (first, row) = fast.row_unit(t);
                let lhs: f64 = row.iter().enumerate().map(|(k, r)| r * v[first + k]).sum();
                let scale: f64 = row
                    .iter()
                    .enumerate()
                    .map(|(k, r)| (r * v[first + k]).abs())
                    .sum::<f64>()
                    .max(1e-300);
                all.eval_unit_into(t, &mut out);
                let rhs: f64 = out.iter().map(|b| b.value * c[b.index]).sum();
                // The multilevel side sums its own terms, which can be larger than the
                // single-level ones (Haar: one scaling term against N - n + 1 wavelet terms).
                let scale = scale.max(out.iter().map(|b| (b.value * c[b.index]).abs()).sum());
                assert!(
                    (lhs - rhs).abs() <= 1e-13 * scale,
                    "p = {p}, J = {level}, t = {t:e}: {lhs} vs {rhs} (scale {scale:e})"
                );
                slow.eval_scaling_unit_into(t, &mut out);
                assert_eq!(out.len(), row.len(), "p = {p}, J = {level}, t = {t:e}");
                for (k, b) in out.iter().enumerate() {
                    assert_eq!(b.index, first + k);
                    let tol = 1e-13 * b.value.abs().max(1.0);
                    assert!(
                        (b.value - row[k]).abs() <= tol,
                        "p = {p}, J = {level}, t = {t:e}, k = {k}: {} vs {}",
                        b.value,
                        row[k]
                    );
                }
            }
        }
    }
}
