//! Least squares from the normal equations: `G c = K^T f` with `G = K^T K` given (for a
//! caller that keeps `G` up to date itself, as the refiner does between rounds), solved as
//! `D G D y = D K^T f`, `c = D y`, `D = diag(G)^{-1/2}`, by a sparse Cholesky
//! `P (D G D) P^T = L L^T` (faer: symbolic step with AMD or a given ordering `P`, numeric
//! step, triangular solves: [`crate::solve::cholesky`]). The same factorization serves
//! `solve::global_ls`.

use faer::{Mat, Par};
use rayon::prelude::*;
use sprs::CsMat;

use super::cholesky::{NonPositivePivot, Pivots, SparseCholesky};
use super::outcome::{GlobalLs, GlobalReport};
use super::params::{GlobalLsParams, GlobalMethod, RankPolicy};
use super::sparse::{check_finite_output, check_values, column_scaling, raw};
use super::SolveError;

/// Stored entries of the equilibrated `K^T K` below which the Cholesky runs on one thread
/// (the refiner's systems, `P` ~ 1,000-2,000 and `nnz` ~ 1e5-3e5, factor in milliseconds;
/// the perf profile of `rkwave adapt --signal jumps` showed rayon's wake-ups and yields beside
/// the factorization).
const PARALLEL_MIN_NNZ: usize = 1 << 20;

/// A factorized, solved normal system in the equilibrated variables.
pub(crate) struct Factored {
    /// `y`, row-major `P x ch`: `c = D y`.
    pub y: Vec<f64>,
    /// The equilibration `D = diag(G)^{-1/2}` (1 on an empty column).
    pub d: Vec<f64>,
    /// Ridge added (0 = none).
    pub ridge: f64,
    /// Smallest pivot `L_qq^2`.
    pub min_pivot: f64,
    /// Stored entries of the equilibrated `G` (diagonal always stored).
    pub normal_nnz: usize,
    /// Stored entries of `L`.
    pub factor_nnz: usize,
}

impl Factored {
    /// The report of this direct solve (no iterations), with the relative normal-equation
    /// `residuals` per channel.
    pub(crate) fn report(&self, residuals: Vec<f64>) -> GlobalReport {
        GlobalReport {
            method: GlobalMethod::Cholesky,
            iterations: vec![0; residuals.len()],
            residuals,
            ridge: self.ridge,
            min_pivot: self.min_pivot,
            normal_nnz: self.normal_nnz,
            factor_nnz: self.factor_nnz,
        }
    }
}

/// `(y, d) -> D K^T (f - K D y)` for equilibrated coefficients `y` (row-major `P x ch`) and
/// the column scaling `d` (`D = diag(d)`): the right-hand side of a correction step of the
/// semi-normal equations.
pub(crate) type NormalCorrection<'a> = &'a (dyn Fn(&[f64], &[f64]) -> Vec<f64> + Sync);

