//! Solving the 2D normal equations `(G + lambda D^{-2}) z = b`: sparse Cholesky or PCG.
//!
//! `D = diag(G)^{-1/2}` equilibrates: the matrix factored is `A = D G D + lambda I` (a
//! relative ridge `lambda`, stated in the report), `z = D y`, `A y = D b`. A function with no
//! sample in its support has `G_kk = 0`: `D_kk = 0` pins its coefficient to 0 (reported as
//! unsampled), the rest of the system is untouched.
//!
//! - Cholesky: faer's supernodal sparse `L L^T` with an AMD ordering; the symbolic
//!   factorization depends only on the stencil pattern (once per basis), the numeric one on
//!   the samples (once per image), and every channel is solved from the one factor. A failed
//!   factorization (a direction the samples do not determine) is retried with the ridge
//!   multiplied by 100 (reported).
//! - PCG on `A`: conjugate gradients with no preconditioner, Jacobi (`diag(A)^{-1}`, which on the
//!   equilibrated `A` is the identity up to the ridge, so it is run on `G` itself), or local
//!   inversion (`M = K~ K~^T` with `K~ ≈ K^+` from [`crate::solve::local_inversion`] on the 2D
//!   kernel matrix: `K^+ K^{+T} = (K^T K)^{-1}`), stopped at a relative residual. Where the
//!   samples are dense (a few per function, stratified) the functions are a Riesz basis for the
//!   sample points: `A` is a mass-like matrix with eigenvalues in `[a, b]`, `b / a` small and
//!   independent of the resolution, so Jacobi PCG converges in a fixed number of iterations
//!   (error factor `2 ((sqrt k - 1) / (sqrt k + 1))^j` after `j` of them, `k = b / a`) at a cost
//!   of one pass over `G` each: the default above `64²` unknowns ([`NormalSolver::Auto`]). Where
//!   the samples
//!   leave directions nearly undetermined `k` grows with the ridge's `1 / lambda`; CG then
//!   stops at its iteration cap and the fit falls back to the Cholesky (reported,
//!   [`StencilCgReport::fallback`]), so a hard case costs at most the cap's iterations more.

use faer::{Mat, Par};
use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMat;

use super::normal::{symmetric_matvec, StencilPattern};
use crate::solve::cg::{
    self, CgParams, ConditionEstimate, Identity, IterationLimit, LocalInverse, ResidualReport,
    SymmetricOperator,
};
use crate::solve::cholesky::{CholeskyError, Pivots, SparseCholesky};

/// The preconditioner of conjugate gradients on the stencil system (the uniform 2D normal
/// equations), as a choice: `None`, Jacobi or local inversion. Each is applied through the
/// one preconditioner trait of the solver layer, [`crate::solve::cg::Preconditioner`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum StencilPreconditioner {
    /// Plain CG on `G + lambda diag(G)`.
    None,
    /// `M = diag(G)^{-1}`: free, and removes the scale differences between functions.
    Jacobi,
    /// `M = K~ K~^T`, `K~` the local inversion of the 2D kernel matrix (rings 0, Cholesky
    /// blocks): a setup of one small factorization per sample pattern, an apply of two
    /// passes over `K~` (`m` columns of `(2p - 1)^2` entries); fewer iterations.
    Local,
}

/// Fill-reducing ordering of the sparse Cholesky.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum FillOrdering {
    /// Nested dissection of the grid of unknowns (separators one 1D half-bandwidth wide):
    /// `O(N log N)` fill and `O(N^{3/2})` flops on a 2D stencil, no graph search.
    #[default]
    NestedDissection,
    /// faer's approximate minimum degree (a general graph heuristic).
    Amd,
}

