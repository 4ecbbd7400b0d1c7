//! Global references: `K^+ = V diag(1/s) U^T` densely (faer thin SVD), and
//! `c = argmin_c ||K c - f||_2` sparsely, by a sparse Cholesky of `K^T K` or by CGLS.
//!
//! * [`dense_pinv`]: the truth for small problems (each dimension up to
//!   [`DENSE_LIMIT`]); one large SVD, so faer runs it with `Par::rayon(0)`.
//! * [`global_ls`] with [`GlobalMethod::Cholesky`]: `D K^T K D y = D K^T f`, `c = D y`,
//!   `D = diag(K^T K)^{-1/2}` (equilibration), AMD-ordered supernodal/simplicial sparse
//!   Cholesky (`faer::sparse::linalg::cholesky`: symbolic once, numeric once, every channel
//!   solved with the one factor). A pivot below `pivot_tol` means `K^T K` is numerically
//!   singular: [`SolveError::RankDeficient`] / [`SolveError::Undersampled`], or with
//!   [`RankPolicy::Regularize`] a ridge `ridge * I` on the equilibrated matrix, reported.
//! * [`global_ls`] with [`GlobalMethod::Cgls`]: conjugate gradients on
//!   `(K D)^T (K D) y = (K D)^T f` without forming it (two sprs-array mat-vecs per
//!   iteration, all channels per sweep, rayon over rows). For a rank-deficient `K` it
//!   converges to the solution of minimum `||D^{-1} c||` (min-norm in the equilibrated
//!   variables; zero on never-sampled columns).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::svd::{pseudoinverse_from_svd_scratch, pseudoinverse_from_svd_with_tolerance};
use faer::linalg::svd::{svd, svd_scratch, ComputeSvdVectors};
use faer::{Mat, Par};
use rayon::prelude::*;
use sprs::CsMat;

use super::cg::{self, CgParams, ConditionEstimate, ResidualReport};
use super::normal::factor_solve;
use super::outcome::{GlobalLs, GlobalReport};
use super::params::{GlobalLsParams, GlobalMethod, RankPolicy};
use super::sparse::{
    check_finite_output, check_values, column_scaling, ldexp, normal_matrix, prepare, raw, spmm,
};
use super::vectors::interleave;
use super::SolveError;

/// Largest number of rows or columns [`dense_pinv`] accepts (an `8192 x 8192` SVD with
/// vectors needs ~1.6 GB and minutes on two cores).
pub const DENSE_LIMIT: usize = 8192;

/// Dense pseudo-inverse and its spectrum.
#[derive(Debug, Clone)]
pub struct DensePinv {
    /// `K^+`, `P x m`.
    pub pinv: Mat<f64>,
    /// Singular values of `K`, non-increasing.
    pub singular_values: Vec<f64>,
    /// Numerical rank (`s_k > cutoff * s_max`).
    pub rank: usize,
    /// Directions dropped: `P - rank`.
    pub cut: usize,
    /// `s_max / s_P`, infinite when `rank < P`.
    pub condition: f64,
}

impl DensePinv {
    /// `K^+ f` for one channel (`f.len() == m`).
    pub fn apply(&self, f: &[f64]) -> Result<Vec<f64>, SolveError> {
        if f.len() != self.pinv.ncols() {
            return Err(SolveError::DimensionMismatch {
                what: "values length (must equal the rows of K)",
                expected: self.pinv.ncols(),
                found: f.len(),
            });
        }
        let out: Vec<f64> = (0..self.pinv.nrows())
            .map(|a| (0..f.len()).map(|i| self.pinv[(a, i)] * f[i]).sum())
            .collect();
        check_finite_output(&out, "dense pinv applied to values")?;
        Ok(out)
    }
}

