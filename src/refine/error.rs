//! Errors of the refiner: each names the value at fault and the way out.

use thiserror::Error;

use crate::basis::BasisError;
use crate::kernel::KernelError;
use crate::reconstruct::ReconstructError;
use crate::solve::SolveError;

/// Everything that can go wrong in `crate::refine`.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum RefineError {
    /// A parameter outside its range.
    #[error("invalid {name} = {value}: {fix}")]
    InvalidParameter {
        /// The parameter.
        name: &'static str,
        /// Its value, as given.
        value: String,
        /// What to pass instead.
        fix: &'static str,
    },
    /// The depth limit is below the base tree.
    #[error("max depth {max_depth} is below the base depth {base_depth}: {fix}")]
    MaxDepthBelowBase {
        /// The requested depth limit.
        max_depth: u32,
        /// The depth of the base tree.
        base_depth: u32,
        /// A parameter and a value that work (never a depth above the limit of 52).
        fix: String,
    },
    /// The base sampling alone needs more samples than the budget.
    #[error("the base sampling needs {required} samples but the budget is {budget}: {fix}")]
    BudgetBelowBase {
        /// The budget.
        budget: usize,
        /// Samples the base tree needs (at least).
        required: u64,
        /// A parameter and a value that work.
        fix: String,
    },
    /// The oracle returned NaN or an infinity.
    #[error("the signal is not finite at x = {x} (value {value}): fix the signal or the domain")]
    NonFiniteValue {
        /// The position.
        x: f64,
        /// The value returned.
        value: f64,
    },
    /// A leaf is narrower than the `f64` resolution of the domain.
    #[error(
        "cannot place a sample inside the level-{level} cell at x = {x}: the domain's f64 \
         resolution is exhausted; lower the max depth or shift the domain towards 0"
    )]
    Unresolvable {
        /// Level of the leaf.
        level: u32,
        /// Left end of the leaf, in the domain.
        x: f64,
    },
    /// A round's normal equations are singular: some active function's samples do not
    /// determine it (at one sample per leaf, `p >= 4` leaves such directions).
    #[error(
        "the refinement round's fit is rank deficient: pivot {pivot:.3e} at column {column} \
         ({column_samples} samples in its support) with {per_leaf} sample(s) per leaf at \
         p = {p}: raise {rho} to 2 or more, so that every leaf holds two samples",
        rho = crate::error::Fix::RefineRho
    )]
    RankDeficient {
        /// The column (active function, in the solve's order) where the pivot fell.
        column: usize,
        /// The pivot, relative to a unit diagonal.
        pivot: f64,
        /// Structural nonzeros of that column of `K`.
        column_samples: usize,
        /// Samples per leaf, `ceil(rho)`.
        per_leaf: usize,
        /// Vanishing moments.
        p: usize,
    },
    /// Basis parameters.
    #[error(transparent)]
    Basis(#[from] BasisError),
    /// Kernel matrix construction.
    #[error(transparent)]
    Kernel(#[from] KernelError),
    /// The least-squares solve.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// A reconstruction the refiner measured or converted.
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
}

impl RefineError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            RefineError::InvalidParameter { .. }
            | RefineError::MaxDepthBelowBase { .. }
            | RefineError::BudgetBelowBase { .. }
            | RefineError::NonFiniteValue { .. }
            | RefineError::Unresolvable { .. } => crate::error::ErrorKind::InvalidInput,
            RefineError::RankDeficient { .. } => crate::error::ErrorKind::Undetermined,
            RefineError::Basis(e) => e.kind(),
            RefineError::Kernel(e) => e.kind(),
            RefineError::Solve(e) => e.kind(),
            RefineError::Reconstruct(e) => e.kind(),
        }
    }
}

crate::error::classified!(RefineError);
