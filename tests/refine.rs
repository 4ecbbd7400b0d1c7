//! The adaptive refiner (docs/design.md §6): exact reproduction without deepening, refinement
//! that stays at the singularity, the local oversampling invariant after every round (checked
//! against column counts of an independently built `K`), the budget, determinism, the
//! incremental fit against a rebuild, and bad input; the `rkwave adapt` command is in
//! `tests/adapt_cli.rs`.

mod common;

use rkwave::basis::minimum_level;
use rkwave::kernel::kernel_matrix;
use rkwave::refine::{
    quadrature_error, refine, ExpressionOracle, Indicator, RefineError, RefineParams, Refinement,
    Refiner, SampleOracle, SignalOracle, Step, StopReason, MAX_DEPTH_LIMIT,
};
use rkwave::refine::{BaseSampling, IntervalTreeParams, MarkingParams, StopParams, TreeParams};
use rkwave::sampling::{Domain, Layout, Signal};
use rkwave::solve::dense_pinv;

/// Named seeds.
const SEED_A: u64 = 7;
const SEED_B: u64 = 8;

fn monomials(p: usize) -> impl Fn(f64) -> f64 {
    // Degree p - 1, every monomial present, on [-1, 2].
    move |x: f64| (0..p).fold(0.0, |acc, _| acc * x + 1.0) + 0.25 * x
}

#[test]
fn polynomials_of_degree_below_p_are_reproduced_without_deepening() {
    for p in 2..=5usize {
        let domain = Domain::new(-1.0, 2.0).unwrap();
        let f = monomials(p);
        let params = RefineParams {
            domain,
            tree: TreeParams {
                p,
                ..RefineParams::default().tree
            },
            stop: StopParams {
                tolerance: 1e-8,
                ..RefineParams::default().stop
            },
            sampling: BaseSampling {
                seed: SEED_A,
                ..RefineParams::default().sampling
            },
            ..RefineParams::default()
        };
        let r = refine(&f, &params).unwrap();
        assert_eq!(r.stop, StopReason::Tolerance, "p = {p}");
        assert_eq!(r.rounds.len(), 1, "p = {p}: no refinement round");
        assert_eq!(r.tree.depth(), r.base_depth as i32);
        assert_eq!(
            r.tree.len(),
            1usize << (r.base_depth + 1),
            "uniform base tree"
        );
        assert!(r.samples.iter().all(|s| s.round == 0));
        let xs = Layout::Random.generate(2000, domain, SEED_B);
        let got = r.evaluate(&xs).unwrap();
        let scale = xs.iter().map(|&x| f(x).abs()).fold(0.0, f64::max);
        for (x, g) in xs.iter().zip(&got) {
            // Exact up to rounding: the condition of the solve times a few ulps.
            assert!((g - f(*x)).abs() <= 1e-10 * scale, "p = {p} x = {x}");
        }
    }
}

#[test]
fn one_jump_deepens_only_within_a_few_supports_of_the_jump() {
    let jump = 0.4;
    let f = |x: f64| 0.3 * x * x + if x >= jump { 1.0 } else { 0.0 };
    for p in [3usize, 4] {
        let params = RefineParams {
            tree: TreeParams {
                p,
                ..RefineParams::default().tree
            },
            interval: IntervalTreeParams {
                max_depth: 14,
                ..RefineParams::default().interval
            },
            stop: StopParams {
                tolerance: 1e-5,
                ..RefineParams::default().stop
            },
            sampling: BaseSampling {
                seed: SEED_A,
                ..RefineParams::default().sampling
            },
            ..RefineParams::default()
        };
        let r = refine(&f, &params).unwrap();
        let base = r.base_depth as i32;
        assert_eq!(
            r.tree.local_depth(jump),
            14,
            "p = {p}: the jump is resolved"
        );
        let points = 100_000;
        for i in 0..=points {
            let x = i as f64 / points as f64;
            let d = r.tree.local_depth(x);
            assert!(d >= base);
            if d > base {
                // Depth d only within three level-d supports ((2p-1) 2^-d wide) of the jump.
                let support = (2 * p - 1) as f64 * (-(d as f64)).exp2();
                assert!(
                    (x - jump).abs() <= 3.0 * support,
                    "p = {p}: depth {d} at x = {x}, {:.1} supports from the jump",
                    (x - jump).abs() / support
                );
            }
        }
        // The smooth part is left at the base depth and sampled only by the base.
        for leaf in r.tree.leaves() {
            let (a, b) = leaf.unit_bounds();
            if b < jump - 0.1 || a > jump + 0.1 {
                assert_eq!(leaf.depth(), base);
            }
        }
        assert!(r
            .samples
            .iter()
            .filter(|s| s.round > 0)
            .all(|s| (s.x - jump).abs() < 0.1));
    }
}

