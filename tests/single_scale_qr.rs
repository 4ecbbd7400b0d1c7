//! The banded QR of the single-scale least squares (issue 11): exact reproduction of the
//! polynomials the basis contains, and agreement with a dense SVD least-squares solution on
//! ill-conditioned sample sets, where the normal equations lose digits.

mod common;

use common::oracle::DenseLs;
use rand::{Rng, SeedableRng};
use rkwave::basis::{minimum_level, CdvBasis, FilterFamily};
use rkwave::kernel::{kernel_matrix, ActiveSet, LevelChoice};
use rkwave::reconstruct::{
    fit_active, single_scale_ls, single_scale_qr, Method, SingleScaleSolver,
};
use rkwave::sampling::Domain;

fn basis(p: usize, coarse: u32, fine: u32) -> CdvBasis {
    CdvBasis::new(p, FilterFamily::cdv_default(p), coarse, fine, Domain::UNIT).unwrap()
}

/// `q(x) = sum_k (2x - 1)^k / (k + 1)`, `k < p`: in the span of every `V_j`, `|q| <= 2.93`.
fn poly(p: usize, x: f64) -> f64 {
    (0..p)
        .map(|k| (2.0 * x - 1.0).powi(k as i32) / (k + 1) as f64)
        .sum()
}

/// Polynomials of degree `< p` are reproduced from random samples to 1e-13 relative (max
/// over 2,000 random points and both ends), for `p = 2..10`, by the QR path, through the
/// parallel chunked triangle (40,000 samples: more than two chunks) and its merge. The data
/// lie in the span, so the least-squares residual is round-off; the tolerance is
/// `~450 eps`, room for the FWT, the evaluation (byte products of digit matrices) and
/// `cond(K) ~ 10` at oversampling `>= 39`.
#[test]
fn polynomials_below_order_p_are_reproduced_to_round_off() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let xs: Vec<f64> = (0..40_000).map(|_| rng.random::<f64>()).collect();
    let mut probe: Vec<f64> = (0..2_000).map(|_| rng.random::<f64>()).collect();
    probe.extend([0.0, 1.0]);
    for p in 2..=10 {
        let n = minimum_level(p);
        let b = basis(p, n, n + 2);
        let f: Vec<f64> = xs.iter().map(|&x| poly(p, x)).collect();
        let active = ActiveSet::uniform(b.clone());
        let lv = LevelChoice {
            coarse: n,
            fine: n + 2,
            oversampling: xs.len() as f64 / active.len() as f64,
        };
        let method = Method::SingleScale {
            ridge: 0.0,
            solver: SingleScaleSolver::Qr,
        };
        // A second channel off the span: its residual, rotated out chunk by chunk and merged,
        // must be the one the evaluated fit leaves at the samples.
        let noisy: Vec<f64> = xs
            .iter()
            .map(|&x| poly(p, x) + 1e-3 * (1e4 * x).sin())
            .collect();
        let fit = fit_active(active, &xs, &[&f, &noisy], method, lv).unwrap();
        assert!(fit.fallbacks.is_empty(), "p = {p}: {:?}", fit.fallbacks);
        let reported = match &fit.solve {
            rkwave::reconstruct::SolveReport::SingleScale(r) => r.residual_rms.clone().unwrap(),
            other => panic!("p = {p}: {other:?}"),
        };
        let at = fit.evaluate(&xs).unwrap();
        let evaluated = |c: usize, g: &[f64]| {
            (at[c]
                .iter()
                .zip(g)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                / xs.len() as f64)
                .sqrt()
        };
        // Off the span the residual is ~7e-4; both sides carry rounding ~1e-16 relative to it.
        let (r1, e1) = (reported[1], evaluated(1, &noisy));
        assert!((r1 - e1).abs() <= 1e-9 * e1, "p = {p}: {r1:e} vs {e1:e}");
        // In the span both are round-off.
        assert!(reported[0] <= 1e-13 && evaluated(0, &f) <= 1e-13, "p = {p}");
        let got = fit.evaluate(&probe).unwrap();
        let scale = probe.iter().map(|&x| poly(p, x).abs()).fold(0.0, f64::max);
        let err = probe
            .iter()
            .zip(&got[0])
            .map(|(&x, g)| (g - poly(p, x)).abs())
            .fold(0.0, f64::max);
        assert!(err <= 1e-13 * scale, "p = {p}: {err:e} relative to {scale}");
    }
}

fn rel(a: &[f64], b: &[f64]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
    let den: f64 = b.iter().map(|y| y * y).sum();
    (num / den).sqrt()
}

