//! The adaptive image engine (issue 13): the 2D wavelet tree, least squares on it, and the
//! refiner's rounds.

mod common;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::basis::tensor::TensorBasis;
use rkwave::basis::FilterFamily;
use rkwave::image::adaptive::{fit_tree, refine_image, AdaptiveError, AdaptiveParams, QuadTree};
use rkwave::image::fit::{fit_image, ImageFitParams, ImageLevels};
use rkwave::image::pixels::{fit_pixels, PixelFilter};
use rkwave::image::ImagePlane;
use rkwave::refine::StopReason;

use common::scenes::{edge_distance, jittered, polynomial, straight_edge};
use common::trees::random_tree;
use rkwave::image::adaptive::{
    GrowthParams, ImageSampling, MarkingParams, QuadTreeParams, StopParams, TreeParams,
};

fn basis(p: usize, w: usize, h: usize, j: (u32, u32)) -> TensorBasis {
    TensorBasis::new(p, FilterFamily::cdv_default(p), w, h, j).unwrap()
}

fn edge_scene(x: f64, y: f64) -> f64 {
    if x < 0.37 * 32.0 + 0.2 * y {
        0.2 + 0.01 * y
    } else {
        0.9 - 0.005 * x
    }
}

/// A tree full up to the depth limit spans `V_J (x) V_J`: the same least-squares solution as
/// the uniform single-scale engine, so the same single-scale coefficients and pixels. Both
/// solve a well-posed problem (8 spp, one function per pixel) through Cholesky of normal
/// matrices related by an orthogonal change of basis; `cond(G) < 1e3` here, so `1e-10`
/// leaves a wide margin over `cond * eps`.
#[test]
fn full_tree_equals_uniform_engine() {
    let (w, h) = (32, 24);
    let (xs, ys) = jittered(w, h, 8, 3);
    let f: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(&x, &y)| edge_scene(x, y))
        .collect();
    let g: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(&x, &y)| (x * 0.3).sin() + y * 0.01)
        .collect();
    let values: Vec<&[f64]> = vec![&f, &g];
    let j = (5, 5);
    let b = basis(2, w, h, j);
    let steps = b.steps();
    let tree = QuadTree::uniform(b, steps);
    assert_eq!(tree.len(), 32 * 32);
    let fit = fit_tree(&tree, &xs, &ys, &values).unwrap();
    assert_eq!(fit.report.ridge, 0.0);
    let params = ImageFitParams {
        levels: ImageLevels::Fixed(j.0, j.1),
        ridge: 0.0,
        ..ImageFitParams::default()
    };
    let uniform = fit_image(w, h, &xs, &ys, &values, &params).unwrap();
    let single = fit.single_scale(&tree);
    for (c, (s, u)) in single.iter().zip(&uniform.coefficients).enumerate() {
        let err = s
            .iter()
            .zip(u)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-10, "channel {c}: coefficients differ by {err:e}");
    }
    let tree_px = fit.box_pixels(&tree).unwrap();
    let uni_px = fit_pixels(&uniform, PixelFilter::Box).unwrap();
    for (c, (t, u)) in tree_px.iter().zip(&uni_px).enumerate() {
        let err = t
            .iter()
            .zip(u)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-10, "channel {c}: pixels differ by {err:e}");
    }
}

