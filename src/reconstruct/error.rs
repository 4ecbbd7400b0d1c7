//! The errors of reconstruction, and the fix of an undersampled fit.

use thiserror::Error;

use super::params::Levels;
use super::undersampled::UndersampledFix;
use crate::basis::{minimum_level, BasisError};
use crate::kernel::KernelError;
use crate::solve::SolveError;

/// Errors of reconstruction.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ReconstructError {
    /// Basis parameters.
    #[error(transparent)]
    Basis(#[from] BasisError),
    /// Sample positions.
    #[error(transparent)]
    Kernel(#[from] KernelError),
    /// The solve.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// Fewer samples than basis functions.
    #[error("{samples} samples cannot determine {functions} basis functions: {fix}")]
    Undersampled {
        /// Samples `m` (rows of `K`).
        samples: usize,
        /// Basis functions `P` (columns of `K`).
        functions: usize,
        /// What to change: only changes that can work here (more samples; a smaller fine
        /// level or a larger `rho` only where the basis is not already the smallest for `p`).
        fix: UndersampledFix,
    },
    /// The request would need more memory than the limit.
    #[error(transparent)]
    Resources(#[from] crate::resources::ResourceError),
    /// A sample value is NaN or infinite.
    #[error(
        "sample {row} (1-based), channel {channel}: value {value} is not finite: fix or remove it"
    )]
    NonFiniteValue {
        /// 1-based sample.
        row: usize,
        /// 0-based channel.
        channel: usize,
        /// The value.
        value: f64,
    },
    /// Values and positions disagree in length.
    #[error("channel {channel} has {found} values for {expected} positions")]
    LengthMismatch {
        /// Channel.
        channel: usize,
        /// Positions.
        expected: usize,
        /// Values.
        found: usize,
    },
}

impl ReconstructError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ReconstructError::Basis(e) => e.kind(),
            ReconstructError::Kernel(e) => e.kind(),
            ReconstructError::Solve(e) => e.kind(),
            ReconstructError::Undersampled { .. } => crate::error::ErrorKind::Undetermined,
            ReconstructError::Resources(e) => e.kind(),
            ReconstructError::NonFiniteValue { .. } | ReconstructError::LengthMismatch { .. } => {
                crate::error::ErrorKind::InvalidInput
            }
        }
    }
}

crate::error::classified!(ReconstructError);

/// [`ReconstructError::Undersampled`] with a fix that can work (module docs); `levels` is
/// `None` for an active set given by the caller.
pub(super) fn undersampled(
    samples: usize,
    functions: usize,
    p: usize,
    fine: u32,
    levels: Option<&Levels>,
) -> ReconstructError {
    let level = minimum_level(p);
    let fix = if fine <= level {
        UndersampledFix::SmallestBasis {
            functions,
            p,
            level,
            haar_functions: (p > 1).then(|| crate::resources::dimension(minimum_level(1)) as usize),
        }
    } else {
        match levels {
            Some(Levels::Auto(lp)) => UndersampledFix::AutoLevels {
                functions,
                rho: lp.rho,
            },
            Some(Levels::Fixed { .. }) => UndersampledFix::FixedLevels {
                functions,
                p,
                level,
            },
            None => UndersampledFix::ActiveSet { functions },
        }
    };
    ReconstructError::Undersampled {
        samples,
        functions,
        fix,
    }
}