/// After every round, every active function has at least `rho` samples per leaf (local slot)
/// of its support: its column of `K` (built here by `kernel_matrix`, independently of the
/// refiner's cache) counts the samples in its support.
#[test]
fn local_oversampling_holds_after_every_round() {
    for (signal, rho) in [
        (Signal::Jumps, 2.0),
        (Signal::Cusp, 3.0),
        (Signal::Bumps, 2.0),
    ] {
        let oracle = SignalOracle::new(signal, Domain::UNIT);
        let params = RefineParams {
            interval: IntervalTreeParams {
                max_depth: 14,
                ..RefineParams::default().interval
            },
            stop: StopParams {
                tolerance: 1e-6,
                budget: 3000,
                ..RefineParams::default().stop
            },
            tree: TreeParams {
                rho,
                ..RefineParams::default().tree
            },
            sampling: BaseSampling {
                base_layout: Layout::Random,
                seed: SEED_A,
                ..RefineParams::default().sampling
            },
            ..RefineParams::default()
        };
        let mut refiner = Refiner::new(&oracle, &params).unwrap();
        let need = rho.ceil() as usize;
        let mut rounds = 0;
        loop {
            let tree = refiner.tree();
            let positions: Vec<f64> = refiner.samples().iter().map(|s| s.x).collect();
            let active = tree.active_set().unwrap();
            let k = kernel_matrix(&active, &positions).unwrap();
            let k_csc = k.to_csc();
            let leaves = tree.leaves();
            let mid: Vec<f64> = leaves
                .iter()
                .map(|l| {
                    let (a, b) = l.unit_bounds();
                    0.5 * (a + b)
                })
                .collect();
            for (c, column) in k_csc.outer_iterator().enumerate() {
                let (lo, hi) = tree.support_unit(active.global(c));
                let slots = mid.iter().filter(|&&t| lo <= t && t <= hi).count();
                assert!(slots > 0);
                assert!(
                    column.nnz() as f64 >= rho * slots as f64,
                    "{signal} round {rounds}: function {} has {} samples for {slots} slots",
                    active.global(c),
                    column.nnz()
                );
            }
            for leaf in &leaves {
                let count = refiner
                    .samples()
                    .iter()
                    .filter(|s| leaf.contains(s.t))
                    .count();
                assert!(
                    count >= need,
                    "{signal} round {rounds}: leaf {leaf:?} has {count}"
                );
            }
            if refiner.refine_once().unwrap() != Step::Refined {
                break;
            }
            rounds += 1;
        }
        assert!(rounds >= 3, "{signal}: the test must see refinement rounds");
        for log in refiner.rounds() {
            assert!(log.min_leaf_samples >= need);
        }
    }
}

#[test]
fn the_refiner_stops_at_the_budget() {
    let oracle = SignalOracle::new(Signal::Jumps, Domain::UNIT);
    let mut last = 0;
    for budget in [400usize, 700, 1500] {
        let params = RefineParams {
            stop: StopParams {
                budget,
                tolerance: 1e-12,
                ..RefineParams::default().stop
            },
            sampling: BaseSampling {
                seed: SEED_A,
                ..RefineParams::default().sampling
            },
            ..RefineParams::default()
        };
        let r = refine(&oracle, &params).unwrap();
        assert_eq!(r.stop, StopReason::Budget);
        assert!(r.samples.len() <= budget, "{} > {budget}", r.samples.len());
        // The last marks are cut to what the budget can sample: little is left over.
        assert!(
            r.samples.len() + 64 >= budget,
            "{} of {budget}",
            r.samples.len()
        );
        assert!(r.samples.len() > last);
        last = r.samples.len();
        for log in &r.rounds {
            assert!(log.samples <= budget);
        }
    }
}