/// Factorizes the equilibrated `G` (CSR, sorted, both triangles; symmetric so also CSC)
/// and solves for the right-hand sides `ktf = K^T f` (row-major `P x ch`); `m` rows of `K`,
/// `column_samples(a)` samples of column `a` (for the error message), `ordering` the
/// fill-reducing order (`ordering[q]` = column eliminated `q`-th; `None` is AMD).
///
/// With `correction` (which needs `K` itself), the solution is refined by one step of the
/// corrected semi-normal equations (Björck 1987): `y <- y + (R^T R)^{-1} D K^T (f - K D y)`
/// with the same factor `R^T R = D G D`. The normal equations alone have a forward error of
/// order `eps cond(K)^2`; after the step it is of order `eps cond(K)` (that of a QR of `K`)
/// as long as `eps cond(K)^2 < 1`, at the cost of two products with `K` and one more pair of
/// triangular solves. Skipped when a ridge had to be added (the problem is then another one).
#[allow(clippy::too_many_arguments)]
pub(crate) fn factor_solve(
    g: &CsMat<f64>,
    ktf: &[f64],
    ch: usize,
    m: usize,
    column_samples: &dyn Fn(usize) -> usize,
    ordering: Option<&[usize]>,
    correction: Option<NormalCorrection<'_>>,
    params: &GlobalLsParams,
) -> Result<Factored, SolveError> {
    let p = g.rows();
    let (gp, gi, gd) = raw(g);
    let diag_of = |a: usize| {
        gi[gp[a]..gp[a + 1]]
            .binary_search(&a)
            .map(|t| gd[gp[a] + t])
            .unwrap_or(0.0)
    };
    let d = column_scaling(diag_of, p, 1.0);
    // Equilibrated G with the diagonal always stored (so a ridge keeps the pattern).
    let mut col_ptr = Vec::with_capacity(p + 1);
    let mut row_idx = Vec::with_capacity(gi.len() + p);
    let mut vals = Vec::with_capacity(gi.len() + p);
    let mut diag_pos = vec![0usize; p];
    col_ptr.push(0usize);
    for a in 0..p {
        let mut has_diag = false;
        for t in gp[a]..gp[a + 1] {
            let b = gi[t];
            if b > a && !has_diag {
                diag_pos[a] = row_idx.len();
                row_idx.push(a);
                vals.push(0.0);
                has_diag = true;
            }
            if b == a {
                diag_pos[a] = row_idx.len();
                has_diag = true;
            }
            row_idx.push(b);
            vals.push(gd[t] * d[a] * d[b]);
        }
        if !has_diag {
            diag_pos[a] = row_idx.len();
            row_idx.push(a);
            vals.push(0.0);
        }
        col_ptr.push(row_idx.len());
    }
    let normal_nnz = row_idx.len();
    let mut cholesky = SparseCholesky::analyze("normal matrix K^T K", &col_ptr, &row_idx, ordering)
        .map_err(|e| SolveError::Factorization {
            what: e.to_string(),
        })?;
    let perm_fwd = cholesky.permutation();
    // Small factors are faster on one thread: rayon's hand-offs cost more than they share.
    let par = if normal_nnz <= PARALLEL_MIN_NNZ {
        Par::Seq
    } else {
        Par::rayon(0)
    };
    // The factor is the largest allocation of the solve: refused before it is made, counted
    // with the two copies of the normal matrix held beside it (16 bytes an entry).
    crate::resources::check(
        || {
            format!(
                "the sparse Cholesky factor of the {p} x {p} normal matrix ({} stored entries, \
                 beside the matrix's {} entries)",
                cholesky.factor_nnz(),
                g.nnz()
            )
        },
        8.0 * cholesky.factor_nnz() as f64 + 16.0 * (g.nnz() + normal_nnz) as f64,
        || {
            "fewer basis functions (a smaller budget, depth limit or fine level) or an \
             iterative solve"
                .into()
        },
    )?;
    let mut ridge = 0.0;
    let mut min_pivot;
    loop {
        let failed_at = match cholesky.factor(&col_ptr, &row_idx, &vals, Pivots::Strict, par) {
            Ok(()) => {
                let (q, piv) = min_pivot_of(&cholesky.diagonal());
                min_pivot = piv;
                (piv < params.pivot_tol).then_some(q)
            }
            Err(NonPositivePivot { step }) => {
                min_pivot = 0.0;
                Some(step)
            }
        };
        let Some(q) = failed_at else { break };
        // faer may report the failing pivot one past the end (a zero trailing block).
        let column = perm_fwd
            .get(q)
            .copied()
            .unwrap_or(q)
            .min(p.saturating_sub(1));
        if params.rank_policy == RankPolicy::Error || ridge > 0.0 {
            if m < p {
                return Err(SolveError::Undersampled {
                    samples: m,
                    functions: p,
                });
            }
            return Err(SolveError::RankDeficient {
                column,
                pivot: min_pivot,
                threshold: params.pivot_tol,
                column_samples: column_samples(column),
            });
        }
        ridge = params.ridge;
        for &t in &diag_pos {
            vals[t] += ridge;
        }
    }
    let mut rhs = Mat::<f64>::from_fn(p, ch, |a, c| d[a] * ktf[a * ch + c]);
    cholesky.solve_in_place(rhs.as_mut(), par);
    let mut y: Vec<f64> = (0..p * ch).map(|t| rhs[(t / ch, t % ch)]).collect();
    if let (Some(correct), true) = (correction, ridge == 0.0) {
        let r = correct(&y, &d);
        let mut delta = Mat::<f64>::from_fn(p, ch, |a, c| r[a * ch + c]);
        cholesky.solve_in_place(delta.as_mut(), par);
        for (t, yt) in y.iter_mut().enumerate() {
            *yt += delta[(t / ch, t % ch)];
        }
    }
    Ok(Factored {
        y,
        d,
        ridge,
        min_pivot,
        normal_nnz,
        factor_nnz: cholesky.factor_nnz(),
    })
}

