//! Unit tests of the tree geometry against the evaluator, the indicator plumbing and the
//! expression oracle.

use super::indicator::{Indication, Unit};
use super::tree::{cell_of, support_cells, WaveletTree};
use super::{ExpressionOracle, SampleOracle};
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
    use crate::refine::{RefineParams, Refiner, SignalOracle, Step};
    use crate::sampling::Signal;
    let oracle = SignalOracle::new(Signal::Jumps, Domain::UNIT);
    let params = RefineParams {
        max_depth: 16,
        tolerance: 1e-9,
        budget: 1500,
        seed: 7,
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