#[test]
fn a_seed_fixes_everything_and_rounds_reuse_exactly() {
    let oracle = SignalOracle::new(Signal::HeaviSine, Domain::UNIT);
    let params = RefineParams {
        stop: StopParams {
            budget: 1200,
            ..RefineParams::default().stop
        },
        sampling: BaseSampling {
            seed: SEED_A,
            ..RefineParams::default().sampling
        },
        ..RefineParams::default()
    };
    let a = refine(&oracle, &params).unwrap();
    let b = refine(&oracle, &params).unwrap();
    assert_eq!(a.samples, b.samples);
    assert_eq!(a.coefficients(), b.coefficients());
    assert_eq!(a.columns(), b.columns());
    let c = refine(
        &oracle,
        &RefineParams {
            sampling: BaseSampling {
                seed: SEED_B,
                ..params.sampling
            },
            ..params
        },
    )
    .unwrap();
    assert_ne!(a.samples, c.samples);
    // The cached evaluations give the same K, hence the same solve, as a rebuild from scratch.
    let (fresh, _) = a.rebuild().unwrap();
    let scale = a.coefficients().iter().fold(0.0f64, |m, c| m.max(c.abs()));
    for (x, y) in fresh.iter().zip(a.coefficients()) {
        assert!((x - y).abs() <= 1e-12 * scale);
    }
    // Every oracle call is a sample: values are never recomputed.
    let calls = std::cell::Cell::new(0usize);
    let counted = |x: f64| {
        calls.set(calls.get() + 1);
        oracle.sample(x)
    };
    let r = refine(&counted, &params).unwrap();
    assert_eq!(calls.get(), r.samples.len());
}

#[test]
fn expressions_refine_where_they_jump() {
    let e = ExpressionOracle::parse("sin(8*x) + (x > 0.6)").unwrap();
    let params = RefineParams {
        interval: IntervalTreeParams {
            max_depth: 16,
            ..RefineParams::default().interval
        },
        stop: StopParams {
            tolerance: 1e-5,
            ..RefineParams::default().stop
        },
        ..RefineParams::default()
    };
    let r = refine(&e, &params).unwrap();
    assert_eq!(r.tree.local_depth(0.6), 16);
    assert!(r.tree.local_depth(0.2) < 10);
}

#[test]
fn bad_input_is_a_clear_error() {
    let f = |x: f64| x;
    let base = RefineParams::default();
    let invalid = |params: RefineParams, name: &str| match refine(&f, &params) {
        Err(RefineError::InvalidParameter { name: n, .. }) => assert_eq!(n, name),
        other => panic!("expected an invalid {name}, got {other:?}"),
    };
    invalid(
        RefineParams {
            stop: StopParams {
                budget: 0,
                ..base.stop
            },
            ..base
        },
        "budget",
    );
    invalid(
        RefineParams {
            stop: StopParams {
                tolerance: 0.0,
                ..base.stop
            },
            ..base
        },
        "tolerance",
    );
    invalid(
        RefineParams {
            stop: StopParams {
                tolerance: -1.0,
                ..base.stop
            },
            ..base
        },
        "tolerance",
    );
    invalid(
        RefineParams {
            stop: StopParams {
                tolerance: f64::NAN,
                ..base.stop
            },
            ..base
        },
        "tolerance",
    );
    invalid(
        RefineParams {
            interval: IntervalTreeParams {
                max_depth: 53,
                ..base.interval
            },
            ..base
        },
        "max depth",
    );
    invalid(
        RefineParams {
            tree: TreeParams {
                rho: 0.5,
                ..base.tree
            },
            ..base
        },
        "rho",
    );
    invalid(
        RefineParams {
            marking: MarkingParams { theta: 0.0 },
            ..base
        },
        "theta",
    );
    invalid(
        RefineParams {
            tree: TreeParams { p: 11, ..base.tree },
            ..base
        },
        "p",
    );
    invalid(
        RefineParams {
            indicator: Indicator::Residual { probes: 0 },
            ..base
        },
        "probes",
    );
    match refine(
        &f,
        &RefineParams {
            interval: IntervalTreeParams {
                max_depth: 5,
                ..base.interval
            },
            ..base
        },
    ) {
        Err(
            e @ RefineError::MaxDepthBelowBase {
                max_depth: 5,
                base_depth: 6,
                ..
            },
        ) => assert!(e.to_string().contains("at least 6"), "{e}"),
        other => panic!("{other:?}"),
    }
    match refine(
        &f,
        &RefineParams {
            stop: StopParams {
                budget: 100,
                ..base.stop
            },
            ..base
        },
    ) {
        Err(e @ RefineError::BudgetBelowBase { .. }) => {
            assert!(e.to_string().contains("budget is 100"))
        }
        other => panic!("{other:?}"),
    }
    let bad = |x: f64| if x > 0.5 { f64::NAN } else { x };
    assert!(matches!(
        refine(&bad, &base),
        Err(RefineError::NonFiniteValue { .. })
    ));
    let inf = ExpressionOracle::parse("1/(x - x)").unwrap();
    assert!(matches!(
        refine(&inf, &base),
        Err(RefineError::NonFiniteValue { .. })
    ));
    let e = ExpressionOracle::parse("sin(x").unwrap_err();
    assert!(e.reason.contains("`)` is missing"), "{e}");
    assert_eq!(minimum_level(3), 4);
}

