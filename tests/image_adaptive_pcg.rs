//! The matrix-free PCG tree solve (issue 13, "each round costs what changed") against the
//! assembled kernel and the direct solve, on random trees and samples.

mod common;

use common::scenes::jittered_with;
use common::trees::{deepen_randomly, sample_slots};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::basis::tensor::TensorBasis;
use rkwave::basis::FilterFamily;
use rkwave::image::adaptive::fit::tree_kernel;
use rkwave::image::adaptive::pcg::{SingleScaleRows, TreeNormalOperator};
use rkwave::image::adaptive::{fit_tree_with, QuadTree, TreeSolver};
use rkwave::image::adaptive::{FitParams, StopParams};

/// A random tree on a 16 x 16 image (p = 2, levels (5, 5), half-pixel limit): the base step 1
/// full, then `deepen` random slots below the limit activated, and `spp` jittered samples per
/// pixel plus 4 more in every slot's cell (so every slot keeps samples).
fn random_case(seed: u64, deepen: usize, spp: usize) -> (QuadTree, Vec<f64>, Vec<f64>) {
    let basis = TensorBasis::new(2, FilterFamily::cdv_default(2), 16, 16, (5, 5)).unwrap();
    let mut tree = QuadTree::uniform(basis, 1);
    let mut rng = Pcg64::seed_from_u64(seed);
    deepen_randomly(&mut tree, deepen, &mut rng);
    let (mut xs, mut ys) = jittered_with(16, 16, spp, &mut rng);
    sample_slots(&tree, 4, &mut rng, &mut xs, &mut ys);
    (tree, xs, ys)
}

