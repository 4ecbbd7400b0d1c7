//! The one conjugate gradient (`rkwave::solve::cg`) against a dense solve: small random
//! symmetric positive definite systems `A = K^T K` (`K` a random banded `m x n` kernel-like
//! matrix), `k = 1..4` right-hand sides in lockstep, every preconditioner (identity, Jacobi,
//! local inversion, additive Schwarz), and the least-squares form (CGLS) against the dense
//! normal equations. The iteration limit is a report (`converged == false`), not an error.
//!
//! Tolerance. With `r = b - A x` the recomputed residual and `x*` the exact solution,
//! `||x - x*|| = ||A^{-1} r|| <= ||A^{-1}|| ||r||` and `||x*|| >= ||b|| / ||A||`, so
//! `||x - x*|| / ||x*|| <= kappa(A) ||r|| / ||b||`. The dense reference (nalgebra's
//! Cholesky) is itself off by about `kappa(A) n eps`. So each channel must satisfy
//! `rel <= kappa (res + n eps)`, with `kappa` from the dense eigenvalues; a factor 2 covers
//! the rounding of the bound's own ingredients.

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::solve::cg::{
    self, AdditiveSchwarz, CgParams, ConditionEstimate, Identity, Jacobi, LocalInverse,
    Preconditioner, ResidualReport, SparseOperator,
};
use rkwave::solve::{local_inversion, LocalInversionParams, Solver};
use sprs::{CsMat, TriMat};

/// Named seeds of the random systems.
const SEEDS: [u64; 4] = [11, 12, 13, 14];

/// A random banded `m x n` matrix (each row: 3 neighbouring columns around its position,
/// entries in `[-0.3, 0.7)`): full column rank for `m = 3 n` with probability one.
fn kernel(rng: &mut Pcg64, m: usize, n: usize) -> CsMat<f64> {
    let mut t = TriMat::new((m, n));
    for i in 0..m {
        let c = i * n / m;
        for j in c.saturating_sub(1)..(c + 2).min(n) {
            t.add_triplet(i, j, rng.random::<f64>() - 0.3);
        }
    }
    t.to_csr()
}

fn dense(a: &CsMat<f64>) -> DMatrix<f64> {
    let mut d = DMatrix::zeros(a.rows(), a.cols());
    for (v, (i, j)) in a.iter() {
        d[(i, j)] += *v;
    }
    d
}

/// `A = K^T K` as CSR (both triangles) and dense.
fn normal(k: &CsMat<f64>) -> (CsMat<f64>, DMatrix<f64>) {
    let kt: CsMat<f64> = k.transpose_view().to_csr();
    let a: CsMat<f64> = &kt * k;
    let d = dense(&a);
    (a.to_csr(), d)
}

fn kappa(a: &DMatrix<f64>) -> f64 {
    let eig = a.clone().symmetric_eigenvalues();
    eig.max() / eig.min()
}

fn params(tolerance: f64, max_iterations: usize) -> CgParams {
    CgParams {
        tolerance,
        max_iterations,
        residual: ResidualReport::Recomputed,
        condition: ConditionEstimate::Lanczos,
        forward_error: None,
    }
}

/// Checks every channel of a PCG solve against the dense Cholesky solve.
fn check(name: &str, a: &CsMat<f64>, ad: &DMatrix<f64>, pre: &dyn Preconditioner, k: usize) {
    let n = a.rows();
    let mut rng = Pcg64::seed_from_u64(n as u64 * 31 + k as u64);
    let bs: Vec<Vec<f64>> = (0..k)
        .map(|_| (0..n).map(|_| rng.random::<f64>() - 0.5).collect())
        .collect();
    let refs: Vec<&[f64]> = bs.iter().map(|b| b.as_slice()).collect();
    let tol = 1e-10;
    let (xs, report) = cg::pcg(
        &SparseOperator::new(a),
        pre,
        &refs,
        None,
        &params(tol, 10 * n),
    );
    assert!(report.all_converged(), "{name}, k {k}: {report:?}");
    let kap = kappa(ad);
    let chol = ad.clone().cholesky().expect("A is positive definite");
    for c in 0..k {
        let want = chol.solve(&DVector::from_column_slice(&bs[c]));
        let got = DVector::from_column_slice(&xs[c]);
        let rel = (&got - &want).norm() / want.norm();
        let res = report.relative_residual[c];
        assert!(res <= tol, "{name}, k {k}, channel {c}: residual {res:e}");
        let bound = 2.0 * kap * (res + n as f64 * f64::EPSILON);
        assert!(
            rel <= bound,
            "{name}, k {k}, channel {c}: {rel:e} > {bound:e}"
        );
        let cond = report.condition.as_ref().expect("asked")[c];
        assert!(cond >= 1.0, "{name}: condition estimate {cond}");
    }
}

