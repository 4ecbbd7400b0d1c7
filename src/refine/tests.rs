//! Unit tests of the tree geometry against the evaluator, the indicator plumbing and the
//! expression oracle.

use super::indicator::{Indication, Unit};
use super::{ExpressionOracle, SampleOracle};
use crate::adaptive::tree::interval::{cell_of, support_cells, WaveletTree};
use crate::basis::{minimum_level, CdvBasis, FilterBank, FilterFamily};
use crate::sampling::Domain;

fn bank(p: usize) -> std::sync::Arc<FilterBank> {
    FilterBank::shared(p, FilterFamily::cdv_default(p)).unwrap()
}

/// The structural supports are exactly the cells where the evaluator reports a function.
#[test]
fn supports_match_the_evaluator() {
    for p in 1..=5usize {
        let n = minimum_level(p);
        let fine = n + 3;
        let basis = CdvBasis::new(p, FilterFamily::cdv_default(p), n, fine, Domain::UNIT).unwrap();
        let mut ev = basis.evaluator();
        let level = fine + 2;
        let cells = 1u64 << level;
        let mut out = Vec::new();
        for c in 0..cells {
            // Three points per cell: its left end, the middle, just before its right end.
            let lo = c as f64 / cells as f64;
            let w = 1.0 / cells as f64;
            for t in [lo, lo + 0.5 * w, lo + w * (1.0 - 1e-9)] {
                ev.eval_unit_into(t, &mut out);
                for a in 0..basis.dimension() {
                    let id = basis.function(a);
                    let (s0, s1) = support_cells(p, id.level, id.index);
                    let cell = cell_of(t, id.level);
                    let inside = s0 <= cell && cell <= s1;
                    let reported = out.iter().any(|v| v.index == a);
                    assert_eq!(inside, reported, "p {p} function {a} ({id:?}) at t = {t}");
                }
            }
        }
    }
}

/// A child's support lies in its parent's, for interior and edge functions alike.
#[test]
fn supports_nest() {
    for p in 1..=8usize {
        let n = minimum_level(p);
        let tree = WaveletTree::uniform(bank(p), n, n as i32, n + 6, Domain::UNIT).unwrap();
        for j in n + 1..=n + 6 {
            for k in 0..(1usize << j) {
                let child = (1usize << j) + k;
                let parent = tree.parent(child).unwrap();
                let (c0, c1) = tree.support_unit(child);
                let (p0, p1) = tree.support_unit(parent);
                assert!(
                    p0 <= c0 && c1 <= p1,
                    "p {p}: child {child} not inside {parent}"
                );
            }
        }
    }
}

/// Leaves partition [0, 1], carry a constant depth, and the depth steps between levels.
#[test]
fn leaves_partition_the_interval_with_constant_depth() {
    let p = 3;
    let n = minimum_level(p);
    let mut tree = WaveletTree::uniform(bank(p), n, n as i32 + 1, 16, Domain::UNIT).unwrap();
    // A deep spike of wavelets around t = 0.3 (ancestors come along).
    for j in n + 2..=16u32 {
        let k = (0.3 * (1u64 << j) as f64) as usize;
        tree.insert((1usize << j) + k);
    }
    let leaves = tree.leaves();
    let mut end = 0.0;
    for leaf in &leaves {
        let (a, b) = leaf.unit_bounds();
        assert_eq!(a, end, "leaves must be contiguous");
        end = b;
        for s in [0.0, 0.37, 0.999] {
            let t = a + s * (b - a);
            assert_eq!(tree.local_depth_unit(t), leaf.depth(), "t = {t}");
        }
    }
    assert_eq!(end, 1.0);
    assert_eq!(tree.local_depth_unit(0.3), 16);
    assert_eq!(tree.local_depth_unit(0.9), n as i32 + 1);
    // Closure: every wavelet's parent is active.
    for a in tree.wavelets() {
        assert!(tree.contains(tree.parent(a).unwrap()));
    }
}

#[test]
fn deepen_adds_children_and_insert_adds_ancestors() {
    let p = 2;
    let n = minimum_level(p);
    let mut tree = WaveletTree::uniform(bank(p), n, n as i32, 10, Domain::UNIT).unwrap();
    let start = tree.len();
    let a = (1usize << n) + 3;
    let added = tree.deepen(&[a]);
    let base = 1usize << (n + 1);
    assert_eq!(added, vec![base + 6, base + 7]);
    assert_eq!(tree.len(), start + 2);
    let deep = (1usize << 9) + 100;
    let added = tree.insert(deep);
    assert_eq!(added, 9 - n as usize); // levels n+1..=9 (level n is complete)
    assert!(tree.contains(deep));
    // Beyond the depth limit nothing is added.
    assert_eq!(tree.insert((1usize << 11) + 5), 0);
    assert_eq!(tree.depth(), 9);
}