/// Depth to the last bit: a unit jump at a non-dyadic position on a quadratic background
/// (reproduced exactly by `p = 3`, so every refinement goes to the jump), depth allowed to 52.
/// Near `sqrt(2) - 1` an ulp is `2^-54`, so the refiner stops with `Resolution` once a new
/// leaf's sampling strata would span fewer than 16 ulps (depth 48); near `sqrt(2) / 1000` it
/// reaches the limit 52. Either way: no NaN; every active function keeps `rho` samples per
/// leaf of its support (column counts of an independently built `K`); the evaluation agrees
/// with `K c` at the samples and with the crate's `Fit` evaluator; the quadrature error is
/// finite and at the size of the unresolved cell (`sqrt(2^-d)`); and the coefficients equal the
/// dense pseudo-inverse solution on the final `K` (a global SVD) to `1e-7` relative, the
/// SVD's `cond(K) eps` with `cond(K) <~ 1e7` (a deep tree is as well conditioned as a shallow
/// one: each level carries `rho` samples per function).
#[test]
fn refinement_reaches_the_resolution_of_f64_next_to_a_non_dyadic_jump() {
    let (a, b) = (
        std::f64::consts::SQRT_2 - 1.0,
        std::f64::consts::SQRT_2 / 1000.0,
    );
    for (jump, deepest) in [(a, 47), (b, 52)] {
        let oracle = ExpressionOracle::parse(&format!("x^2 - 2*x - (x > {jump:?})")).unwrap();
        let params = to_the_resolution(Domain::UNIT, SEED_A);
        let r = refine(&oracle, &params).unwrap();
        deep_refinement_checks(&r, &oracle, jump, deepest);
    }
}

/// Parameters that let the tree go as deep as it can: the depth limit at its largest and a
/// tolerance no estimate reaches, 3000 samples.
fn to_the_resolution(domain: Domain, seed: u64) -> RefineParams {
    let mut params = RefineParams {
        domain,
        ..RefineParams::default()
    };
    params.interval.max_depth = MAX_DEPTH_LIMIT;
    params.stop.tolerance = 1e-14;
    params.stop.budget = 3000;
    params.sampling.seed = seed;
    params
}

