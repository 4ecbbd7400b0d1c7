//! The errors of basis construction and evaluation.

use thiserror::Error;

/// Errors of basis construction and evaluation: each names the value at fault and the fix.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum BasisError {
    /// `p` outside the supported range.
    #[error("p = {p} vanishing moments is not supported: choose p in 1..={max}")]
    UnsupportedOrder {
        /// Requested `p`.
        p: usize,
        /// Largest supported `p`.
        max: usize,
    },
    /// `coarse > fine`.
    #[error(
        "coarse level n = {coarse} is above the finest wavelet level N = {fine}: choose n <= N"
    )]
    CoarseAboveFine {
        /// Coarse level `n`.
        coarse: u32,
        /// Finest wavelet level `N`.
        fine: u32,
    },
    /// The coarse level is too small for `p` (edge blocks would overlap).
    #[error(
        "coarse level n = {coarse} is too small for p = {p}: the left and right edge functions \
         overlap below level {minimum}; choose n >= {minimum}"
    )]
    CoarseLevelTooSmall {
        /// Vanishing moments.
        p: usize,
        /// Requested coarse level.
        coarse: u32,
        /// `j_min(p)`.
        minimum: u32,
    },
    /// The fine level is beyond what `f64` positions resolve.
    #[error("fine level N = {fine} is too deep: choose N <= {max}")]
    FineLevelTooDeep {
        /// Requested level.
        fine: u32,
        /// Maximum level.
        max: u32,
    },
    /// A position outside the domain or not finite.
    #[error(
        "position {} is outside the domain [{}, {}] (or not finite): give positions within \
         the domain",
        crate::norms::show(*.x),
        crate::norms::show(*.a),
        crate::norms::show(*.b)
    )]
    PositionOutside {
        /// The position.
        x: f64,
        /// Left end.
        a: f64,
        /// Right end.
        b: f64,
    },
    /// A numerical step of the construction failed (an internal error).
    #[error("CDV construction failed at {step}: {detail}")]
    Construction {
        /// The step.
        step: &'static str,
        /// What went wrong.
        detail: String,
    },
}

impl BasisError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            BasisError::UnsupportedOrder { .. }
            | BasisError::CoarseAboveFine { .. }
            | BasisError::CoarseLevelTooSmall { .. }
            | BasisError::FineLevelTooDeep { .. }
            | BasisError::PositionOutside { .. } => crate::error::ErrorKind::InvalidInput,
            BasisError::Construction { .. } => crate::error::ErrorKind::Internal,
        }
    }
}

crate::error::classified!(BasisError);