/// How the normal equations are solved.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum NormalSolver {
    /// By size ([`NormalSolver::resolve`]): the sparse Cholesky up to
    /// [`CHOLESKY_MAX_FUNCTIONS`] unknowns, where it is exact and no slower, and Jacobi PCG
    /// above ([`NormalSolver::default_cg`], with its fallback to the Cholesky). The report
    /// names the solver used.
    Auto,
    /// Sparse Cholesky (exact; memory of the fill-in, ~`N log N`).
    Cholesky,
    /// Preconditioned conjugate gradients (memory of `G` only).
    Cg {
        /// The preconditioner.
        preconditioner: StencilPreconditioner,
        /// Stop at `||b - A x|| <= tolerance ||b||`.
        tolerance: f64,
        /// With `Some(eps)`, go on past `tolerance` until the estimated relative error of the
        /// coefficients `cond(M^{-1} A) ||r||_{M^{-1}} / ||b||_{M^{-1}}` is at most `eps`
        /// ([`crate::solve::cg`]'s forward-error stop): the residual alone leaves errors up
        /// to `cond(A) tolerance`, `1e-2` of the value range on detail at Nyquist.
        forward_error: Option<f64>,
        /// Stop after this many iterations: a channel short of the tolerance then makes the
        /// fit solve the system by the sparse Cholesky instead (reported,
        /// [`StencilCgReport::fallback`]).
        max_iterations: usize,
    },
    /// Local inversion instead of a global solve (docs/design.md §4): `z_c = K~ f_c` with `K~ ≈ K^+`
    /// from [`crate::solve::apply_local`] on the 2D kernel matrix: local, approximate (its
    /// error against the global solve shrinks with `rings`), and `G` is still accumulated for
    /// `ImageFit::solve_normal`.
    Local(crate::solve::LocalInversionParams),
}

/// Relative residual at which the default CG stops ([`NormalSolver::default_cg`]): the pixels
/// then agree with the Cholesky's to well below the noise of a render
/// (docs/measurements/plan-speed.md, "The uniform fit by conjugate gradients").
pub const CG_TOLERANCE: f64 = 1e-6;

/// Estimated relative error of the coefficients at which the default CG stops
/// ([`NormalSolver::default_cg`]; `cond(M^{-1} A) ||r||_{M^{-1}} / ||b||_{M^{-1}}`,
/// [`crate::solve::cg`]).
pub const CG_FORWARD_ERROR: f64 = 1e-6;

/// Iterations after which the default CG gives way to the Cholesky: a few times what dense
/// samples need, and well below the cost of the factorization in passes over `G`.
pub const CG_MAX_ITERATIONS: usize = 150;

/// Unknowns up to which [`NormalSolver::Auto`] takes the sparse Cholesky: at 4 samples per
/// function its factorization costs about what the CG iterations do at `64²` and grows as
/// `N^{3/2}` against CG's `N` (docs/measurements/plan-speed.md, "The uniform fit by conjugate
/// gradients").
pub const CHOLESKY_MAX_FUNCTIONS: usize = crate::resources::UNIFORM_CHOLESKY_MAX_FUNCTIONS;

impl NormalSolver {
    /// The solver for `functions` unknowns: [`NormalSolver::Auto`] resolved by size, any other
    /// unchanged.
    pub fn resolve(self, functions: usize) -> Self {
        match self {
            NormalSolver::Auto if functions <= CHOLESKY_MAX_FUNCTIONS => NormalSolver::Cholesky,
            NormalSolver::Auto => NormalSolver::default_cg(),
            other => other,
        }
    }

    /// Jacobi PCG to [`CG_TOLERANCE`] and the forward error [`CG_FORWARD_ERROR`], at most
    /// [`CG_MAX_ITERATIONS`] (then the Cholesky).
    pub const fn default_cg() -> Self {
        NormalSolver::Cg {
            preconditioner: StencilPreconditioner::Jacobi,
            tolerance: CG_TOLERANCE,
            forward_error: Some(CG_FORWARD_ERROR),
            max_iterations: CG_MAX_ITERATIONS,
        }
    }
}