fn scene(x: f64, y: f64) -> f64 {
    let edge = if x + 0.3 * y < 9.3 { 0.2 } else { 0.8 };
    edge + 0.01 * x * y / 16.0
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// `K_T c` and `K_T^T r` through the single-scale rows and the 2D FWT equal the assembled tree
/// kernel's products: both are the same sums in another order (the synthesis is exact), so
/// they agree to rounding, `1e-12` relative.
#[test]
fn matrix_free_products_equal_the_assembled_kernel() {
    for seed in 0..3 {
        let (tree, xs, ys) = random_case(seed, 40, 2);
        let functions = tree.functions();
        let k = tree_kernel(&tree, &functions, &xs, &ys);
        let rows = SingleScaleRows::new(tree.basis(), &xs, &ys);
        assert_eq!(rows.len(), xs.len());
        let op = TreeNormalOperator::new(&tree, &rows, &xs, &ys);
        let mut rng = Pcg64::seed_from_u64(100 + seed);
        let c: Vec<f64> = functions
            .iter()
            .map(|_| rng.random::<f64>() - 0.5)
            .collect();
        let mut full = vec![0.0; tree.basis().len()];
        for (&f, &v) in functions.iter().zip(&c) {
            full[f] = v;
        }
        let want = csr_times(&k, &c);
        let got = op.values(&full);
        let diff: Vec<f64> = want.iter().zip(&got).map(|(a, b)| a - b).collect();
        assert!(norm(&diff) <= 1e-12 * norm(&want), "K c: {}", norm(&diff));
        let r: Vec<f64> = xs.iter().map(|_| rng.random::<f64>() - 0.5).collect();
        let kt = k.transpose_view().to_csr();
        let want = csr_times(&kt, &r);
        let got = op.rhs(&r);
        let got: Vec<f64> = functions.iter().map(|&f| got[f]).collect();
        let diff: Vec<f64> = want.iter().zip(&got).map(|(a, b)| a - b).collect();
        assert!(norm(&diff) <= 1e-12 * norm(&want), "K^T r: {}", norm(&diff));
        // nothing leaks off the tree
        let all = op.rhs(&r);
        let on: std::collections::HashSet<usize> = functions.iter().copied().collect();
        assert!(all
            .iter()
            .enumerate()
            .all(|(i, &v)| on.contains(&i) || v == 0.0));
    }
}

/// `A v` for a CSR matrix and a plain vector.
fn csr_times(a: &sprs::CsMat<f64>, v: &[f64]) -> Vec<f64> {
    a.outer_iterator()
        .map(|row| row.iter().map(|(j, x)| x * v[j]).sum())
        .collect()
}

/// PCG and the direct solve agree. With `r = b - G x` the PCG residual and `x*` the exact
/// solution, `||x - x*|| <= ||G^-1|| ||r||` and `||x*|| >= ||b|| / ||G||`, so the relative
/// coefficient difference is at most `kappa(G) ||r|| / ||b||`; the direct solve adds its own
/// `~kappa eps`. `kappa(G)` is computed exactly from the dense `G` of the test's small tree.
#[test]
fn pcg_agrees_with_the_direct_solve_within_kappa_times_residual() {
    for seed in 0..3 {
        let (tree, xs, ys) = random_case(seed, 30, 2);
        let v0: Vec<f64> = xs.iter().zip(&ys).map(|(&x, &y)| scene(x, y)).collect();
        let v1: Vec<f64> = xs
            .iter()
            .zip(&ys)
            .map(|(&x, &y)| (0.3 * x).sin() * y)
            .collect();
        let values: Vec<&[f64]> = vec![&v0, &v1];
        let direct = fit_tree_with(&tree, &xs, &ys, &values, TreeSolver::Direct, None).unwrap();
        assert_eq!(direct.report.ridge, 0.0, "the case is well sampled");
        let tol = 1e-11;
        let solver = TreeSolver::Pcg {
            tolerance: tol,
            max_iterations: 5000,
        };
        let it = fit_tree_with(&tree, &xs, &ys, &values, solver, None).unwrap();
        let r = &it.report;
        assert_eq!(r.solver, "pcg");
        assert!(r.converged && r.relative_residual <= tol, "{r:?}");
        assert!(r.iterations > 0 && r.condition >= 1.0);
        // kappa(G) from the dense normal matrix
        let functions = tree.functions();
        let k = tree_kernel(&tree, &functions, &xs, &ys);
        let kd = DMatrix::from_fn(xs.len(), functions.len(), |i, j| {
            *k.get(i, j).unwrap_or(&0.0)
        });
        let g = kd.transpose() * &kd;
        let eig = g.symmetric_eigenvalues();
        let kappa = eig.max() / eig.min();
        assert!(kappa.is_finite() && kappa > 1.0);
        for c in 0..2 {
            let d = DVector::from_iterator(
                functions.len(),
                functions.iter().map(|&f| direct.coefficients[c][f]),
            );
            let p = DVector::from_iterator(
                functions.len(),
                functions.iter().map(|&f| it.coefficients[c][f]),
            );
            let rel = (&d - &p).norm() / d.norm();
            let bound = kappa * (r.relative_residual + 1e-14) * 2.0;
            assert!(
                rel <= bound,
                "seed {seed}: {rel:e} > {bound:e} (kappa {kappa:e})"
            );
            // off the tree both are exactly 0
            assert!(it.coefficients[c]
                .iter()
                .enumerate()
                .all(|(i, &v)| functions.binary_search(&i).is_ok() || v == 0.0));
        }
    }
}

/// A warm start at the solution needs no iteration, and a stalled PCG on a small tree (one
/// iteration allowed) hands over to the direct solve, saying so.
#[test]
fn warm_start_and_fallback_are_reported() {
    let (tree, xs, ys) = random_case(7, 20, 2);
    let v: Vec<f64> = xs.iter().zip(&ys).map(|(&x, &y)| scene(x, y)).collect();
    let values: Vec<&[f64]> = vec![&v];
    let solver = TreeSolver::Pcg {
        tolerance: 1e-9,
        max_iterations: 2000,
    };
    let cold = fit_tree_with(&tree, &xs, &ys, &values, solver, None).unwrap();
    let warm = fit_tree_with(&tree, &xs, &ys, &values, solver, Some(&cold.coefficients)).unwrap();
    assert!(warm.report.converged);
    assert!(
        warm.report.iterations < cold.report.iterations.max(1),
        "{} !< {}",
        warm.report.iterations,
        cold.report.iterations
    );
    let stalled = TreeSolver::Pcg {
        tolerance: 1e-14,
        max_iterations: 1,
    };
    let fb = fit_tree_with(&tree, &xs, &ys, &values, stalled, None).unwrap();
    assert_eq!(fb.report.solver, "pcg->direct");
    assert!(!fb.report.converged && fb.report.iterations == 1);
    let direct = fit_tree_with(&tree, &xs, &ys, &values, TreeSolver::Direct, None).unwrap();
    assert_eq!(fb.coefficients, direct.coefficients);
}

/// Additive Schwarz (overlapping tiles, every level in each): one tile covering the image is
/// the whole `G`, so `M^{-1} = G^{-1}` and CG converges in one iteration (to rounding); with
/// 4-pixel tiles it agrees with the direct solve within `kappa(G)` times its residual (as
/// above) and needs fewer iterations than Jacobi-PCG on the same normal equations.
#[test]
fn schwarz_pcg_is_exact_on_one_tile_and_beats_jacobi_on_small_tiles() {
    for seed in 0..3 {
        let (tree, xs, ys) = random_case(20 + seed, 30, 2);
        let v: Vec<f64> = xs.iter().zip(&ys).map(|(&x, &y)| scene(x, y)).collect();
        let values: Vec<&[f64]> = vec![&v];
        let direct = fit_tree_with(&tree, &xs, &ys, &values, TreeSolver::Direct, None).unwrap();
        let schwarz = |tile: f64, halo: f64| TreeSolver::Schwarz {
            tolerance: 1e-11,
            max_iterations: 2000,
            tile,
            halo,
        };
        let one = fit_tree_with(&tree, &xs, &ys, &values, schwarz(16.0, 0.0), None).unwrap();
        let r = &one.report;
        assert_eq!(r.solver, "schwarz");
        assert_eq!(r.schwarz.unwrap().blocks, 1);
        assert!(r.converged && r.iterations <= 1, "one tile: {r:?}");
        let tiles = fit_tree_with(&tree, &xs, &ys, &values, schwarz(4.0, 1.0), None).unwrap();
        let t = &tiles.report;
        assert!(t.converged && t.schwarz.unwrap().blocks == 16, "{t:?}");
        let jacobi = TreeSolver::Pcg {
            tolerance: 1e-11,
            max_iterations: 2000,
        };
        let j = fit_tree_with(&tree, &xs, &ys, &values, jacobi, None).unwrap();
        assert!(
            t.iterations < j.report.iterations,
            "seed {seed}: Schwarz {} >= Jacobi {}",
            t.iterations,
            j.report.iterations
        );
        let functions = tree.functions();
        let k = tree_kernel(&tree, &functions, &xs, &ys);
        let kd = DMatrix::from_fn(xs.len(), functions.len(), |i, j| {
            *k.get(i, j).unwrap_or(&0.0)
        });
        let eig = (kd.transpose() * &kd).symmetric_eigenvalues();
        let kappa = eig.max() / eig.min();
        let pick =
            |c: &[f64]| DVector::from_iterator(functions.len(), functions.iter().map(|&f| c[f]));
        let d = pick(&direct.coefficients[0]);
        for (fit, res) in [(&one, r.relative_residual), (&tiles, t.relative_residual)] {
            let rel = (&d - pick(&fit.coefficients[0])).norm() / d.norm();
            let bound = kappa * (res + 1e-14) * 2.0;
            assert!(rel <= bound, "seed {seed}: {rel:e} > {bound:e}");
        }
    }
}

/// Impossible Schwarz parameters are refused by name before any work.
#[test]
fn bad_schwarz_parameters_are_refused() {
    use rkwave::image::adaptive::{AdaptiveError, AdaptiveParams};
    for (tolerance, max_iterations, tile, halo) in [
        (0.0, 10, 8.0, 1.0),
        (1e-8, 0, 8.0, 1.0),
        (1e-8, 10, 0.5, 1.0),
        (1e-8, 10, f64::NAN, 1.0),
        (1e-8, 10, 8.0, -1.0),
    ] {
        let params = AdaptiveParams {
            stop: StopParams {
                budget: 1000,
                ..AdaptiveParams::default().stop
            },
            fit: FitParams {
                solver: TreeSolver::Schwarz {
                    tolerance,
                    max_iterations,
                    tile,
                    halo,
                },
                ..AdaptiveParams::default().fit
            },
            ..AdaptiveParams::default()
        };
        match params.validate() {
            Err(AdaptiveError::Parameter { parameter, .. }) => assert_eq!(parameter, "solver"),
            other => panic!("{tolerance} {max_iterations} {tile} {halo}: {other:?}"),
        }
    }
}

/// Loose rounds, accurate output ([`AdaptiveParams::round_tolerance`]): the rounds' PCG fits
/// stop at the round tolerance (they only feed the indicator), and the fit of the stopping
/// round is continued to the solver's own tolerance, so the output coefficients are the least
/// squares solution on the final tree and samples. Checked against the direct solve there:
/// within `1e-7` relative (the continuation stops at a normal-equation residual of `1e-12`;
/// with a condition of the Jacobi-scaled `G` of order `1e3` the coefficient error is below
/// `1e-9`), while a fit stopped at the round tolerance is off by more than `1e-5`. The direct
/// solve has no tolerance: the setting leaves its run bit for bit unchanged.
#[test]
fn loose_rounds_end_in_the_accurate_fit() {
    use rkwave::image::adaptive::{fit_tree, refine_image, AdaptiveParams};
    use rkwave::image::ImagePlane;
    let plane = ImagePlane::new(32, 32).unwrap();
    let edge = |x: f64, y: f64| if x + 0.4 * y < 17.0 { 0.2 } else { 0.9 };
    let pcg = TreeSolver::Pcg {
        tolerance: 1e-12,
        max_iterations: 5000,
    };
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        fit: FitParams {
            solver: pcg,
            round_tolerance: Some(1e-2),
            ..AdaptiveParams::default().fit
        },
        ..AdaptiveParams::default()
    };
    let run = refine_image(&edge, plane, &params).unwrap();
    let rounds = &run.report.rounds;
    assert!(rounds.len() >= 3, "{} rounds", rounds.len());
    for r in &rounds[..rounds.len() - 1] {
        assert!(r.final_fit.is_none(), "round {}", r.round);
    }
    for r in rounds {
        assert!(
            r.fit.converged && r.fit.relative_residual <= 1e-2,
            "round {}",
            r.round
        );
    }
    let last = rounds
        .last()
        .unwrap()
        .final_fit
        .as_ref()
        .expect("continued");
    assert!(
        last.converged && last.relative_residual <= 1e-12,
        "{last:?}"
    );
    let values: Vec<&[f64]> = run.values.iter().map(|v| v.as_slice()).collect();
    let direct = fit_tree(&run.tree, &run.xs, &run.ys, &values).unwrap();
    let loose = fit_tree_with(
        &run.tree,
        &run.xs,
        &run.ys,
        &values,
        TreeSolver::Pcg {
            tolerance: 1e-2,
            max_iterations: 5000,
        },
        None,
    )
    .unwrap();
    let d = &direct.coefficients[0];
    let scale = norm(d);
    let diff = |c: &[f64]| norm(&c.iter().zip(d).map(|(a, b)| a - b).collect::<Vec<_>>()) / scale;
    let (accurate, early) = (diff(&run.fit.coefficients[0]), diff(&loose.coefficients[0]));
    assert!(accurate <= 1e-7, "continued fit off by {accurate:e}");
    assert!(
        early > 1e-5,
        "a loose fit is already accurate ({early:e}): the test shows nothing"
    );
    // the direct solve ignores it
    let reference = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        ..AdaptiveParams::default()
    };
    let with = AdaptiveParams {
        fit: FitParams {
            round_tolerance: Some(1e-2),
            ..reference.fit
        },
        ..reference
    };
    let (a, b) = (
        refine_image(&edge, plane, &reference).unwrap(),
        refine_image(&edge, plane, &with).unwrap(),
    );
    assert_eq!(a.image.channels, b.image.channels);
    assert!(b.report.rounds.iter().all(|r| r.final_fit.is_none()));
    // out of range
    for t in [0.0, 1.0, f64::NAN, -1e-3] {
        let bad = AdaptiveParams {
            fit: FitParams {
                round_tolerance: Some(t),
                ..params.fit
            },
            ..params
        };
        match bad.validate() {
            Err(rkwave::image::adaptive::AdaptiveError::Parameter { parameter, .. }) => {
                assert_eq!(parameter, "round_tolerance")
            }
            other => panic!("{t}: {other:?}"),
        }
    }
}