#[test]
fn dorfler_marks_the_fewest_largest() {
    let units = |etas: &[f64]| Indication {
        units: etas
            .iter()
            .enumerate()
            .map(|(i, &eta)| Unit {
                eta,
                wavelets: vec![i],
            })
            .collect(),
        ..Indication::default()
    };
    // Squares 16, 9, 1, 0: theta 0.5 needs 16 of 26 -> one unit; 0.9 needs 25 -> two.
    let ind = units(&[4.0, 3.0, 1.0, 0.0]);
    assert_eq!(ind.dorfler(0.5), 1);
    assert_eq!(ind.dorfler(0.9), 2);
    assert_eq!(ind.dorfler(1.0), 3); // never the zero
    assert_eq!(units(&[0.0, 0.0]).dorfler(0.5), 0);
}

#[test]
fn expressions_follow_the_documented_semantics() {
    let e = ExpressionOracle::parse("sin(8*x) + (x > 0.6)").unwrap();
    assert_eq!(e.sample(0.7), (5.6f64).sin() + 1.0);
    assert_eq!(e.sample(0.5), (4.0f64).sin());
    let c = ExpressionOracle::parse("(x >= 0.5) - (x <= 0.25) + (x == 1) + 2*(x != 0.5)").unwrap();
    assert_eq!(c.sample(0.5), 1.0);
    assert_eq!(c.sample(0.25), -1.0 + 2.0);
    assert_eq!(c.sample(1.0), 1.0 + 1.0 + 2.0);
    assert_eq!(
        ExpressionOracle::parse("PI").unwrap().sample(0.3),
        std::f64::consts::PI
    );
    assert!(ExpressionOracle::parse("sqrt(x - 2)")
        .unwrap()
        .sample(0.5)
        .is_nan());
    for bad in ["", "sin(", "x +* 2", "y + x", "jumpz"] {
        let err = ExpressionOracle::parse(bad).unwrap_err();
        assert_eq!(err.expression, bad);
        assert!(!err.reason.is_empty());
    }
    assert!(ExpressionOracle::parse("y + x")
        .unwrap_err()
        .to_string()
        .contains("unknown name `y`"));
}

/// The normal equations kept up to date round by round equal `K^T K` and `K^T f` of a `K`
/// built from scratch by `kernel::kernel_matrix` (an independent evaluation): entry by entry
/// to the rounding of a sum of `m` products, `|dG_ab| <= m eps sum_i |K_ia K_ib|`.
#[test]
fn incremental_normal_equations_equal_a_fresh_k_transpose_k() {
    use crate::kernel::kernel_matrix;
    use crate::refine::{
        BaseSampling, IntervalTreeParams, RefineParams, Refiner, SignalOracle, Step, StopParams,
    };
    use crate::sampling::Signal;
    let oracle = SignalOracle::new(Signal::Jumps, Domain::UNIT);
    let params = RefineParams {
        interval: IntervalTreeParams {
            max_depth: 16,
            ..RefineParams::default().interval
        },
        stop: StopParams {
            tolerance: 1e-9,
            budget: 1500,
            ..RefineParams::default().stop
        },
        sampling: BaseSampling {
            seed: 7,
            ..RefineParams::default().sampling
        },
        ..RefineParams::default()
    };
    let mut refiner = Refiner::new(&oracle, &params).unwrap();
    let mut rounds = 0;
    while rounds < 12 && refiner.refine_once().unwrap() == Step::Refined {
        rounds += 1;
    }
    assert!(rounds >= 5, "the test must see several rounds");
    let tree = refiner.tree();
    let positions: Vec<f64> = refiner.samples().iter().map(|s| s.x).collect();
    let values: Vec<f64> = refiner.samples().iter().map(|s| s.value).collect();
    let active = tree.active_set().unwrap();
    let k = kernel_matrix(&active, &positions).unwrap().to_dense();
    let (g, rhs) = refiner.normal().dense(refiner.columns());
    let (m, p) = (k.nrows(), k.ncols());
    assert_eq!(p, refiner.columns().len());
    let eps = f64::EPSILON * m as f64;
    for a in 0..p {
        let (mut f, mut fs) = (0.0, 0.0);
        for i in 0..m {
            f += k[[i, a]] * values[i];
            fs += (k[[i, a]] * values[i]).abs();
        }
        assert!((rhs[a] - f).abs() <= eps * fs, "K^T f at {a}");
        for b in 0..p {
            let (mut s, mut abs) = (0.0, 0.0);
            for i in 0..m {
                s += k[[i, a]] * k[[i, b]];
                abs += (k[[i, a]] * k[[i, b]]).abs();
            }
            assert!(
                (g[a][b] - s).abs() <= eps * abs,
                "G[{a}][{b}] = {} against {s}",
                g[a][b]
            );
        }
    }
}