#[test]
fn pcg_matches_the_dense_solve_for_every_preconditioner_and_channel_count() {
    for seed in SEEDS {
        let mut rng = Pcg64::seed_from_u64(seed);
        let n = 12 + (seed as usize % 4) * 5;
        let k = kernel(&mut rng, 3 * n, n);
        let (a, ad) = normal(&k);
        let inverse_diagonal: Vec<f64> = (0..n).map(|i| 1.0 / ad[(i, i)]).collect();
        let li = local_inversion(
            &k,
            &LocalInversionParams {
                rings: 0,
                solver: Solver::Cholesky,
                ..LocalInversionParams::default()
            },
        )
        .unwrap();
        let li_csr = li.pinv.to_csr();
        // overlapping blocks of 6 unknowns, every 4
        let blocks: Vec<Vec<usize>> = (0..n)
            .step_by(4)
            .map(|s| (s..(s + 6).min(n)).collect())
            .collect();
        let schwarz = AdditiveSchwarz::new(&a, blocks);
        assert_eq!(schwarz.len(), n);
        for channels in 1..=4 {
            check("identity", &a, &ad, &Identity, channels);
            check("jacobi", &a, &ad, &Jacobi::new(&inverse_diagonal), channels);
            check(
                "local",
                &a,
                &ad,
                &LocalInverse::new(&li.pinv, &li_csr),
                channels,
            );
            check("schwarz", &a, &ad, &schwarz, channels);
        }
    }
}

/// Channels in lockstep are the channels alone, bit for bit (each channel's sums run in
/// index order and never mix with the others'), and a zero right-hand side is solved by 0
/// without an iteration.
#[test]
fn lockstep_channels_equal_single_channel_runs() {
    let mut rng = Pcg64::seed_from_u64(SEEDS[0]);
    let n = 20;
    let (a, ad) = normal(&kernel(&mut rng, 60, n));
    let inverse_diagonal: Vec<f64> = (0..n).map(|i| 1.0 / ad[(i, i)]).collect();
    let jacobi = Jacobi::new(&inverse_diagonal);
    let b1: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
    let b2: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).cos()).collect();
    let zero = vec![0.0; n];
    let op = SparseOperator::new(&a);
    let p = params(1e-12, 200);
    let (many, report) = cg::pcg(&op, &jacobi, &[&b1, &zero, &b2], None, &p);
    for (c, b) in [(0, &b1), (2, &b2)] {
        let (one, r) = cg::pcg(&op, &jacobi, &[b], None, &p);
        assert_eq!(many[c], one[0], "channel {c}");
        assert_eq!(report.iterations[c], r.iterations[0]);
    }
    assert!(many[1].iter().all(|&v| v == 0.0));
    assert_eq!(report.iterations[1], 0);
    assert!(report.converged[1]);
}

/// Past the iteration limit the CG reports `converged == false` with the iterate it has (its
/// residual above the tolerance); it does not fail.
#[test]
fn the_iteration_limit_is_reported_not_an_error() {
    let mut rng = Pcg64::seed_from_u64(SEEDS[1]);
    let n = 30;
    let (a, _) = normal(&kernel(&mut rng, 90, n));
    let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
    let (x, report) = cg::pcg(
        &SparseOperator::new(&a),
        &Identity,
        &[&b],
        None,
        &params(1e-14, 2),
    );
    assert_eq!(report.iterations, vec![2]);
    assert_eq!(report.converged, vec![false]);
    assert!(!report.all_converged() && report.first_unconverged() == Some(0));
    assert!(report.relative_residual[0] > 1e-14 && report.relative_residual[0] < 1.0);
    assert!(x[0].iter().all(|v| v.is_finite()) && x[0].iter().any(|&v| v != 0.0));
}