/// A round continues PCG's exact diagonal `G_aa = sum_i Psi_a(x_i)^2` ([`DiagonalSums`]):
/// the previous round's sums plus the new samples' terms, and for new functions their old
/// samples found through the cover of their supports. On random trees grown by random slots
/// and samples appended, the continued sums equal sums afresh to `1e-13` relative (the same
/// terms in another order: a few ulps of sums of at most a few hundred terms); a previous
/// state that is not a prefix (a tree that lost functions) is ignored, giving the fresh bits.
#[test]
fn the_continued_diagonal_equals_the_rebuilt_one() {
    use rkwave::image::adaptive::pcg::DiagonalSums;
    for seed in 0..6u64 {
        let (tree, xs, ys) = random_case(seed, 4, 2);
        let mut grown = tree.clone();
        let mut rng = Pcg64::seed_from_u64(seed + 100);
        for _ in 0..6 {
            let slots: Vec<_> = grown
                .leaves()
                .into_iter()
                .filter(|c| c.step < grown.steps())
                .collect();
            grown.deepen(slots[rng.random_range(0..slots.len())]);
        }
        assert!(grown.len() > tree.len());
        let old = xs.len() * 2 / 3;
        let before = DiagonalSums::new(&tree, &xs[..old], &ys[..old], None);
        let continued = DiagonalSums::new(&grown, &xs, &ys, Some(&before));
        let fresh = DiagonalSums::new(&grown, &xs, &ys, None);
        let scale = fresh.sums().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (a, (c, f)) in continued.sums().iter().zip(fresh.sums()).enumerate() {
            assert!(
                (c - f).abs() <= 1e-13 * scale,
                "seed {seed}, function {a}: {c} vs {f}"
            );
        }
        assert!(fresh.sums().iter().filter(|&&v| v > 0.0).count() > tree.len());
        // the grown tree's state does not continue into the smaller tree
        let back = DiagonalSums::new(&tree, &xs, &ys, Some(&fresh));
        let again = DiagonalSums::new(&tree, &xs, &ys, None);
        assert_eq!(back.sums(), again.sums());
    }
}

