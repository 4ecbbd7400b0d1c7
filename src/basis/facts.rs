//! Measured facts of a basis `Psi(n, N)`: the identities of docs/design.md §2, computed exactly
//! (refinement algebra and the interval FWT), never by quadrature.
//!
//! - Orthonormality: `G = S^T G_V S`, `S` the synthesis matrix into `V_{N+1}` (sparse product of
//!   the one-level steps); `G_V` is the identity up to the edge Gram deviation obtained from the
//!   Stein equation, added as a bound.
//! - Polynomial reproduction: the exact coefficients `<t^d, phi_{n,k}>` (moments from the
//!   refinement equations) synthesize `t^d` through exact pointwise evaluation.
//! - Vanishing moments: `int t^d psi_{j,k}` from the exact moments of the edge and interior wavelets.
//! - Perfect reconstruction: synthesis after analysis on random data.

use rand::{Rng, SeedableRng};
use serde::Serialize;

use super::filters::binomial;
use super::fwt::{analysis, synthesis, synthesis_matrix};
use super::{BasisValue, CdvBasis};

/// Errors of the four identities (all in absolute terms on the basis' own domain; polynomials are
/// `((x - a) / (b - a))^d`).
#[derive(Clone, Debug, Serialize)]
pub struct BasisFacts {
    /// `max |G - I|` over the Gram matrix of `Psi(n, N)`.
    pub orthonormality_error: f64,
    /// Max abs error reproducing `t^d`, `d < p`, from `V_n` at the test points.
    pub polynomial_error: f64,
    /// Number of positions at which the polynomials were checked.
    pub polynomial_points: usize,
    /// `max |int t^d psi|` over all wavelets of levels `n..=N`, `d < p`.
    pub vanishing_moment_error: f64,
    /// Max abs error of synthesis after analysis on random data.
    pub fwt_error: f64,
}

impl BasisFacts {
    /// Measures all four (seeded; `polynomial_points >= 10_000` recommended).
    pub fn measure(basis: &CdvBasis, polynomial_points: usize, seed: u64) -> Self {
        Self {
            orthonormality_error: orthonormality_error(basis),
            polynomial_error: polynomial_error(basis, polynomial_points, seed),
            polynomial_points,
            vanishing_moment_error: vanishing_moment_error(basis),
            fwt_error: fwt_error(basis, seed),
        }
    }
}

/// `max |S^T S - I|` plus the edge Gram deviation of `V_{N+1}`.
pub fn orthonormality_error(basis: &CdvBasis) -> f64 {
    let bank = basis.bank();
    let total = basis.dimension();
    let mut s: sprs::CsMat<f64> = sprs::CsMat::eye(total);
    for j in basis.coarse()..=basis.fine() {
        let step = synthesis_matrix(bank, j, total);
        s = &step * &s;
    }
    let st = s.transpose_view().to_csr();
    let gram = &st * &s;
    let mut err: f64 = 0.0;
    let mut diag_seen = vec![false; total];
    for (row, vec) in gram.outer_iterator().enumerate() {
        for (col, &v) in vec.iter() {
            let target = if row == col {
                diag_seen[row] = true;
                1.0
            } else {
                0.0
            };
            err = err.max((v - target).abs());
        }
    }
    if diag_seen.iter().any(|&d| !d) {
        err = err.max(1.0);
    }
    err + bank.edge_gram_error()
}

/// Exact coefficients `<t^d, phi_{n,k}>` on `[0, 1]`, `k < 2^n`.
pub fn monomial_coefficients(basis: &CdvBasis, d: usize) -> Vec<f64> {
    let bank = basis.bank();
    let n = basis.coarse();
    let p = bank.p();
    let e = bank.edge_count();
    let size = 1usize << n;
    let s = 0.5f64.powf(n as f64 * (d as f64 + 0.5));
    let mut c = vec![0.0; size];
    for (m, cm) in c.iter_mut().enumerate().take(size - e).skip(e) {
        *cm = s * bank.interior.translate_moment(d, m as i64);
    }
    if let (Some(left), Some(right)) = (bank.left.as_ref(), bank.right.as_ref()) {
        let h = 0.5f64.powi(n as i32);
        for k in 0..p {
            c[k] = s * left.scaling_moments[k][d];
            c[size - 1 - k] = h.sqrt()
                * (0..=d)
                    .map(|q| binomial(d, q) * (-h).powi(q as i32) * right.scaling_moments[k][q])
                    .sum::<f64>();
        }
    }
    c
}

