//! Errors of the solver layer: `Result<T, SolveError>` everywhere a user can reach.
//!
//! Every variant carries the offending values and says how to fix the call, so a report
//! can print the error as it is. The solvers never panic on user input and never return a
//! non-finite number silently: a NaN or an infinity in an output becomes
//! [`SolveError::NonFiniteOutput`].

use thiserror::Error;

use crate::error::Fix;

/// Everything that can go wrong in `crate::solve`.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum SolveError {
    /// Fewer samples than basis functions where the method needs full column rank
    /// (a sparse Cholesky of `K^T K` with `RankPolicy::Error`).
    #[error(
        "{samples} samples cannot determine {functions} basis functions (K^T K is \
         singular): give at least {functions} samples (twice as many is better) or fewer \
         basis functions (a smaller fine level), or accept a regularized answer with {fix}",
        fix = Fix::RegularizedAnswer
    )]
    Undersampled {
        /// Samples `m` (rows of `K`).
        samples: usize,
        /// Basis functions `P` (columns of `K`).
        functions: usize,
    },

    /// The normal matrix is numerically singular although `rows >= cols`.
    #[error(
        "rank deficient: pivot {pivot:.3e} of the equilibrated normal matrix at column \
         {column} is below the threshold {threshold:.3e} (column has {column_samples} \
         nonzero samples). Add samples where that basis function lives, lower the fine \
         level, or accept a regularized answer: {regularize} ({local}), which cuts \
         unsupported directions",
        regularize = Fix::RegularizeOrLocal,
        local = Fix::MethodLocal
    )]
    RankDeficient {
        /// A column (basis function) at which the factorization found the deficiency.
        column: usize,
        /// The pivot found there, relative to a unit diagonal.
        pivot: f64,
        /// The threshold it fell under.
        threshold: f64,
        /// Structural nonzeros of that column of `K`.
        column_samples: usize,
    },

    /// The request would need more memory than the limit.
    #[error(transparent)]
    Resources(#[from] crate::resources::ResourceError),

    /// A factorization failed outright.
    #[error("factorization failed: {what}")]
    Factorization {
        /// Which factorization, where, and what to change.
        what: String,
    },

    /// The dense SVD of the kernel matrix did not converge.
    #[error(
        "factorization failed: dense SVD of the {rows} x {cols} kernel matrix: {detail}; try \
         {qr} locally",
        qr = Fix::SolverQr
    )]
    DenseSvd {
        /// Rows of `K`.
        rows: usize,
        /// Columns of `K`.
        cols: usize,
        /// The SVD's own report.
        detail: String,
    },

    /// Shapes of the inputs do not fit together.
    #[error("dimension mismatch in {what}: expected {expected}, found {found}")]
    DimensionMismatch {
        /// Which input.
        what: &'static str,
        /// The size it must have.
        expected: usize,
        /// The size it has.
        found: usize,
    },

    /// A parameter is out of its range.
    #[error("invalid {name} = {value}: {fix}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// Allowed range / what to pass instead.
        fix: &'static str,
    },

    /// An input holds NaN or an infinity.
    #[error("non-finite input in {what} at position {index}: {value}; clean the samples first")]
    NonFiniteInput {
        /// Which input (`"kernel matrix"`, `"values channel 2"`, …).
        what: String,
        /// Flat index of the first offending entry (storage order).
        index: usize,
        /// The offending value.
        value: f64,
    },

    /// A result came out non-finite (overflow); nothing is returned rather than NaN.
    #[error(
        "non-finite output in {what}: the result overflows f64. Rescale the values \
         (e.g. divide them by their largest magnitude), or drop more singular values: \
         raise the relative cut-off of the pseudo-inverse ({cutoff}, e.g. 1e-8)",
        cutoff = Fix::Cutoff
    )]
    NonFiniteOutput {
        /// Which output.
        what: String,
    },

    /// A dense reference was asked for a matrix that is too large.
    #[error(
        "matrix {rows} x {cols} is too large for the dense reference (limit {limit} per \
         dimension); use the sparse least squares instead ({global} or {single})",
        global = Fix::MethodGlobal,
        single = Fix::MethodSingleScale
    )]
    TooLarge {
        /// Rows of `K`.
        rows: usize,
        /// Columns of `K`.
        cols: usize,
        /// Largest dimension accepted.
        limit: usize,
    },

    /// The iterative solver did not reach its tolerance.
    #[error(
        "iterative solve of channel {channel} did not converge: relative normal-equation \
         residual {residual:.3e} > tol {tol:.3e} after {iterations} iterations. Raise \
         GlobalLsParams::max_iter above {iterations}, loosen GlobalLsParams::tol (e.g. \
         1e-10), or use GlobalLsParams::method = GlobalMethod::Cholesky"
    )]
    NotConverged {
        /// Channel (right-hand side) that failed.
        channel: usize,
        /// Iterations done.
        iterations: usize,
        /// Final relative residual `||K^T r|| / ||K^T f||`.
        residual: f64,
        /// Tolerance asked for.
        tol: f64,
    },
}

impl SolveError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            SolveError::Undersampled { .. } | SolveError::RankDeficient { .. } => {
                crate::error::ErrorKind::Undetermined
            }
            SolveError::Resources(e) => e.kind(),
            SolveError::Factorization { .. }
            | SolveError::DenseSvd { .. }
            | SolveError::NonFiniteOutput { .. } => crate::error::ErrorKind::Numerical,
            SolveError::DimensionMismatch { .. }
            | SolveError::InvalidParameter { .. }
            | SolveError::NonFiniteInput { .. } => crate::error::ErrorKind::InvalidInput,
            SolveError::TooLarge { .. } => crate::error::ErrorKind::ResourceLimit,
            SolveError::NotConverged { .. } => crate::error::ErrorKind::NotConverged,
        }
    }
}

crate::error::classified!(SolveError);