/// The exact diagonal evaluates each sample only to the depth the tree's functions reach
/// there; its sums equal, bit for bit, those of the whole multilevel evaluation of every
/// sample filtered by the tree (the same terms in the same order: 8 parts of consecutive
/// samples, each summed in sample order, the parts added in order), on random trees from
/// nearly uniform to deep in places.
#[test]
fn the_diagonal_to_the_local_depth_equals_the_whole_evaluation_bit_for_bit() {
    use rkwave::image::adaptive::pcg::DiagonalSums;
    for (seed, deepen) in [(0u64, 0usize), (1, 3), (2, 12), (3, 40), (4, 120)] {
        let (tree, xs, ys) = random_case(seed, deepen, 2);
        let basis = tree.basis();
        let mut mask = vec![false; basis.len()];
        tree.functions().into_iter().for_each(|f| mask[f] = true);
        let part = xs.len().div_ceil(8).max(1);
        let mut reference = vec![0.0; basis.len()];
        for (cx, cy) in xs.chunks(part).zip(ys.chunks(part)) {
            let mut ev = basis.multilevel_evaluator();
            let (mut row, mut acc) = (Vec::new(), vec![0.0; basis.len()]);
            for (&x, &y) in cx.iter().zip(cy) {
                ev.eval_unordered_into(x, y, &mut row).unwrap();
                for v in row.iter().filter(|v| mask[v.index]) {
                    acc[v.index] += v.value * v.value;
                }
            }
            reference.iter_mut().zip(acc).for_each(|(t, v)| *t += v);
        }
        let sums = DiagonalSums::new(&tree, &xs, &ys, None);
        for (a, (got, want)) in sums.sums().iter().zip(&reference).enumerate() {
            assert_eq!(got.to_bits(), want.to_bits(), "seed {seed}, function {a}");
        }
        assert!(reference.iter().filter(|&&v| v > 0.0).count() >= tree.len() * 9 / 10);
    }
}