/// Max abs error of `sum_k <t^d, phi_{n,k}> phi_{n,k}(x) - t^d` over `d < p` at `points`
/// positions: a uniform grid with both ends plus seeded random positions (a tenth of them).
pub fn polynomial_error(basis: &CdvBasis, points: usize, seed: u64) -> f64 {
    let coarse_only = CdvBasis::with_bank(
        basis.bank().clone(),
        basis.coarse(),
        basis.coarse(),
        basis.domain(),
    )
    .expect("levels already validated");
    let root = basis.domain().length().sqrt();
    let coefficients: Vec<Vec<f64>> = (0..basis.p())
        .map(|d| {
            monomial_coefficients(basis, d)
                .into_iter()
                .map(|c| c * root)
                .collect()
        })
        .collect();
    let grid = points - points / 10;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let mut ts: Vec<f64> = (0..grid)
        .map(|i| i as f64 / (grid.max(2) - 1) as f64)
        .collect();
    ts.extend((0..points / 10).map(|_| rng.random::<f64>()));
    let mut ev = coarse_only.evaluator();
    let mut out: Vec<BasisValue> = Vec::new();
    let scaling = 1usize << basis.coarse();
    let mut err: f64 = 0.0;
    for t in ts {
        ev.eval_unit_into(t, &mut out);
        for (d, c) in coefficients.iter().enumerate() {
            let f: f64 = out
                .iter()
                .filter(|v| v.index < scaling)
                .map(|v| c[v.index] * v.value)
                .sum();
            err = err.max((f - t.powi(d as i32)).abs());
        }
    }
    err
}

/// `max |int_0^1 t^d psi_{j,k}(t) dt|` over levels `n..=N`, all `k`, `d < p`.
pub fn vanishing_moment_error(basis: &CdvBasis) -> f64 {
    let bank = basis.bank();
    let p = bank.p();
    let e = bank.edge_count();
    let omega = &bank.interior.wavelet_moments;
    let mut err: f64 = 0.0;
    for j in basis.coarse()..=basis.fine() {
        let size = 1usize << j;
        let h = 0.5f64.powi(j as i32);
        for d in 0..p {
            let s = 0.5f64.powf(j as f64 * (d as f64 + 0.5));
            for m in e..size - e {
                let v: f64 = (0..=d)
                    .map(|q| binomial(d, q) * (m as f64).powi((d - q) as i32) * omega[q])
                    .sum();
                err = err.max((s * v).abs());
            }
            if let (Some(left), Some(right)) = (bank.left.as_ref(), bank.right.as_ref()) {
                for k in 0..p {
                    err = err.max((s * left.wavelet_moments[k][d]).abs());
                    let r: f64 = (0..=d)
                        .map(|q| binomial(d, q) * (-h).powi(q as i32) * right.wavelet_moments[k][q])
                        .sum();
                    err = err.max((h.sqrt() * r).abs());
                }
            }
        }
    }
    err
}

/// Max abs error of `synthesis(analysis(f)) - f` for seeded uniform random `f` in `[-1, 1]`.
pub fn fwt_error(basis: &CdvBasis, seed: u64) -> f64 {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let data: Vec<f64> = (0..basis.dimension())
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let bank = basis.bank();
    let c = analysis(bank, basis.coarse(), basis.fine(), &data);
    let back = synthesis(bank, basis.coarse(), basis.fine(), &c);
    data.iter()
        .zip(&back)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}
