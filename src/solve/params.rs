//! Knobs of the solvers: `K~ ≈ K^+` column by column from `pinv(K[jdx, idx])` (local), or
//! `c = argmin ||K c - f||` (global).
//!
//! Every field says what it costs and what it buys; the defaults are the accurate choice.

use serde::Serialize;

use super::SolveError;

/// Dense solver for one local block `K1 = K[jdx, idx]` (`r x n`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Default)]
pub enum Solver {
    /// Thin SVD, `K1^+ = V diag(1/s_k, s_k > cutoff * s_max) U^T`: the minimum-norm
    /// pseudo-inverse, exact condition numbers; the most expensive (~ 2-4x QR).
    #[default]
    Svd,
    /// Column-pivoted Householder QR, `K1 P = Q R`, least squares on the leading `rank`
    /// columns where `|R_kk| > cutoff * |R_00|`. Equals the pseudo-inverse for full column
    /// rank; for a rank-deficient block it is the *basic* solution (zeros on the dropped
    /// columns), not the minimum-norm one. Condition numbers are `|R_00| / |R_nn|` estimates.
    Qr,
    /// Cholesky of the normal matrix `K1^T K1 = (K^T K)[idx, idx]` (extracted from a
    /// global `K^T K` formed once, so `K1` is never built), after symmetric diagonal
    /// equilibration. Cheapest, but squares the condition number: accurate to about
    /// `cond(K1)^2 * eps`. A failed or numerically singular factorization is retried with a
    /// relative diagonal shift ([`LocalInversionParams::cholesky_shift`]), and reported.
    Cholesky,
}

/// Most neighbourhood rings the command line accepts: rings 1 already reaches 1e-9..1e-16
/// (docs/design.md §4) and each ring widens every block (up to 8x the factorization); the library
/// takes any number and stops growing a neighbourhood once it no longer changes.
pub const MAX_RINGS: usize = 10;

/// Parameters of the local inversion (`solve::local_inversion`, `apply_local`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LocalInversionParams {
    /// Neighbourhood growth steps (`idx <- columns touching jdx`, `jdx <- rows touching
    /// idx`): each ring multiplies block rows and columns (about 2x in 1D) and the
    /// factorization cost (~ r n^2) by up to ~8x, and buys orders of magnitude of accuracy
    /// (docs/design.md §4: rings 0 → 1e-4..1e2 error, rings 1 → 1e-9..1e-16).
    pub rings: usize,
    /// Dense solver per block, see [`Solver`]: SVD is exact and slowest, Cholesky the
    /// cheapest and least accurate on ill-conditioned blocks.
    pub solver: Solver,
    /// Relative cut-off: singular values (SVD) or `|R_kk|` (QR) below `cutoff * max` are
    /// dropped. Larger values bound the block inverse by `1 / (cutoff * s_max)` (no blow-up
    /// on undersampled blocks) at the price of a biased, lower-rank local fit.
    pub cutoff: f64,
    /// First relative diagonal shift for a failed Cholesky (times the unit diagonal of the
    /// equilibrated normal matrix, x10 per retry, at most 8 retries): a larger shift always
    /// succeeds but biases the result like a ridge of that size; unused by SVD / QR.
    pub cholesky_shift: f64,
}

impl Default for LocalInversionParams {
    fn default() -> Self {
        Self {
            rings: 1,
            solver: Solver::Svd,
            cutoff: 1e-12,
            cholesky_shift: 1e-12,
        }
    }
}

impl LocalInversionParams {
    /// Checks ranges; called by every entry point.
    pub fn validate(&self) -> Result<(), SolveError> {
        if !(self.cutoff.is_finite() && (0.0..1.0).contains(&self.cutoff)) {
            return Err(SolveError::InvalidParameter {
                name: "cutoff",
                value: self.cutoff.to_string(),
                fix: "pass a relative singular value cut-off in [0, 1), e.g. 1e-12",
            });
        }
        if !(self.cholesky_shift.is_finite()
            && self.cholesky_shift > 0.0
            && self.cholesky_shift < 1.0)
        {
            return Err(SolveError::InvalidParameter {
                name: "cholesky_shift",
                value: self.cholesky_shift.to_string(),
                fix: "pass a relative shift in (0, 1), e.g. 1e-12",
            });
        }
        Ok(())
    }
}