/// Tensor polynomials of degree `< p` in each variable lie in the coarse space, which every
/// tree holds: the fit reproduces them at any point and their box pixels exactly. Values are
/// O(10); the fit is exact up to `cond * eps`, so 1e-9 absolute.
#[test]
fn tensor_polynomials_reproduced_on_any_tree() {
    for (p, seed) in [(2usize, 1u64), (3, 2)] {
        let (w, h) = (40, 32);
        let b = basis(p, w, h, (7, 7));
        let tree = random_tree(b, 1, 60, seed);
        // parent closure holds
        let (nx, _) = tree.basis().dims();
        for f in tree.functions() {
            if let Some(c) = tree.cell_of_function(f) {
                assert!(tree.is_active(c), "function {f} (x {}) of {c:?}", f % nx);
                if let Some(parent) = c.parent() {
                    assert!(tree.is_active(parent));
                }
            }
        }
        let poly = |x: f64, y: f64| {
            let (u, v) = (x / 10.0, y / 10.0);
            if p == 2 {
                1.0 + 2.0 * u - 0.5 * v + 0.3 * u * v
            } else {
                1.0 + u * u - 0.5 * v * v * u + 0.2 * u * u * v * v - v
            }
        };
        let (xs, ys) = jittered(w, h, 6, seed + 10);
        let f: Vec<f64> = xs.iter().zip(&ys).map(|(&x, &y)| poly(x, y)).collect();
        let fit = fit_tree(&tree, &xs, &ys, &[&f]).unwrap();
        let mut rng = Pcg64::seed_from_u64(seed);
        for _ in 0..50 {
            let (x, y) = (
                rng.random::<f64>() * w as f64,
                rng.random::<f64>() * h as f64,
            );
            let v = fit.evaluate(&tree, x, y).unwrap()[0];
            assert!((v - poly(x, y)).abs() < 1e-9, "p = {p} at ({x}, {y}): {v}");
        }
        // box pixels: exact integrals of the polynomial (Simpson is exact for degree <= 3 per
        // axis, and these have degree <= 2 per axis)
        let px = fit.box_pixels(&tree).unwrap();
        for (py, pxl) in [(0usize, 0usize), (5, 17), (31, 39), (12, 3)] {
            let simpson =
                |g: &dyn Fn(f64) -> f64, a: f64| (g(a) + 4.0 * g(a + 0.5) + g(a + 1.0)) / 6.0;
            let exact = simpson(&|y| simpson(&|x| poly(x, y), pxl as f64), py as f64);
            let got = px[0][py * w + pxl];
            assert!(
                (got - exact).abs() < 1e-9,
                "pixel ({pxl}, {py}): {got} vs {exact}"
            );
        }
    }
}

/// The depth map and slots agree: slots partition the image, each point's slot has the
/// point's depth, and a slot's parent is active.
#[test]
fn slots_partition_the_image() {
    let b = basis(2, 48, 32, (7, 7));
    let tree = random_tree(b, 1, 40, 9);
    let area: f64 = tree
        .leaves()
        .iter()
        .map(|&c| {
            let r = tree.rect(c);
            assert!(!tree.is_active(c));
            if let Some(parent) = c.parent() {
                assert!(tree.is_active(parent));
            }
            (r[1] - r[0]) * (r[3] - r[2])
        })
        .sum();
    assert!((area - 48.0 * 32.0).abs() < 1e-9);
    let mut rng = Pcg64::seed_from_u64(4);
    for _ in 0..200 {
        let (x, y) = (rng.random::<f64>() * 48.0, rng.random::<f64>() * 32.0);
        let s = tree.leaf_at(x, y);
        let r = tree.rect(s);
        assert!(r[0] <= x && x <= r[1] && r[2] <= y && y <= r[3]);
        assert_eq!(tree.depth_at(x, y), s.step);
    }
}

fn params(budget: usize) -> AdaptiveParams {
    AdaptiveParams {
        stop: StopParams {
            budget,
            ..AdaptiveParams::default().stop
        },
        ..AdaptiveParams::default()
    }
}

/// A polynomial of degree < p: every wavelet coefficient is zero up to rounding, the
/// estimate is at rounding level, so the refiner stops at once without deepening.
#[test]
fn polynomial_scene_is_not_deepened() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let p = AdaptiveParams {
        stop: StopParams {
            tolerance: 1e-8,
            ..(params(20_000)).stop
        },
        ..params(20_000)
    };
    let run = refine_image(&polynomial, plane, &p).unwrap();
    assert_eq!(run.report.stop, StopReason::Tolerance);
    assert_eq!(run.report.rounds.len(), 1);
    assert_eq!(run.xs.len(), run.report.base_samples);
    let base_step = run.report.base_levels.0 - run.report.coarse_levels.0;
    assert!(run.tree.leaves().iter().all(|c| c.step == base_step));
}