/// `E` and `E^T` on `k` interleaved vectors (one pass over the rows for every channel, the
/// channel count unrolled as a constant for 1, 3, 4 and 7) give each vector's own product
/// bit for bit, for those counts and for the generic path (2, 5).
#[test]
fn interleaved_products_equal_one_vector_at_a_time() {
    let (tree, xs, ys) = random_case(7, 30, 2);
    let basis = tree.basis();
    let rows = SingleScaleRows::new(basis, &xs, &ys);
    let columns = rows.columns(basis.len());
    let n = basis.len();
    let mut rng = Pcg64::seed_from_u64(77);
    for k in [1usize, 2, 3, 4, 5, 7] {
        let s: Vec<Vec<f64>> = (0..k)
            .map(|_| (0..n).map(|_| rng.random::<f64>() - 0.5).collect())
            .collect();
        let r: Vec<Vec<f64>> = (0..k)
            .map(|_| xs.iter().map(|_| rng.random::<f64>() - 0.5).collect())
            .collect();
        let s_many: Vec<f64> = (0..n * k).map(|t| s[t % k][t / k]).collect();
        let r_many: Vec<f64> = (0..xs.len() * k).map(|t| r[t % k][t / k]).collect();
        let mut values = vec![0.0; xs.len() * k];
        rows.apply_many(&s_many, k, &mut values);
        let sums = columns.apply_many(&r_many, k);
        for c in 0..k {
            let mut one = vec![0.0; xs.len()];
            rows.apply(&s[c], &mut one);
            let mut back = vec![0.0; n];
            rows.apply_transpose(&r[c], &mut back);
            for (i, v) in one.iter().enumerate() {
                assert_eq!(
                    v.to_bits(),
                    values[i * k + c].to_bits(),
                    "k {k}, E, sample {i}"
                );
            }
            for (j, v) in back.iter().enumerate() {
                assert_eq!(
                    v.to_bits(),
                    sums[j * k + c].to_bits(),
                    "k {k}, E^T, function {j}"
                );
            }
        }
    }
}