/// Global sparse least-squares method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Default)]
pub enum GlobalMethod {
    /// Sparse Cholesky of the equilibrated `K^T K` (AMD ordering, symbolic once, numeric
    /// once, all channels solved with the one factor), then one step of the corrected
    /// semi-normal equations `c += (R^T R)^{-1} K^T (f - K c)` (Björck): forward error of
    /// order `eps cond(K)`, a QR's, where the normal equations alone give `eps cond(K)^2`
    /// (valid while `eps cond(K)^2 < 1`; skipped when a ridge was added). Memory grows with
    /// fill-in (tiny for banded 1D problems, large in 2D).
    #[default]
    Cholesky,
    /// CGLS (conjugate gradients on the normal equations without forming them, Jacobi
    /// column scaling as preconditioner), matrix-free on the sprs CSR arrays, all channels
    /// per sweep. Memory `O(nnz + (m + P) * channels)`; iterations grow with `cond(K)`.
    Cgls,
}

/// What the global Cholesky does with a numerically singular `K^T K`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Default)]
pub enum RankPolicy {
    /// Return [`SolveError::Undersampled`] / [`SolveError::RankDeficient`].
    #[default]
    Error,
    /// Add the ridge `GlobalLsParams::ridge` (relative to the unit diagonal of the
    /// equilibrated normal matrix) and solve; reported in `GlobalReport::ridge`.
    Regularize,
}

/// Parameters of the global sparse least-squares solve (`solve::global_ls`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GlobalLsParams {
    /// Cholesky (direct) or CGLS (iterative).
    pub method: GlobalMethod,
    /// Cholesky only: error out or regularize when the normal matrix is singular.
    pub rank_policy: RankPolicy,
    /// Cholesky only: a pivot of the equilibrated normal matrix below this declares it
    /// numerically singular; smaller accepts worse-conditioned problems (accuracy
    /// `~ eps / pivot`), larger rejects them earlier.
    pub pivot_tol: f64,
    /// Cholesky with `RankPolicy::Regularize`: relative ridge added to the unit diagonal;
    /// larger is more robust and more biased.
    pub ridge: f64,
    /// CGLS only: stop when `||A^T r|| <= tol * ||A^T f||` (equilibrated `A`); smaller
    /// costs iterations (linear in `log(1/tol)`) and gives digits.
    pub tol: f64,
    /// CGLS only: iteration budget; exceeding it is [`SolveError::NotConverged`].
    pub max_iter: usize,
}

impl Default for GlobalLsParams {
    fn default() -> Self {
        Self {
            method: GlobalMethod::Cholesky,
            rank_policy: RankPolicy::Error,
            pivot_tol: 1e-13,
            ridge: 1e-10,
            tol: 1e-13,
            max_iter: 20_000,
        }
    }
}

impl GlobalLsParams {
    /// Checks ranges; called by every entry point.
    pub fn validate(&self) -> Result<(), SolveError> {
        let pos = |name, v: f64, fix| {
            if v.is_finite() && v > 0.0 && v < 1.0 {
                Ok(())
            } else {
                Err(SolveError::InvalidParameter {
                    name,
                    value: v.to_string(),
                    fix,
                })
            }
        };
        pos(
            "pivot_tol",
            self.pivot_tol,
            "pass a value in (0, 1), e.g. 1e-13",
        )?;
        pos("ridge", self.ridge, "pass a value in (0, 1), e.g. 1e-10")?;
        pos("tol", self.tol, "pass a value in (0, 1), e.g. 1e-13")?;
        if self.max_iter == 0 {
            return Err(SolveError::InvalidParameter {
                name: "max_iter",
                value: "0".into(),
                fix: "pass at least 1 iteration",
            });
        }
        Ok(())
    }
}