/// The tree's global solve reaches the accuracy of an SVD of `K`, not of `K^T K`: on a tree
/// with a deep spike of wavelets, three samples per leaf clustered in `1e-5` of its width
/// (so each leaf's functions are nearly dependent on its samples; `cond(K) = 8.4e5`, which
/// the column scaling cannot remove) and data in the span, `f = K c*`, least-squares perturbation theory bounds a
/// backward-stable solve's forward error by `O(eps cond(K))`, and the normal equations alone
/// give `O(eps cond(K)^2)`. Reference: `c*` itself and the dense SVD solution `K^+ f`. The
/// bound asserted, `1e3 eps cond(K)`, leaves the usual factor for `P`-dependent constants.
#[test]
fn tree_solve_reaches_svd_accuracy_on_ill_conditioned_k() {
    use super::normal::NormalEquations;
    use super::Sample;
    use crate::kernel::{ActiveSet, EvaluationRows};
    use crate::solve::{dense_pinv, GlobalLsParams};
    let p = 3;
    let n = minimum_level(p);
    let deep = n + 10;
    let mut tree = WaveletTree::uniform(bank(p), n, n as i32 + 1, deep, Domain::UNIT).unwrap();
    for j in n + 2..=deep {
        let k = (0.3 * (1u64 << j) as f64) as usize;
        tree.insert((1usize << j) + k);
    }
    let full = CdvBasis::new(p, FilterFamily::cdv_default(p), n, deep, Domain::UNIT).unwrap();
    // Three pseudo-random samples per leaf in a cluster `1e-5` of its width (an LCG:
    // reproducible, no dependency): K has full rank, cond(K) ~ 8e5.
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let spread = 1e-5;
    let mut ts = Vec::new();
    for leaf in tree.leaves() {
        let (a, b) = leaf.unit_bounds();
        let centre = a + (b - a) * (0.5 + 0.5 * (1.0 - spread) * (2.0 * uniform() - 1.0));
        for _ in 0..3 {
            ts.push(centre + (b - a) * spread * (uniform() - 0.5));
        }
    }
    let columns = tree.columns();
    let mut cached = EvaluationRows::new();
    cached.push(&full, &ts);
    let c_true: Vec<f64> = (0..columns.len()).map(|_| 2.0 * uniform() - 1.0).collect();
    let mut samples: Vec<Sample> = ts
        .iter()
        .map(|&t| Sample {
            x: t,
            t,
            value: 0.0,
            round: 0,
        })
        .collect();
    let mut normal = NormalEquations::default();
    // First the kernel (values are not needed for it), then f = K c* and the system again.
    normal.update(&cached, &samples, &columns, |a| tree.support_unit(a));
    let k = cached.kernel(&ActiveSet::from_sorted(
        tree.basis().unwrap(),
        columns.clone(),
    ));
    for (v, (i, j)) in k.iter() {
        samples[i].value += v * c_true[j];
    }
    let mut normal = NormalEquations::default();
    normal.update(&cached, &samples, &columns, |a| tree.support_unit(a));
    let pinv = dense_pinv(&k, 1e-15).unwrap();
    assert_eq!(pinv.rank, columns.len(), "K has full column rank");
    let cond = pinv.condition;
    let values: Vec<f64> = samples.iter().map(|s| s.value).collect();
    let svd = pinv.apply(&values).unwrap();
    let solved = normal.solve(&samples, &GlobalLsParams::default()).unwrap();
    let by_slot = &solved.coefficients[0];
    let norm = |v: &mut dyn Iterator<Item = f64>| v.map(|x| x * x).sum::<f64>().sqrt();
    let c_norm = norm(&mut c_true.iter().copied());
    let err = norm(
        &mut columns
            .iter()
            .enumerate()
            .map(|(c, &a)| by_slot[normal.slot(a).unwrap()] - c_true[c]),
    ) / c_norm;
    let err_svd = norm(
        &mut columns
            .iter()
            .enumerate()
            .map(|(c, &a)| by_slot[normal.slot(a).unwrap()] - svd[c]),
    ) / c_norm;
    // The normal equations alone, for the record (same G, same order: AMD here).
    let (g, rhs) = normal.dense(&columns);
    let mut tri = sprs::TriMat::new((columns.len(), columns.len()));
    for (a, row) in g.iter().enumerate() {
        for (b, &v) in row.iter().enumerate() {
            if v != 0.0 {
                tri.add_triplet(a, b, v);
            }
        }
    }
    let counts = vec![1; columns.len()];
    let plain = crate::solve::normal_ls(
        &tri.to_csr(),
        &[&rhs],
        ts.len(),
        &counts,
        None,
        &GlobalLsParams::default(),
    )
    .unwrap();
    let err_plain = norm(
        &mut plain.coefficients[0]
            .iter()
            .zip(&c_true)
            .map(|(x, y)| x - y),
    ) / c_norm;
    let bound = 1e3 * f64::EPSILON * cond;
    assert!(
        cond > 1e4,
        "the example must be ill-conditioned: cond(K) = {cond:e}"
    );
    assert!(
        err <= bound && err_svd <= bound,
        "relative error {err:e} against c*, {err_svd:e} against the SVD, above 1e3 eps \
         cond(K) = {bound:e} (cond {cond:e}); the normal equations alone would give ~ eps \
         cond^2 = {:e}",
        f64::EPSILON * cond * cond
    );
    // The step is what makes the difference (measured: 1.3e-13 against 2.3e-9 without it).
    assert!(
        err * 100.0 < err_plain,
        "the corrected solve ({err:e}) must beat the normal equations alone ({err_plain:e})"
    );
}