/// CGLS on `A = K D` (`D` the column scaling) equals the dense least-squares solution
/// `y = (A^T A)^{-1} A^T f` within `kappa(A^T A) (res + n eps)` (the bound above, with the
/// normal residual `||A^T r|| / ||A^T f||`), for 1 to 4 interleaved channels; its limit is a
/// report too.
#[test]
fn cgls_matches_the_dense_least_squares_solution() {
    for seed in SEEDS {
        let mut rng = Pcg64::seed_from_u64(seed + 100);
        let (m, n) = (50, 16);
        let k = kernel(&mut rng, m, n);
        let kt: CsMat<f64> = k.transpose_view().to_csr();
        let kd = dense(&k);
        let d: Vec<f64> = (0..n).map(|a| 1.0 / kd.column(a).norm()).collect();
        let ad = &kd * DMatrix::from_diagonal(&DVector::from_column_slice(&d));
        let g = ad.transpose() * &ad;
        let kap = kappa(&g);
        for ch in 1..=4 {
            let fs: Vec<Vec<f64>> = (0..ch)
                .map(|_| (0..m).map(|_| rng.random::<f64>() - 0.5).collect())
                .collect();
            let f: Vec<f64> = (0..m * ch).map(|t| fs[t % ch][t / ch]).collect();
            let tol = 1e-12;
            let (y, report) = cg::cgls(&k, &kt, &d, &f, ch, &params(tol, 500));
            assert!(report.all_converged(), "{report:?}");
            for (c, fc) in fs.iter().enumerate() {
                let rhs = ad.transpose() * DVector::from_column_slice(fc);
                let want = g.clone().cholesky().unwrap().solve(&rhs);
                let got = DVector::from_iterator(n, (0..n).map(|a| y[a * ch + c]));
                let rel = (&got - &want).norm() / want.norm();
                let bound = 2.0 * kap * (report.relative_residual[c] + n as f64 * f64::EPSILON);
                assert!(
                    rel <= bound,
                    "seed {seed}, ch {ch}, channel {c}: {rel:e} > {bound:e}"
                );
            }
            let (_, stalled) = cg::cgls(&k, &kt, &d, &f, ch, &params(1e-15, 1));
            assert!(stalled.converged.iter().all(|&c| !c), "{stalled:?}");
            assert!(stalled.iterations.iter().all(|&i| i == 1));
        }
    }
}

/// The forward-error stop (`CgParams::forward_error`): on an ill-conditioned system (the 1D
/// Laplacian `tridiag(-1, 2.0002, -1)` of order 400 with a varying diagonal scale, `cond`
/// about 2e4 after Jacobi), the residual stop alone at `1e-3` leaves a relative error of
/// 1.1e-4 (over a thousand times `eps`); with the forward stop at `eps = 1e-7` the error in the norm of `M`
/// (here `M = diag(A)`) is at most `2 eps` (the bound uses the Lanczos estimate of the
/// condition, a lower estimate: the factor 2 covers its shortfall once the extreme Ritz
/// values have converged, which the stop's late check ensures), from a zero start and
/// from a warm start, and the reported bound is at most `eps`.
#[test]
fn forward_error_stop_bounds_the_error_not_the_residual() {
    let n = 400;
    let mut t = TriMat::new((n, n));
    let scale = |i: usize| 1.0 + (i % 7) as f64;
    for i in 0..n {
        t.add_triplet(i, i, 2.0002 * scale(i) * scale(i));
        if i + 1 < n {
            t.add_triplet(i, i + 1, -scale(i) * scale(i + 1));
            t.add_triplet(i + 1, i, -scale(i) * scale(i + 1));
        }
    }
    let a: CsMat<f64> = t.to_csr();
    let ad = dense(&a);
    let diag: Vec<f64> = (0..n).map(|i| 1.0 / ad[(i, i)]).collect();
    let jacobi = Jacobi::new(&diag);
    let mut rng = Pcg64::seed_from_u64(7);
    let b: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
    let want = ad
        .clone()
        .cholesky()
        .unwrap()
        .solve(&DVector::from_column_slice(&b));
    // ||v||_M with M = diag(A)
    let m_norm = |v: &DVector<f64>| {
        v.iter()
            .zip(&diag)
            .map(|(x, d)| x * x / d)
            .sum::<f64>()
            .sqrt()
    };
    let rel = |x: &[f64]| m_norm(&(DVector::from_column_slice(x) - &want)) / m_norm(&want);
    let op = SparseOperator::new(&a);
    let residual_only = params(1e-3, 10 * n);
    let (x, _) = cg::pcg(&op, &jacobi, &[&b], None, &residual_only);
    let loose = rel(&x[0]);
    assert!(loose > 100.0 * 1e-7, "the residual stop alone: {loose:e}");
    let eps = 1e-7;
    let forward = CgParams {
        forward_error: Some(eps),
        ..residual_only
    };
    let (x, report) = cg::pcg(&op, &jacobi, &[&b], None, &forward);
    assert!(report.all_converged(), "{report:?}");
    let bound = report.forward_error.as_ref().unwrap()[0];
    assert!(bound <= eps, "reported bound {bound:e}");
    let cold = rel(&x[0]);
    assert!(cold <= 2.0 * eps, "from zero: {cold:e} (loose {loose:e})");
    // warm start from the loose iterate
    let start: Vec<f64> = x[0].iter().map(|v| v * (1.0 + 1e-3)).collect();
    let (x, report) = cg::pcg(&op, &jacobi, &[&b], Some(vec![start]), &forward);
    assert!(report.all_converged(), "{report:?}");
    let warm = rel(&x[0]);
    assert!(warm <= 2.0 * eps, "from a warm start: {warm:e}");
}