/// Dense `K^+` through faer's thin SVD, dropping `s_k <= cutoff * s_max`.
pub fn dense_pinv(k: &CsMat<f64>, cutoff: f64) -> Result<DensePinv, SolveError> {
    if !(cutoff.is_finite() && (0.0..1.0).contains(&cutoff)) {
        return Err(SolveError::InvalidParameter {
            name: "cutoff",
            value: cutoff.to_string(),
            fix: "pass a relative singular value cut-off in [0, 1), e.g. 1e-12",
        });
    }
    let (m, p) = k.shape();
    if m > DENSE_LIMIT || p > DENSE_LIMIT {
        return Err(SolveError::TooLarge {
            rows: m,
            cols: p,
            limit: DENSE_LIMIT,
        });
    }
    let prep = prepare(k)?;
    let size = m.min(p);
    if size == 0 {
        return Ok(DensePinv {
            pinv: Mat::zeros(p, m),
            singular_values: vec![],
            rank: 0,
            cut: p,
            condition: f64::INFINITY,
        });
    }
    let mut a = Mat::<f64>::zeros(m, p);
    let (kp, ki, kd) = raw(&prep.k);
    for i in 0..m {
        for t in kp[i]..kp[i + 1] {
            a[(i, ki[t])] += kd[t];
        }
    }
    let par = Par::rayon(0);
    let mut s = faer::diag::Diag::<f64>::zeros(size);
    let mut u = Mat::<f64>::zeros(m, size);
    let mut v = Mat::<f64>::zeros(p, size);
    let mut mem = MemBuffer::new(svd_scratch::<f64>(
        m,
        p,
        ComputeSvdVectors::Thin,
        ComputeSvdVectors::Thin,
        par,
        Default::default(),
    ));
    svd(
        a.as_ref(),
        s.as_mut(),
        Some(u.as_mut()),
        Some(v.as_mut()),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .map_err(|e| SolveError::DenseSvd {
        rows: m,
        cols: p,
        detail: format!("{e:?}"),
    })?;
    let mut pinv = Mat::<f64>::zeros(p, m);
    let mut mem = MemBuffer::new(pseudoinverse_from_svd_scratch::<f64>(m, p, par));
    pseudoinverse_from_svd_with_tolerance(
        pinv.as_mut(),
        s.as_ref(),
        u.as_ref(),
        v.as_ref(),
        0.0,
        cutoff,
        par,
        MemStack::new(&mut mem),
    );
    let e = prep.exponent;
    let sv: Vec<f64> = (0..size).map(|i| ldexp(s[i], e)).collect();
    let smax = s[0];
    let rank = (0..size)
        .filter(|&i| s[i] > cutoff * smax && s[i] > 0.0)
        .count();
    if e != 0 {
        for j in 0..m {
            for i in 0..p {
                pinv[(i, j)] = ldexp(pinv[(i, j)], -e);
            }
        }
    }
    for j in 0..m {
        if (0..p).any(|i| !pinv[(i, j)].is_finite()) {
            return Err(SolveError::NonFiniteOutput {
                what: format!("dense pseudo-inverse column {j}"),
            });
        }
    }
    let condition = if rank == p {
        smax / s[p - 1]
    } else {
        f64::INFINITY
    };
    Ok(DensePinv {
        pinv,
        singular_values: sv,
        rank,
        cut: p - rank,
        condition,
    })
}

/// Global sparse least squares for every channel (`values[ch].len() == rows of K`).
pub fn global_ls(
    k: &CsMat<f64>,
    values: &[&[f64]],
    params: &GlobalLsParams,
) -> Result<GlobalLs, SolveError> {
    params.validate()?;
    check_values(values, k.rows())?;
    let (m, p) = k.shape();
    if m < p && params.method == GlobalMethod::Cholesky && params.rank_policy == RankPolicy::Error {
        return Err(SolveError::Undersampled {
            samples: m,
            functions: p,
        });
    }
    if values.is_empty() || p == 0 || m == 0 {
        return Ok(GlobalLs::empty(p, values.len(), params.method));
    }
    match params.method {
        GlobalMethod::Cholesky => cholesky_ls(k, values, params),
        GlobalMethod::Cgls => cgls(k, values, params),
    }
}

/// Splits a row-major `p x ch` block into channels, scaled by `d[a] * 2^-e`.
fn deinterleave(x: &[f64], d: &[f64], ch: usize, e: i32) -> Vec<Vec<f64>> {
    (0..ch)
        .map(|c| {
            d.par_iter()
                .enumerate()
                .map(|(a, &da)| ldexp(da * x[a * ch + c], -e))
                .collect()
        })
        .collect()
}

/// Relative normal-equation residuals `||A^T (f - A y)|| / ||A^T f||` per channel for
/// `A = K_s D`, with `y` row-major `p x ch`.
fn normal_residuals(
    ks: &CsMat<f64>,
    kt: &CsMat<f64>,
    d: &[f64],
    f: &[f64],
    y: &[f64],
    ch: usize,
) -> Vec<f64> {
    let (m, p) = ks.shape();
    let dy: Vec<f64> = (0..p * ch).map(|t| d[t / ch] * y[t]).collect();
    let mut r = vec![0.0; m * ch];
    spmm(ks, &dy, &mut r, ch);
    r.par_iter_mut().zip(f).for_each(|(r, f)| *r = f - *r);
    let mut s = vec![0.0; p * ch];
    spmm(kt, &r, &mut s, ch);
    let mut s0 = vec![0.0; p * ch];
    spmm(kt, f, &mut s0, ch);
    (0..ch)
        .map(|c| {
            let a = crate::norms::rms((0..p).map(|t| d[t] * s[t * ch + c]));
            let b = crate::norms::rms((0..p).map(|t| d[t] * s0[t * ch + c]));
            // ||.||_2 ratio = rms ratio (same count); ||.||_2 = sqrt(p) rms when b = 0.
            if b > 0.0 {
                a / b
            } else {
                a * (p as f64).sqrt()
            }
        })
        .collect()
}

fn cholesky_ls(
    k: &CsMat<f64>,
    values: &[&[f64]],
    params: &GlobalLsParams,
) -> Result<GlobalLs, SolveError> {
    let (m, p) = k.shape();
    let ch = values.len();
    if m < p && params.rank_policy == RankPolicy::Error {
        return Err(SolveError::Undersampled {
            samples: m,
            functions: p,
        });
    }
    let prep = prepare(k)?;
    let g = normal_matrix(&prep.k, &prep.kt);
    // Right-hand sides K_s^T f, row-major P x ch.
    let f = interleave(values);
    let mut ktf = vec![0.0; p * ch];
    spmm(&prep.kt, &f, &mut ktf, ch);
    let tp = raw(&prep.kt).0;
    // One corrected semi-normal step: the accuracy of a QR of K, not of K^T K.
    let correction = |y: &[f64], d: &[f64]| {
        let dy: Vec<f64> = y.iter().enumerate().map(|(t, v)| d[t / ch] * v).collect();
        let mut r = vec![0.0; m * ch];
        spmm(&prep.k, &dy, &mut r, ch);
        r.par_iter_mut().zip(&f).for_each(|(r, f)| *r = f - *r);
        let mut s = vec![0.0; p * ch];
        spmm(&prep.kt, &r, &mut s, ch);
        s.iter_mut().enumerate().for_each(|(t, v)| *v *= d[t / ch]);
        s
    };
    let solved = factor_solve(
        &g,
        &ktf,
        ch,
        m,
        &|a| tp[a + 1] - tp[a],
        None,
        Some(&correction),
        params,
    )?;
    let residuals = normal_residuals(&prep.k, &prep.kt, &solved.d, &f, &solved.y, ch);
    let coefficients = deinterleave(&solved.y, &solved.d, ch, prep.exponent);
    for (c, x) in coefficients.iter().enumerate() {
        check_finite_output(x, &format!("global Cholesky least squares, channel {c}"))?;
    }
    Ok(GlobalLs {
        coefficients,
        report: solved.report(residuals),
    })
}

fn cgls(
    k: &CsMat<f64>,
    values: &[&[f64]],
    params: &GlobalLsParams,
) -> Result<GlobalLs, SolveError> {
    let p = k.cols();
    let ch = values.len();
    let prep = prepare(k)?;
    let (tp, _, td) = raw(&prep.kt);
    let d = column_scaling(|a| td[tp[a]..tp[a + 1]].iter().map(|v| v * v).sum(), p, 0.0);
    let f = interleave(values);
    let cg = CgParams {
        tolerance: params.tol,
        max_iterations: params.max_iter,
        residual: ResidualReport::Recurred,
        condition: ConditionEstimate::Skip,
        forward_error: None,
    };
    let (y, report) = cg::cgls(&prep.k, &prep.kt, &d, &f, ch, &cg);
    // The one CG reports the iteration limit; the global solve's contract is the tolerance.
    const ON_LIMIT: cg::IterationLimit = cg::IterationLimit::Fail;
    if let (Some(c), cg::IterationLimit::Fail) = (report.first_unconverged(), ON_LIMIT) {
        return Err(SolveError::NotConverged {
            channel: c,
            iterations: report.iterations[c],
            residual: report.relative_residual[c],
            tol: params.tol,
        });
    }
    let residuals = normal_residuals(&prep.k, &prep.kt, &d, &f, &y, ch);
    let coefficients = deinterleave(&y, &d, ch, prep.exponent);
    for (c, x) in coefficients.iter().enumerate() {
        check_finite_output(x, &format!("global CGLS least squares, channel {c}"))?;
    }
    Ok(GlobalLs {
        coefficients,
        report: GlobalReport {
            method: GlobalMethod::Cgls,
            iterations: report.iterations,
            residuals,
            ridge: 0.0,
            min_pivot: 0.0,
            normal_nnz: 0,
            factor_nnz: 0,
        },
    })
}