/// [`AdaptiveParams::measure_rebuild`] measures each round's fit against the same fit from
/// scratch and changes nothing else: the run's pixels are bit for bit those of the run
/// without it (PCG and the direct solve), every round reports a rebuild of the same system
/// (functions, samples) solved to the round's tolerance, and the rebuilds' seconds are kept
/// out of the stage times.
#[test]
fn measuring_rebuilds_changes_nothing_else() {
    use rkwave::image::adaptive::{refine_image, AdaptiveParams};
    use rkwave::image::ImagePlane;
    let plane = ImagePlane::new(32, 32).unwrap();
    let edge = |x: f64, y: f64| if x + 0.4 * y < 17.0 { 0.2 } else { 0.9 };
    let pcg = TreeSolver::Pcg {
        tolerance: 1e-10,
        max_iterations: 5000,
    };
    for solver in [pcg, TreeSolver::Direct] {
        let plain = AdaptiveParams {
            stop: StopParams {
                budget: 4 * plane.pixels(),
                ..AdaptiveParams::default().stop
            },
            fit: FitParams {
                solver,
                ..AdaptiveParams::default().fit
            },
            ..AdaptiveParams::default()
        };
        let measured = AdaptiveParams {
            fit: FitParams {
                measure_rebuild: true,
                ..plain.fit
            },
            ..plain
        };
        let (a, b) = (
            refine_image(&edge, plane, &plain).unwrap(),
            refine_image(&edge, plane, &measured).unwrap(),
        );
        assert_eq!(a.image.channels, b.image.channels, "{solver:?}");
        assert_eq!(a.xs, b.xs);
        assert_eq!(a.report.times.rebuild_s, 0.0);
        assert!(b.report.times.rebuild_s > 0.0);
        assert!(b.report.rounds.len() >= 3);
        for r in &a.report.rounds {
            assert!(r.rebuild.is_none());
        }
        for r in &b.report.rounds {
            let rebuild = r.rebuild.as_ref().expect("measured");
            assert_eq!(rebuild.fit.functions, r.fit.functions, "round {}", r.round);
            assert_eq!(rebuild.fit.samples, r.fit.samples);
            assert!(
                rebuild.fit.converged,
                "round {}: {:?}",
                r.round, rebuild.fit
            );
            assert!(rebuild.fit.relative_residual <= 1e-2 || rebuild.fit.solver == "direct");
            assert!((rebuild.ratio - rebuild.round_s / rebuild.rebuild_s).abs() < 1e-12);
        }
    }
}