fn deep_refinement_checks(r: &Refinement, oracle: &ExpressionOracle, jump: f64, deepest: i32) {
    let depth = r.tree.depth();
    assert!(depth >= deepest, "depth {depth}, stop {:?}", r.stop);
    assert!(
        matches!(r.stop, StopReason::Resolution | StopReason::DepthLimit),
        "{:?} at depth {depth}",
        r.stop
    );
    assert!(r.coefficients().iter().all(|c| c.is_finite()));
    // Local oversampling on the final tree.
    let active = r.tree.active_set().unwrap();
    let positions: Vec<f64> = r.samples.iter().map(|s| s.x).collect();
    let k = kernel_matrix(&active, &positions).unwrap();
    let leaves = r.tree.leaves();
    let mid: Vec<f64> = leaves
        .iter()
        .map(|l| {
            let (a, b) = l.unit_bounds();
            0.5 * (a + b)
        })
        .collect();
    for (c, column) in k.to_csc().outer_iterator().enumerate() {
        let (lo, hi) = r.tree.support_unit(active.global(c));
        let slots = mid.iter().filter(|&&t| lo <= t && t <= hi).count();
        assert!(column.nnz() >= 2 * slots, "function {}", active.global(c));
    }
    for leaf in &leaves {
        let count = r.samples.iter().filter(|s| leaf.contains(s.t)).count();
        assert!(count >= 2, "leaf {leaf:?} holds {count}");
    }
    // Kernel and evaluation: K c at the samples is the reconstruction there.
    let at_samples = r.evaluate(&positions).unwrap();
    let kc: Vec<f64> = k
        .outer_iterator()
        .map(|row| row.iter().map(|(c, v)| v * r.coefficients()[c]).sum())
        .collect();
    let scale = at_samples.iter().fold(1.0f64, |m, v| m.max(v.abs()));
    for (i, (a, b)) in at_samples.iter().zip(&kc).enumerate() {
        assert!(
            (a - b).abs() <= 1e-12 * scale,
            "sample {i}: {a} against K c = {b}"
        );
    }
    // Values next to the jump, on both sides, within a few cells of the finest level.
    let h = (-(depth as f64)).exp2();
    let xs: Vec<f64> = [-64.0f64, -8.0, 8.0, 64.0, -1e-6, 1e-6, -1e-3, 1e-3]
        .iter()
        .map(|&d| jump + if d.abs() < 1.0 { d } else { d * h })
        .collect();
    let got = r.evaluate(&xs).unwrap();
    assert!(got.iter().all(|v| v.is_finite()));
    let via_fit = r.fit.evaluate(&xs).unwrap().swap_remove(0);
    for (a, b) in got.iter().zip(&via_fit) {
        assert!((a - b).abs() <= 1e-12 * scale, "{a} against the Fit's {b}");
    }
    // Away from the jump the reconstruction follows the signal: within 1e-2 of the unit jump
    // 8 cells away (the ringing of the unresolved cell decays over the supports), 1e-6 from
    // 64 cells on.
    for (i, (x, g)) in xs.iter().zip(&got).enumerate() {
        let bound = if i == 1 || i == 2 { 1e-2 } else { 1e-6 };
        let e = (g - oracle.sample(*x)).abs();
        assert!(e < bound, "x = {x}: {g}, error {e:e}");
    }
    // Quadrature on the leaves and the jump: finite, at the size of the unresolved cell.
    let mut breaks: Vec<f64> = leaves.iter().map(|l| l.unit_bounds().0).collect();
    breaks.push(jump);
    let q = quadrature_error(r, oracle, Domain::UNIT, &breaks, 2).unwrap();
    assert!(q.l2.is_finite() && q.max.is_finite());
    assert!(q.l2 < 64.0 * h.sqrt(), "L2 {} at depth {depth}", q.l2);
    let reference = dense_pinv(&k, 1e-14).unwrap();
    let values: Vec<f64> = r.samples.iter().map(|s| s.value).collect();
    let reference = reference.apply(&values).unwrap();
    let scale = reference.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    for (a, (x, y)) in r.coefficients().iter().zip(&reference).enumerate() {
        assert!(
            (x - y).abs() <= 1e-7 * scale,
            "coefficient {a}: {x} against the dense {y}"
        );
    }
}

