//! Why an adaptive image reconstruction refused or failed.

use thiserror::Error;

use crate::basis::tensor::TensorError;
use crate::image::fit::ImageFitError;
use crate::image::pixels::PixelError;
use crate::solve::SolveError;

/// Errors of the adaptive image engine: each names the value at fault and the way out.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum AdaptiveError {
    /// A parameter out of range.
    #[error("{parameter} = {value} is invalid: {expected}")]
    Parameter {
        /// The parameter's name.
        parameter: &'static str,
        /// Its value as given.
        value: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// The base samples alone exceed the budget.
    #[error(
        "the sample budget {budget} is below the {base} base samples ({slots} coarsest slots x \
         {per_slot} samples each): raise the budget or lower rho"
    )]
    BudgetTooSmall {
        /// The budget given.
        budget: usize,
        /// Samples the base set needs.
        base: usize,
        /// Base slots.
        slots: usize,
        /// Samples per slot, `ceil(rho)`.
        per_slot: usize,
    },
    /// The basis (resolution, levels).
    #[error(transparent)]
    Tensor(#[from] TensorError),
    /// Bad sample arrays.
    #[error(transparent)]
    Samples(#[from] ImageFitError),
    /// The least-squares solve.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// Pixel integrals.
    #[error(transparent)]
    Pixels(#[from] PixelError),
    /// A budget whose samples cannot fit in memory (refused before any is drawn).
    #[error(transparent)]
    Resource(#[from] crate::resources::ResourceError),
    /// A recorded refinement history that does not fit the tree (a record of another run).
    #[error(
        "round {round} of the refinement history marks the cell {cell}, which is {reason}: \
         the history belongs to another run or parameters"
    )]
    History {
        /// The round.
        round: usize,
        /// The cell, in words.
        cell: String,
        /// What is wrong with it.
        reason: &'static str,
    },
}

impl AdaptiveError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            AdaptiveError::Parameter { .. }
            | AdaptiveError::BudgetTooSmall { .. }
            | AdaptiveError::History { .. } => crate::error::ErrorKind::InvalidInput,
            AdaptiveError::Tensor(e) => e.kind(),
            AdaptiveError::Samples(e) => e.kind(),
            AdaptiveError::Solve(e) => e.kind(),
            AdaptiveError::Pixels(e) => e.kind(),
            AdaptiveError::Resource(e) => e.kind(),
        }
    }
}

crate::error::classified!(AdaptiveError);