/// A single straight edge: the refiner deepens along it and nowhere far from it.
#[test]
fn depth_concentrates_along_a_straight_edge() {
    let (w, h) = (48, 48);
    let plane = ImagePlane::new(w, h).unwrap();
    let run = refine_image(&straight_edge, plane, &params(4 * w * h)).unwrap();
    let base = run.report.base_levels.0 - run.report.coarse_levels.0;
    let depth = run.tree.depth_map();
    let (mut near, mut n_near, mut far, mut n_far) = (0.0, 0, 0.0, 0);
    for py in 0..h {
        for px in 0..w {
            let d = edge_distance(px as f64 + 0.5, py as f64 + 0.5);
            let dep = depth[py * w + px];
            if d < 0.5 {
                near += dep as f64;
                n_near += 1;
            } else if d > 8.0 {
                n_far += 1;
                far += dep as f64;
            }
        }
    }
    let near = near / n_near as f64;
    assert!(
        near >= base as f64 + 2.0,
        "mean depth on the edge {near}, base {base}"
    );
    let far = far / n_far as f64;
    assert!(
        far <= base as f64 + 0.5,
        "mean depth beyond 8 px {far}, base {base}"
    );
}

/// The invariant `samples(slot) >= ceil(rho)` and the budget hold after every round (runs
/// stopped after `r` rounds are prefixes of the full run: the refiner is deterministic).
#[test]
fn invariant_and_budget_after_every_round() {
    let (w, h) = (32, 32);
    let plane = ImagePlane::new(w, h).unwrap();
    for (budget, rho) in [(4 * w * h, 4.0), (3 * w * h, 2.5)] {
        for rounds in 0..5 {
            let mut p = params(budget);
            p.stop.max_rounds = rounds;
            p.tree.rho = rho;
            p.sampling.seed = 7;
            let run = refine_image(&straight_edge, plane, &p).unwrap();
            assert!(run.xs.len() <= budget, "{} > {budget}", run.xs.len());
            let counts = run.tree.leaf_counts(&run.xs, &run.ys);
            for slot in run.tree.leaves() {
                let c = counts.get(&slot).copied().unwrap_or(0);
                assert!(c >= rho.ceil() as usize, "slot {slot:?} has {c} samples");
            }
        }
    }
}

/// Small budgets: never exceeded, and the stop reason says so.
#[test]
fn budget_never_exceeded() {
    let plane = ImagePlane::new(32, 32).unwrap();
    for budget in [1024, 1500, 2048, 2500, 5000] {
        let run = refine_image(&straight_edge, plane, &params(budget)).unwrap();
        assert!(run.xs.len() <= budget);
        assert!(matches!(
            run.report.stop,
            StopReason::Budget | StopReason::DepthLimit | StopReason::MaxRounds
        ));
    }
}

#[test]
fn deterministic_for_a_seed() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let a = refine_image(&straight_edge, plane, &params(3000)).unwrap();
    let b = refine_image(&straight_edge, plane, &params(3000)).unwrap();
    assert_eq!(a.xs, b.xs);
    assert_eq!(a.ys, b.ys);
    assert_eq!(a.image, b.image);
    let c = refine_image(
        &straight_edge,
        plane,
        &AdaptiveParams {
            sampling: ImageSampling {
                seed: 2,
                ..(params(3000)).sampling
            },
            ..params(3000)
        },
    )
    .unwrap();
    assert_ne!(a.xs, c.xs);
}