/// Far from 0 the resolution of `f64` runs out early: on `[1000, 1001]` an ulp is `1.1e-13`,
/// so leaves below ~`2^-38` cannot hold two distinct positions. The refiner stops with
/// `Resolution` there (not an error, not a collapsed sample), and every sample is distinct.
#[test]
fn refinement_stops_at_the_resolution_of_the_domain() {
    let domain = Domain::new(1000.0, 1001.0).unwrap();
    let oracle = ExpressionOracle::parse("x - (x > 1000.3183098861837)").unwrap();
    let params = to_the_resolution(domain, SEED_B);
    let r = refine(&oracle, &params).unwrap();
    assert_eq!(r.stop, StopReason::Resolution, "depth {}", r.tree.depth());
    let depth = r.tree.depth();
    assert!((30..=40).contains(&depth), "depth {depth}");
    let mut xs: Vec<f64> = r.samples.iter().map(|s| s.x).collect();
    xs.sort_by(f64::total_cmp);
    let n = xs.len();
    xs.dedup();
    assert_eq!(xs.len(), n, "samples collapsed onto each other");
    for leaf in r.tree.leaves() {
        let count = r.samples.iter().filter(|s| leaf.contains(s.t)).count();
        assert!(count >= 2, "leaf {leaf:?} holds {count}");
    }
    assert!(r.coefficients().iter().all(|c| c.is_finite()));
}

/// Every way out a depth or budget error names is a real parameter with a value that works:
/// applying it makes the parameters valid (and never a depth above the limit of 52).
#[test]
fn depth_and_budget_hints_name_a_value_that_works() {
    let base = RefineParams::default();
    let cases = [
        RefineParams {
            interval: IntervalTreeParams {
                coarse: Some(40),
                max_depth: 40,
                ..base.interval
            },
            ..base
        },
        RefineParams {
            interval: IntervalTreeParams {
                coarse: Some(60),
                max_depth: 52,
                ..base.interval
            },
            ..base
        },
        RefineParams {
            interval: IntervalTreeParams {
                coarse: Some(50),
                max_depth: 40,
                ..base.interval
            },
            ..base
        },
        RefineParams {
            interval: IntervalTreeParams {
                base_depth: Some(51),
                max_depth: 52,
                ..base.interval
            },
            ..base
        },
        RefineParams {
            interval: IntervalTreeParams {
                base_depth: Some(30),
                max_depth: 20,
                ..base.interval
            },
            ..base
        },
        RefineParams {
            sampling: BaseSampling {
                base_samples: 100_000,
                ..base.sampling
            },
            interval: IntervalTreeParams {
                max_depth: 8,
                ..base.interval
            },
            ..base
        },
        RefineParams {
            sampling: BaseSampling {
                base_samples: 5000,
                ..base.sampling
            },
            stop: StopParams {
                budget: 1000,
                ..base.stop
            },
            ..base
        },
        RefineParams {
            stop: StopParams {
                budget: 10,
                ..base.stop
            },
            ..base
        },
    ];
    for bad in cases {
        let err = bad.validate().expect_err("invalid");
        let text = err.to_string();
        let number = |key: &str| -> Option<u64> {
            let rest = &text[text.find(key)? + key.len()..];
            let digits: String = rest
                .trim_start()
                .chars()
                .take_while(|c| c.is_ascii_digit())
                .collect();
            digits.parse().ok()
        };
        let fixed = if let Some(v) = number("raise the max depth to at least") {
            assert!(v <= u64::from(MAX_DEPTH_LIMIT), "{text}");
            RefineParams {
                interval: IntervalTreeParams {
                    max_depth: v as u32,
                    ..bad.interval
                },
                ..bad
            }
        } else if let Some(v) = number("lower the coarse level n to at most") {
            RefineParams {
                interval: IntervalTreeParams {
                    coarse: Some(v as u32),
                    ..bad.interval
                },
                ..bad
            }
        } else if let Some(v) = number("lower the base depth to at most") {
            RefineParams {
                interval: IntervalTreeParams {
                    base_depth: Some(v as u32),
                    ..bad.interval
                },
                ..bad
            }
        } else if let Some(v) = number("lower the base samples to at most") {
            RefineParams {
                sampling: BaseSampling {
                    base_samples: v as usize,
                    ..bad.sampling
                },
                ..bad
            }
        } else if let Some(v) = number("raise the budget to at least") {
            RefineParams {
                stop: StopParams {
                    budget: v as usize,
                    ..bad.stop
                },
                ..bad
            }
        } else {
            panic!("no parameter and value in: {text}");
        };
        fixed
            .validate()
            .unwrap_or_else(|e| panic!("{text}\n  applied, still: {e}"));
    }
}