/// `c -> K^T (f - K c)` for coefficients `c` by channel (`c[ch][a]`, the plain, not the
/// equilibrated, coefficients), one vector of length `P` per channel: the right-hand side of
/// a corrected semi-normal step, which needs the rows of `K` and the data `f` that `G` and
/// `K^T f` were formed from.
pub type NormalResidual<'a> = &'a (dyn Fn(&[Vec<f64>]) -> Vec<Vec<f64>> + Sync);

/// `c = argmin ||K c - f||` for every channel from the normal equations alone: `gram` is
/// `G = K^T K` (`P x P` CSR, sorted indices, both triangles), `rhs[ch]` is `K^T f[ch]`,
/// `rows` the number of samples `m`, `column_samples[a]` the samples in column `a`, and
/// `ordering` an elimination order (`None`: AMD). Always the sparse Cholesky of
/// [`GlobalMethod::Cholesky`] (with its rank policy); the residual reported is
/// `||D (K^T f - G c)|| / ||D K^T f||`, the equilibrated normal-equation residual.
///
/// Its forward error is of order `eps cond(K)^2`; a caller that still has `K` and `f` gets
/// `eps cond(K)` from [`normal_ls_corrected`].
pub fn normal_ls(
    gram: &CsMat<f64>,
    rhs: &[&[f64]],
    rows: usize,
    column_samples: &[usize],
    ordering: Option<&[usize]>,
    params: &GlobalLsParams,
) -> Result<GlobalLs, SolveError> {
    normal_ls_with(gram, rhs, rows, column_samples, ordering, None, params)
}

/// [`normal_ls`] followed by one step of the corrected semi-normal equations (Björck 1987)
/// with the same factor `R^T R = D G D`:
///
/// ```text
/// c <- c + D (R^T R)^{-1} D K^T (f - K c),       K^T (f - K c) = residual(c).
/// ```
///
/// The normal equations alone have a forward error of order `eps cond(K)^2`; after the step
/// it is of order `eps cond(K)`, that of a QR of `K`, as long as `eps cond(K)^2 < 1`. The
/// step costs one call of `residual` (two products with `K`) and one more pair of triangular
/// solves. It is skipped when a ridge had to be added (`report.ridge > 0`: the problem solved
/// is then another one).
#[allow(clippy::too_many_arguments)]
pub fn normal_ls_corrected(
    gram: &CsMat<f64>,
    rhs: &[&[f64]],
    rows: usize,
    column_samples: &[usize],
    ordering: Option<&[usize]>,
    residual: NormalResidual<'_>,
    params: &GlobalLsParams,
) -> Result<GlobalLs, SolveError> {
    normal_ls_with(
        gram,
        rhs,
        rows,
        column_samples,
        ordering,
        Some(residual),
        params,
    )
}