#[test]
fn bad_input_gives_typed_errors() {
    let plane = ImagePlane::new(32, 32).unwrap();
    let bad = |p: AdaptiveParams| refine_image(&straight_edge, plane, &p).unwrap_err();
    assert!(matches!(
        bad(params(0)),
        AdaptiveError::Parameter {
            parameter: "budget",
            ..
        }
    ));
    for (rho, theta) in [(f64::NAN, 0.5), (0.5, 0.5), (4.0, 0.0), (4.0, f64::NAN)] {
        let e = bad(AdaptiveParams {
            tree: TreeParams {
                rho,
                ..(params(5000)).tree
            },
            marking: MarkingParams { theta },
            ..params(5000)
        });
        assert!(matches!(e, AdaptiveError::Parameter { .. }), "{e}");
    }
    let e = bad(AdaptiveParams {
        stop: StopParams {
            tolerance: -1.0,
            ..(params(5000)).stop
        },
        ..params(5000)
    });
    assert!(e.to_string().contains("tolerance"));
    // 8 x 8 coarse + 16 x 16 base slots at 4 samples need 1024
    let e = bad(params(100));
    assert!(matches!(e, AdaptiveError::BudgetTooSmall { .. }), "{e}");
    assert!(e.to_string().contains("100"));
    let e = bad(AdaptiveParams {
        quad: QuadTreeParams {
            base_level: Some(2),
            ..(params(5000)).quad
        },
        ..params(5000)
    });
    assert!(matches!(e, AdaptiveError::Parameter { .. }), "{e}");
    // fit_tree on bad samples
    let tree = QuadTree::uniform(basis(2, 32, 32, (6, 6)), 1);
    let nan = [0.0, f64::NAN];
    let e = fit_tree(&tree, &[1.0, 2.0], &[1.0, 2.0], &[&nan]).unwrap_err();
    assert!(e.to_string().contains("not finite"), "{e}");
    let e = fit_tree(&tree, &[1.0, 40.0], &[1.0, 2.0], &[&[0.0, 1.0]]).unwrap_err();
    assert!(e.to_string().contains("outside"), "{e}");
    let e = fit_tree(&tree, &[1.0], &[1.0, 2.0], &[&[0.0]]).unwrap_err();
    assert!(e.to_string().contains("ys"), "{e}");
}

/// A one-channel scene.
type Scene2 = dyn Fn(f64, f64) -> f64 + Sync;

/// Fine detail everywhere (a chirp) beside a straight edge: the significant slots run out
/// long before the budget does.
fn edge_and_chirp(x: f64, y: f64) -> f64 {
    straight_edge(x, y) + 0.2 * (0.02 * (x * x + y * y)).sin()
}

/// The round schedule: every round that samples adds at least `min_growth` times the
/// samples of its fit, or the whole rest of the budget (less the coverage rule's reserve) (the marked slots' children, and the
/// spare samples spread over the other slots); so a run that stops at the budget has spent it
/// exactly, in at most `log(budget / base) / log(1 + min_growth) + 1` sampling rounds.
/// Both spreading rules, two budgets and scenes (a lone edge: few significant slots; an edge
/// and a chirp: detail at the depth limit).
#[test]
fn every_round_grows_by_the_least_growth_or_spends_the_budget() {
    use rkwave::image::adaptive::marking::SpreadRule;
    let plane = ImagePlane::new(32, 32).unwrap();
    let scenes: [(&str, &Scene2); 2] = [
        ("edge", &straight_edge),
        ("edge and chirp", &edge_and_chirp),
    ];
    for (name, scene) in scenes {
        for spread in SpreadRule::ALL {
            for budget in [4 * 1024, 8 * 1024 + 3] {
                let p = AdaptiveParams {
                    growth: GrowthParams {
                        spread,
                        ..(params(budget)).growth
                    },
                    ..params(budget)
                };
                let run = refine_image(&scene, plane, &p).unwrap();
                let rounds = &run.report.rounds;
                let what = format!("{name}, {spread:?}, budget {budget}");
                for pair in rounds.windows(2) {
                    let (now, next) = (pair[0].samples, pair[1].samples);
                    // the coverage rule's reserve is not the round's to spend, and a fill
                    // round adds exactly the samples it tops the pixels up with
                    let least = ((p.growth.min_growth * now as f64).ceil() as usize)
                        .min(budget - now - pair[0].reserved);
                    if pair[0].filled > 0 {
                        assert_eq!(next - now, pair[0].filled, "{what}");
                        continue;
                    }
                    assert!(
                        next - now >= least,
                        "{what}: round {} added {} samples to {now}, least {least}",
                        pair[0].round,
                        next - now
                    );
                }
                assert!(run.xs.len() <= budget, "{what}");
                if run.report.stop == StopReason::Budget {
                    assert_eq!(run.xs.len(), budget, "{what}: budget left");
                }
                let most = (budget as f64 / run.report.base_samples as f64).ln()
                    / (1.0 + p.growth.min_growth).ln()
                    + 1.0;
                assert!(
                    (rounds.len() - 1) as f64 <= most,
                    "{what}: {} sampling rounds, at most {most:.1}",
                    rounds.len() - 1
                );
            }
        }
    }
}