/// `pcg_to`: each channel stops at its own tolerance (its recomputed residual at most it,
/// its coefficients within `kappa (res + n eps)` of the dense solve), and a channel is the
/// same channel run alone at that tolerance, bit for bit; a looser channel takes no more
/// iterations than a tighter one of the same right-hand side.
#[test]
fn per_channel_tolerances_stop_each_channel_at_its_own() {
    for seed in SEEDS {
        let mut rng = Pcg64::seed_from_u64(seed);
        let n = 25;
        let (a, ad) = normal(&kernel(&mut rng, 75, n));
        let kap = kappa(&ad);
        let inverse_diagonal: Vec<f64> = (0..n).map(|i| 1.0 / ad[(i, i)]).collect();
        let jacobi = Jacobi::new(&inverse_diagonal);
        let op = SparseOperator::new(&a);
        let b: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
        let tolerances = [5e-2, 1e-6, 1e-11];
        let p = params(0.5, 500);
        let (xs, report) = cg::pcg_to(&op, &jacobi, &[&b, &b, &b], None, &p, &tolerances, false);
        let exact = ad
            .clone()
            .cholesky()
            .unwrap()
            .solve(&DVector::from_vec(b.clone()));
        for (c, &t) in tolerances.iter().enumerate() {
            let res = report.relative_residual[c];
            assert!(
                report.converged[c] && res <= t,
                "seed {seed} channel {c}: {res} > {t}"
            );
            let err = (DVector::from_vec(xs[c].clone()) - &exact).norm() / exact.norm();
            let bound = 2.0 * kap * (res + n as f64 * f64::EPSILON);
            assert!(
                err <= bound,
                "seed {seed} channel {c}: error {err} > {bound}"
            );
            let (alone, r) = cg::pcg_to(&op, &jacobi, &[&b], None, &p, &[t], false);
            assert_eq!(alone[0], xs[c], "seed {seed} channel {c}");
            assert_eq!(r.iterations[0], report.iterations[c]);
            assert_eq!(report.start_residual[c], 1.0);
        }
        assert!(report.iterations[0] <= report.iterations[1]);
        assert!(report.iterations[1] <= report.iterations[2]);
    }
}

/// The scaled start (`pcg_to`'s `scale_start`, read at zero iterations): `s x_0` with
/// `s = x_0.b / x_0.A x_0`, whose energy error is `||x*||_A^2 - (x_0.b)^2 / x_0.A x_0`
/// (to rounding), at most the zero start's `||x*||_A` and `x_0`'s own, for starts of
/// either sign, too long, too short or unrelated to the solution; the reported start
/// residual is that of the scaled start.
#[test]
fn a_scaled_start_is_never_farther_than_zero_or_the_start() {
    for seed in SEEDS {
        let mut rng = Pcg64::seed_from_u64(seed);
        let n = 20;
        let (a, ad) = normal(&kernel(&mut rng, 60, n));
        let op = SparseOperator::new(&a);
        let b: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
        let bv = DVector::from_vec(b.clone());
        let exact = ad.clone().cholesky().unwrap().solve(&bv);
        let energy = |e: &DVector<f64>| e.dot(&(&ad * e));
        let noise: Vec<f64> = (0..n).map(|_| rng.random::<f64>() - 0.5).collect();
        for (factor, mix) in [(3.0, 0.1), (-2.0, 0.1), (0.2, 0.5), (1.0, 0.0), (0.0, 1.0)] {
            let x0: Vec<f64> = (0..n).map(|i| factor * exact[i] + mix * noise[i]).collect();
            let x0v = DVector::from_vec(x0.clone());
            let (x, report) = cg::pcg_to(
                &op,
                &Identity,
                &[&b],
                Some(vec![x0.clone()]),
                &params(1e-12, 0),
                &[1e-12],
                true,
            );
            let xv = DVector::from_vec(x[0].clone());
            let scaled = energy(&(&xv - &exact));
            let formula = energy(&exact) - x0v.dot(&bv).powi(2) / energy(&x0v);
            let scale = energy(&exact);
            assert!(
                (scaled - formula).abs() <= 1e-9 * scale,
                "seed {seed} start {factor}/{mix}: {scaled} against {formula}"
            );
            assert!(
                scaled <= energy(&exact) * (1.0 + 1e-12),
                "farther than zero"
            );
            assert!(
                scaled <= energy(&(&x0v - &exact)) * (1.0 + 1e-12) + 1e-15 * scale,
                "farther than the start"
            );
            let residual = (&bv - &ad * &xv).norm() / bv.norm();
            assert!((report.start_residual[0] - residual).abs() <= 1e-9);
        }
    }
}