/// A round continues the single-scale rows ([`SingleScaleRows::continued`]): the previous
/// rows plus the new samples' rows are the rows afresh, bit for bit (each row is evaluated
/// alone); a previous state that is not a prefix (another last position, more rows than
/// positions, another basis) is ignored.
#[test]
fn continued_rows_equal_the_rows_afresh() {
    let (tree, xs, ys) = random_case(7, 30, 3);
    let basis = tree.basis();
    let n = basis.len();
    let mut rng = Pcg64::seed_from_u64(71);
    let s: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
    let values = |rows: &SingleScaleRows| {
        let mut out = vec![0.0; rows.len()];
        rows.apply(&s, &mut out);
        out.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
    };
    let fresh = values(&SingleScaleRows::new(basis, &xs, &ys));
    let m = xs.len();
    let mut rows = SingleScaleRows::continued(None, basis, &xs[..m / 3], &ys[..m / 3]);
    rows = SingleScaleRows::continued(Some(rows), basis, &xs[..m / 2], &ys[..m / 2]);
    rows = SingleScaleRows::continued(Some(rows), basis, &xs, &ys);
    assert_eq!(rows.len(), m);
    assert_eq!(values(&rows), fresh);
    // not a prefix: the positions changed under the rows
    let prefix = SingleScaleRows::new(basis, &xs[..m / 2], &ys[..m / 2]);
    let mut moved = xs.clone();
    moved[m / 2 - 1] = (moved[m / 2 - 1] + 0.5) % 16.0;
    let again = SingleScaleRows::continued(Some(prefix.clone()), basis, &moved, &ys);
    assert_eq!(
        values(&again),
        values(&SingleScaleRows::new(basis, &moved, &ys))
    );
    // more rows than positions, another basis
    let few = SingleScaleRows::continued(Some(prefix.clone()), basis, &xs[..3], &ys[..3]);
    assert_eq!(few.len(), 3);
    let other = TensorBasis::new(2, FilterFamily::cdv_default(2), 16, 16, (6, 6)).unwrap();
    let s6: Vec<f64> = (0..other.len())
        .map(|_| rng.random::<f64>() - 0.5)
        .collect();
    let on_other = SingleScaleRows::continued(Some(prefix), &other, &xs, &ys);
    let (mut a, mut b) = (vec![0.0; m], vec![0.0; m]);
    on_other.apply(&s6, &mut a);
    SingleScaleRows::new(&other, &xs, &ys).apply(&s6, &mut b);
    assert_eq!(a, b);
}