/// What one CG solve of the stencil system did: per channel what the solver layer's
/// [`crate::solve::cg::CgReport`] says, with the preconditioner chosen, its setup time and
/// the fallback taken.
#[derive(Clone, Debug, Serialize)]
pub struct StencilCgReport {
    /// The preconditioner.
    pub preconditioner: StencilPreconditioner,
    /// Iterations per channel.
    pub iterations: Vec<usize>,
    /// Final relative residual per channel.
    pub residual: Vec<f64>,
    /// With the forward-error stop: per channel the final estimated bound on the
    /// coefficients' relative error.
    pub forward_error: Option<Vec<f64>>,
    /// Whether every channel reached the tolerance (and the forward-error tolerance).
    pub converged: bool,
    /// Seconds to build the preconditioner.
    pub setup_s: f64,
    /// Why the system was solved by the sparse Cholesky after all (a channel short of the
    /// tolerance at the iteration cap, or a breakdown); `None` when CG's iterate is the result.
    pub fallback: Option<String>,
    /// What the caller does at the iteration limit, named at the call (the stencil system's
    /// is [`IterationLimit::FallBack`]); taken when `converged` is false.
    pub on_limit: IterationLimit,
}

/// The assembled system and (for Cholesky) its factor.
pub struct NormalSystem {
    pattern: StencilPattern,
    /// `G` on the pattern (lower triangle).
    g: Vec<f64>,
    /// `D_kk = G_kk^{-1/2}` (0 where unsampled).
    d: Vec<f64>,
    /// Relative ridge actually used.
    ridge: f64,
    factor: Option<SparseCholesky>,
    /// Stored entries of the Cholesky factor.
    factor_nnz: usize,
    /// How the factorization, the solve and the equilibration run: on the rayon pool
    /// (`Par::rayon(0)`, the default) or on the calling thread ([`Self::sequential`]).
    par: Par,
}

/// What the Cholesky factorization found.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FactorReport {
    /// The fill-reducing ordering used.
    pub ordering: FillOrdering,
    /// Stored entries of `L` (fill-in included).
    pub factor_nnz: usize,
    /// Pivots `L_jj^2` of the equilibrated matrix below [`PIVOT_TOLERANCE`] (directions the
    /// samples do not determine, beyond the unsampled functions): each was replaced by 1,
    /// which fixes that direction's component at about 0 (reported, never NaN).
    pub replaced_pivots: usize,
    /// Smallest pivot `L_jj^2` kept (about `1 / cond`; small values flag undersampled areas).
    pub min_pivot: f64,
    /// Times the factorization met a negative pivot and was redone with the ridge times 100
    /// (the final ridge is in the solve report).
    pub ridge_retries: usize,
}

/// Largest relative ridge tried before the factorization is declared failed.
pub const MAX_RIDGE: f64 = 1e-2;

/// Pivots of the equilibrated factor below this are replaced (as in 1D, see
/// [`crate::reconstruct::PIVOT_TOLERANCE`]).
pub const PIVOT_TOLERANCE: f64 = crate::reconstruct::PIVOT_TOLERANCE;

impl std::fmt::Debug for NormalSystem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NormalSystem")
            .field("unknowns", &self.pattern.len())
            .field("nnz", &self.pattern.nnz())
            .field("ridge", &self.ridge)
            .field("factored", &self.factor.is_some())
            .finish()
    }
}