/// [`normal_ls`] with an optional corrected semi-normal step.
fn normal_ls_with(
    gram: &CsMat<f64>,
    rhs: &[&[f64]],
    rows: usize,
    column_samples: &[usize],
    ordering: Option<&[usize]>,
    residual: Option<NormalResidual<'_>>,
    params: &GlobalLsParams,
) -> Result<GlobalLs, SolveError> {
    params.validate()?;
    let p = gram.rows();
    check_values(rhs, p)?;
    if gram.cols() != p || !gram.is_csr() || column_samples.len() != p {
        return Err(SolveError::DimensionMismatch {
            what: "normal matrix (square CSR) and column samples",
            expected: p,
            found: column_samples.len(),
        });
    }
    if let Some(order) = ordering {
        let mut seen = vec![false; p];
        if order.len() != p
            || order
                .iter()
                .any(|&a| a >= p || std::mem::replace(&mut seen[a], true))
        {
            return Err(SolveError::DimensionMismatch {
                what: "elimination order (a permutation of the columns)",
                expected: p,
                found: order.len(),
            });
        }
    }
    let ch = rhs.len();
    if ch == 0 || p == 0 {
        return Ok(GlobalLs::empty(p, ch, GlobalMethod::Cholesky));
    }
    let mut ktf = vec![0.0; p * ch];
    for (c, r) in rhs.iter().enumerate() {
        for (a, v) in r.iter().enumerate() {
            ktf[a * ch + c] = *v;
        }
    }
    // The residual in the equilibrated variables: `D K^T (f - K D y)`, row-major `P x ch`.
    // A residual of the wrong shape is the caller's error, reported after the solve.
    let misshapen = std::sync::Mutex::new(None::<(usize, usize)>);
    let correction = residual.map(|residual| {
        let misshapen = &misshapen;
        move |y: &[f64], d: &[f64]| -> Vec<f64> {
            let c: Vec<Vec<f64>> = (0..ch)
                .map(|k| (0..p).map(|a| d[a] * y[a * ch + k]).collect())
                .collect();
            let r = residual(&c);
            let mut out = vec![0.0; p * ch];
            let bad = (r.len() != ch)
                .then_some((ch, r.len()))
                .or_else(|| r.iter().map(Vec::len).find(|&n| n != p).map(|n| (p, n)));
            if bad.is_some() {
                *misshapen.lock().unwrap_or_else(|e| e.into_inner()) = bad;
                return out;
            }
            for (k, rk) in r.iter().enumerate() {
                for (a, v) in rk.iter().enumerate() {
                    out[a * ch + k] = d[a] * v;
                }
            }
            out
        }
    });
    let solved = factor_solve(
        gram,
        &ktf,
        ch,
        rows,
        &|a| column_samples[a],
        ordering,
        correction
            .as_ref()
            .map(|f| f as &(dyn Fn(&[f64], &[f64]) -> Vec<f64> + Sync)),
        params,
    )?;
    if let Some((expected, found)) = misshapen.into_inner().unwrap_or_else(|e| e.into_inner()) {
        return Err(SolveError::DimensionMismatch {
            what: "normal residual (one vector of P entries per channel)",
            expected,
            found,
        });
    }
    let (gp, gi, gd) = raw(gram);
    let coefficients: Vec<Vec<f64>> = (0..ch)
        .map(|c| (0..p).map(|a| solved.d[a] * solved.y[a * ch + c]).collect())
        .collect();
    let residuals = coefficients
        .iter()
        .zip(rhs)
        .map(|(x, b)| {
            let residual: Vec<f64> = (0..p)
                .into_par_iter()
                .map(|a| {
                    let gx: f64 = (gp[a]..gp[a + 1]).map(|t| gd[t] * x[gi[t]]).sum();
                    solved.d[a] * (b[a] - gx)
                })
                .collect();
            let num = crate::norms::rms(residual);
            let den = crate::norms::rms((0..p).map(|a| solved.d[a] * b[a]));
            // ||.||_2 ratio = rms ratio (same count); ||.||_2 = sqrt(p) rms when den = 0.
            if den > 0.0 {
                num / den
            } else {
                num * (p as f64).sqrt()
            }
        })
        .collect();
    for (c, x) in coefficients.iter().enumerate() {
        check_finite_output(x, &format!("normal-equation least squares, channel {c}"))?;
    }
    Ok(GlobalLs {
        coefficients,
        report: solved.report(residuals),
    })
}

/// Smallest `L_qq^2` (elimination step `q`) of a factor's diagonal `L_qq`.
fn min_pivot_of(diagonal: &[f64]) -> (usize, f64) {
    diagonal
        .iter()
        .enumerate()
        .map(|(q, &l)| (q, l * l))
        .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a })
}