/// The noise test's probes at their own tolerance ([`FitParams::probe_tolerance`]): in every
/// round of a PCG run with the noise test, the report's channels are the image's (asked the
/// round tolerance, reached it) then the probes' (asked the probe tolerance, reached it,
/// never more iterations than the same run's probes at the round tolerance); the stopping
/// round's continued fit has the image's channels alone, at the solver's tolerance. Out of
/// range it is refused naming `probe_tolerance`.
#[test]
fn probes_stop_at_their_own_tolerance() {
    use rkwave::image::adaptive::{refine_image, AdaptiveParams};
    use rkwave::image::ImagePlane;
    let plane = ImagePlane::new(32, 32).unwrap();
    let noisy = |x: f64, y: f64| {
        let edge = if x + 0.4 * y < 17.0 { 0.2 } else { 0.9 };
        edge + 0.05 * ((x * 12.9898 + y * 78.233).sin() * 43758.5453).fract()
    };
    let base = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        fit: FitParams {
            solver: TreeSolver::plan_pcg(),
            round_tolerance: Some(1e-2),
            ..AdaptiveParams::default().fit
        },
        ..AdaptiveParams::default()
    };
    assert!(base.noise.false_alarm > 0.0 && base.noise.probes >= 1);
    let probes = base.noise.probes;
    let loose = AdaptiveParams {
        fit: FitParams {
            probe_tolerance: Some(5e-2),
            ..base.fit
        },
        ..base
    };
    let run = refine_image(&noisy, plane, &loose).unwrap();
    let rounds = &run.report.rounds;
    assert!(rounds.len() >= 2, "{} rounds", rounds.len());
    for r in rounds {
        let ch = &r.fit.channels;
        assert_eq!(ch.len(), 1 + probes, "round {}", r.round);
        assert!(
            ch[0].tolerance == 1e-2 && ch[0].residual <= 1e-2,
            "{:?}",
            ch[0]
        );
        for p in &ch[1..] {
            assert!(p.tolerance == 5e-2 && p.residual <= 5e-2, "{p:?}");
        }
    }
    let last = rounds
        .last()
        .unwrap()
        .final_fit
        .as_ref()
        .expect("continued");
    assert_eq!(last.channels.len(), 1);
    assert!(last.channels[0].tolerance == 3e-4 && last.channels[0].residual <= 3e-4);
    // the first round (zero starts on the same tree and samples) against the round tolerance
    let tight = refine_image(&noisy, plane, &base).unwrap();
    let first = (
        &rounds[0].fit.channels,
        &tight.report.rounds[0].fit.channels,
    );
    assert_eq!(first.0[0], first.1[0], "the image channel is unchanged");
    for (a, b) in first.0[1..].iter().zip(&first.1[1..]) {
        assert!(a.iterations <= b.iterations, "{a:?} against {b:?}");
        assert!(b.tolerance == 1e-2 && b.residual <= 1e-2);
    }
    for t in [0.0, 1.0, f64::NAN, -1e-3] {
        let bad = AdaptiveParams {
            fit: FitParams {
                probe_tolerance: Some(t),
                ..loose.fit
            },
            ..loose
        };
        match bad.validate() {
            Err(rkwave::image::adaptive::AdaptiveError::Parameter { parameter, .. }) => {
                assert_eq!(parameter, "probe_tolerance")
            }
            other => panic!("{t}: {other:?}"),
        }
    }
}