fn equilibration(pattern: &StencilPattern, g: &[f64]) -> Vec<f64> {
    (0..pattern.len())
        .map(|j| {
            let v = g[pattern.col_ptr[j]];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect()
}

impl NormalSystem {
    /// Wraps `G` without factoring (for CG).
    pub fn new(pattern: StencilPattern, g: Vec<f64>, ridge: f64) -> Self {
        let d = equilibration(&pattern, &g);
        Self {
            pattern,
            g,
            d,
            ridge,
            factor: None,
            factor_nnz: 0,
            par: Par::rayon(0),
        }
    }

    /// The same system worked on the calling thread alone: for callers that already run one
    /// system per worker (the tiles of `image::tiles`). The arithmetic is that of a
    /// one-thread pool, so the bits do not depend on the pool the caller runs in.
    pub fn sequential(mut self) -> Self {
        self.par = Par::Seq;
        self
    }

    /// Factors `A = D G D + lambda I`: symbolic (the given fill-reducing ordering), then
    /// numeric with pivots below [`PIVOT_TOLERANCE`] replaced by 1; a negative pivot is
    /// retried with the ridge times 100 up to [`MAX_RIDGE`].
    pub fn factor(&mut self, ordering: FillOrdering) -> Result<FactorReport, CholeskyError> {
        const WHAT: &str = "2D normal matrix";
        let n = self.pattern.len();
        let fwd = match ordering {
            FillOrdering::NestedDissection => Some(self.pattern.nested_dissection()),
            FillOrdering::Amd => None,
        };
        let (col_ptr, row_idx) = (&self.pattern.col_ptr, &self.pattern.row_idx);
        let mut cholesky = SparseCholesky::analyze(WHAT, col_ptr, row_idx, fwd.as_deref())?;
        let par = self.par;
        let pivots = Pivots::ReplaceBelow {
            epsilon: PIVOT_TOLERANCE,
        };
        let mut ridge_retries = 0;
        loop {
            let a = self.equilibrated(self.ridge);
            match cholesky.factor(col_ptr, row_idx, &a, pivots, par) {
                Ok(()) => break,
                // a negative pivot (rounding on a direction the samples do not determine):
                // a larger ridge, reported
                Err(_) if self.ridge < MAX_RIDGE => {
                    self.ridge = (self.ridge * 100.0).max(1e-12);
                    ridge_retries += 1;
                }
                Err(e) => {
                    return Err(CholeskyError::NotPositive {
                        what: WHAT,
                        size: n,
                        step: e.step,
                        ridge: self.ridge,
                    })
                }
            }
        }
        let pivots = cholesky.diagonal();
        // replaced pivots are exactly 1 (delta); so are unsampled functions' (pinned) ones
        let pinned = self.d.iter().filter(|&&d| d == 0.0).count();
        let ones = pivots.iter().filter(|&&l| l == 1.0).count();
        let min_pivot = pivots
            .iter()
            .filter(|&&l| l != 1.0)
            .map(|l| l * l)
            .fold(f64::INFINITY, f64::min);
        self.factor_nnz = cholesky.factor_nnz();
        self.factor = Some(cholesky);
        Ok(FactorReport {
            ordering,
            factor_nnz: self.factor_nnz,
            replaced_pivots: ones.saturating_sub(pinned),
            min_pivot,
            ridge_retries,
        })
    }

    /// `A = D G D + lambda I` on the pattern (unsampled diagonals set to 1).
    fn equilibrated(&self, ridge: f64) -> Vec<f64> {
        let p = &self.pattern;
        let mut a = vec![0.0; self.g.len()];
        let fill = |(chunk, out): (usize, &mut [f64])| {
            let start = chunk << 14;
            // column of the first entry: binary search in col_ptr
            let mut j = p.col_ptr.partition_point(|&c| c <= start) - 1;
            for (t, v) in out.iter_mut().enumerate() {
                let s = start + t;
                while p.col_ptr[j + 1] <= s {
                    j += 1;
                }
                let i = p.row_idx[s];
                *v = self.d[i] * self.g[s] * self.d[j];
                if i == j {
                    *v = if self.d[j] == 0.0 { 1.0 } else { *v + ridge };
                }
            }
        };
        match self.par {
            Par::Seq => a.chunks_mut(1 << 14).enumerate().for_each(fill),
            _ => a.par_chunks_mut(1 << 14).enumerate().for_each(fill),
        }
        a
    }

    /// The pattern of `G`.
    pub fn pattern(&self) -> &StencilPattern {
        &self.pattern
    }
    /// Relative ridge in use.
    pub fn ridge(&self) -> f64 {
        self.ridge
    }
    /// Entries of the Cholesky factor (0 before [`Self::factor`]).
    pub fn factor_nnz(&self) -> usize {
        self.factor_nnz
    }
    /// Whether a Cholesky factor is held.
    pub fn is_factored(&self) -> bool {
        self.factor.is_some()
    }

    /// Solves `(G + lambda D^{-2}) z = b` for several right-hand sides with the factor.
    ///
    /// # Panics
    /// If the system is not factored (an internal contract).
    pub fn solve_factored(&self, rhs: &[&[f64]]) -> Vec<Vec<f64>> {
        let cholesky = self.factor.as_ref().expect("solve_factored needs a factor");
        let n = self.pattern.len();
        let mut b = Mat::<f64>::from_fn(n, rhs.len(), |i, c| self.d[i] * rhs[c][i]);
        let par = if rhs.len() > 1 { self.par } else { Par::Seq };
        cholesky.solve_in_place(b.as_mut(), par);
        (0..rhs.len())
            .map(|c| (0..n).map(|i| self.d[i] * b[(i, c)]).collect())
            .collect()
    }

    /// `y_c = (G + lambda D^{-2}) x_c` for every vector (zero rows and columns where
    /// unsampled).
    pub fn apply(&self, x: &[&[f64]], y: &mut [Vec<f64>]) {
        symmetric_matvec(&self.pattern, &self.g, x, y);
        let r = self.ridge;
        if r > 0.0 {
            for (xc, yc) in x.iter().zip(y.iter_mut()) {
                for ((yi, xi), di) in yc.iter_mut().zip(xc.iter()).zip(&self.d) {
                    if *di > 0.0 {
                        *yi += r * xi / (di * di)
                    }
                }
            }
        }
    }

    /// PCG for `(G + lambda D^{-2}) z_c = b_c`, all right-hand sides together (one pass over
    /// `G` per iteration serves every channel still iterating: [`crate::solve::cg::pcg`]);
    /// `local` is `K~` (CSC, `P x m`) and its CSR form for [`StencilPreconditioner::Local`].
    /// Returns per channel the solution, the iterations and the final recurred relative
    /// residual `||b - A z|| / ||b||`, and the estimated forward-error bound when
    /// `forward_error` is given. Components of `b` where a function is unsampled are
    /// outside the range of `G` and dropped.
    pub fn solve_cg(
        &self,
        rhs: &[&[f64]],
        preconditioner: StencilPreconditioner,
        local: Option<&(CsMat<f64>, CsMat<f64>)>,
        tolerance: f64,
        forward_error: Option<f64>,
        max_iterations: usize,
    ) -> Vec<(Vec<f64>, usize, f64, Option<f64>)> {
        let b: Vec<Vec<f64>> = rhs
            .iter()
            .map(|b| {
                b.iter()
                    .zip(&self.d)
                    .map(|(v, d)| if *d > 0.0 { *v } else { 0.0 })
                    .collect()
            })
            .collect();
        let b: Vec<&[f64]> = b.iter().map(|b| b.as_slice()).collect();
        let params = CgParams {
            tolerance,
            max_iterations,
            residual: ResidualReport::Recurred,
            condition: ConditionEstimate::Skip,
            forward_error,
        };
        let jacobi = EquilibratedJacobi {
            d: &self.d,
            ridge: self.ridge,
        };
        let local = local.map(|(csc, csr)| LocalInverse::new(csc, csr));
        let pre: &dyn cg::Preconditioner = match (preconditioner, &local) {
            (StencilPreconditioner::Jacobi, _) => &jacobi,
            (StencilPreconditioner::Local, Some(local)) => local,
            _ => &Identity,
        };
        let (x, report) = cg::pcg(self, pre, &b, None, &params);
        let bounds = report.forward_error.unwrap_or_default();
        x.into_iter()
            .zip(report.iterations)
            .zip(report.relative_residual)
            .enumerate()
            .map(|(c, ((x, it), r))| (x, it, r, bounds.get(c).copied()))
            .collect()
    }
}

impl SymmetricOperator for NormalSystem {
    fn dim(&self) -> usize {
        self.pattern.len()
    }
    fn apply(&self, p: &[&[f64]], q: &mut [Vec<f64>]) {
        NormalSystem::apply(self, p, q);
    }
}

/// Jacobi on `A = G + lambda D^{-2}`: `diag(A) = (1 + lambda) D^{-2}`, so `z_i = d_i^2 r_i /
/// (1 + lambda)` (0 where unsampled).
struct EquilibratedJacobi<'a> {
    d: &'a [f64],
    ridge: f64,
}

impl cg::Preconditioner for EquilibratedJacobi<'_> {
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]) {
        for (z, r) in z.iter_mut().zip(r) {
            for ((zi, ri), di) in z.iter_mut().zip(*r).zip(self.d) {
                *zi = di * di * ri / (1.0 + self.ridge);
            }
        }
    }
}