/// Ill-conditioned sample sets against the dense SVD solution (the oracle of
/// `tests/common/oracle.rs`, here with this test's own, tighter constants): a dense cluster beside a
/// sparse stretch, groups of samples at ulp distance, samples exactly on the dyadic knots of
/// `V_{N+1}`. Data: a smooth non-polynomial signal (nonzero residual). Tolerance for the QR
/// path: `||c - c_svd|| <= 20 eps cond(K) ||c_svd||` plus the residual term
/// `eps cond(K)^2 ||r|| / (||K|| ||c||)` of least-squares perturbation theory, with constants
/// for `P <= 128` unknowns; the normal equations are held only to their own bound
/// `eps cond(K)^2` (they lose about `log10 cond(K)` more digits).
#[test]
fn ill_conditioned_sample_sets_match_the_dense_svd() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let p = 4;
    let n = minimum_level(p);
    let b = basis(p, n, n + 2); // P = 2^(n+3)
    let cells = (b.dimension()) as f64; // V_{N+1} has 2^{N+1} = P cells
    let mut sets: Vec<(&str, Vec<f64>)> = Vec::new();
    // Dense cluster in [0.40, 0.42] beside a stretch with about 4 samples per cell.
    let mut cluster: Vec<f64> = (0..3_000)
        .map(|_| 0.40 + 0.02 * rng.random::<f64>())
        .collect();
    cluster.extend((0..(4.0 * cells) as usize).map(|_| rng.random::<f64>()));
    sets.push(("cluster beside sparse stretch", cluster));
    // Groups of 8 samples one ulp apart at 3 random points per cell.
    let mut ulp = Vec::new();
    for _ in 0..(3.0 * cells) as usize {
        let mut x: f64 = 0.001 + 0.998 * rng.random::<f64>();
        for _ in 0..8 {
            ulp.push(x);
            x = f64::from_bits(x.to_bits() + 1);
        }
    }
    sets.push(("groups at ulp distance", ulp));
    // Every dyadic knot of V_{N+1}, both ends included, plus 2 random samples per cell.
    let mut knots: Vec<f64> = (0..=cells as usize).map(|k| k as f64 / cells).collect();
    knots.extend((0..(2.0 * cells) as usize).map(|_| rng.random::<f64>()));
    sets.push(("samples on dyadic knots", knots));
    let eps = f64::EPSILON;
    for (name, xs) in &sets {
        let f: Vec<f64> = xs.iter().map(|&x| (7.0 * x).sin() + x.exp()).collect();
        let k = kernel_matrix(&ActiveSet::uniform(b.clone()), xs).unwrap();
        let oracle = DenseLs::new(&k);
        let (reference, cond) = (oracle.solve(&f), oracle.condition());
        let resid: f64 = oracle
            .apply(&reference)
            .iter()
            .zip(&f)
            .map(|(kc, fi)| (kc - fi).powi(2))
            .sum::<f64>()
            .sqrt();
        let cnorm: f64 = reference.iter().map(|c| c * c).sum::<f64>().sqrt();
        let knorm = oracle.norm();
        let (qr, qrep) = single_scale_qr(&b, xs, &[&f], 0.0).unwrap();
        let (ne, nrep) = single_scale_ls(&b, xs, &[&f], 0.0).unwrap();
        assert_eq!(qrep.deficient, 0, "{name}: {qrep:?}");
        let e_qr = rel(&qr[0], &reference);
        let e_ne = rel(&ne[0], &reference);
        let bound = 20.0 * eps * cond + 20.0 * eps * cond * cond * resid / (knorm * cnorm);
        println!(
            "{name}: cond(K) = {cond:.3e}, QR {e_qr:.2e}, normal equations {e_ne:.2e} \
             (deficient {}), QR bound {bound:.2e}",
            nrep.deficient
        );
        assert!(
            e_qr <= bound,
            "{name}: QR {e_qr:e} > {bound:e} (cond {cond:e})"
        );
        if nrep.deficient == 0 {
            assert!(e_ne <= 20.0 * eps * cond * cond, "{name}: NE {e_ne:e}");
        }
        // The residual the QR rotated out is the samples' residual: ||f - K c|| is stationary
        // at the least-squares minimum (a coefficient error e changes it by ~||K e||^2), so
        // it agrees with the dense reference's to the rounding of the sums, ~ m eps ||f||.
        let ref_rms = resid / (xs.len() as f64).sqrt();
        let qr_rms = qrep
            .residual_rms
            .as_ref()
            .expect("the QR reports its residual")[0];
        let fnorm = f.iter().map(|v| v * v).sum::<f64>().sqrt();
        let tol = xs.len() as f64 * eps * fnorm / (xs.len() as f64).sqrt();
        assert!(
            (qr_rms - ref_rms).abs() <= tol,
            "{name}: residual RMS {qr_rms:e} from the QR against {ref_rms:e} (tolerance {tol:e})"
        );
        assert!(
            nrep.residual_rms.is_none(),
            "the normal equations do not report one"
        );
    }
}
