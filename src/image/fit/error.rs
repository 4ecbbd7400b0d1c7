//! The errors of the image fit.

use thiserror::Error;

use crate::basis::tensor::TensorError;
use crate::solve::cholesky::CholeskyError;
use crate::solve::SolveError;

/// Errors of the image fit: each names the value at fault and the way out.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ImageFitError {
    /// The basis (resolution, levels, positions).
    #[error(transparent)]
    Tensor(#[from] TensorError),
    /// Sample `index` (0-based) lies outside the image.
    #[error(
        "sample {index} at ({x}, {y}) is outside the image [0, {width}] x [0, {height}] (or not \
         finite): give positions in pixel units within the image"
    )]
    SampleOutside {
        /// 0-based sample index.
        index: usize,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// Width.
        width: usize,
        /// Height.
        height: usize,
    },
    /// Positions and values disagree in length.
    #[error("{what} has {found} entries for {expected} samples: give one value per sample")]
    LengthMismatch {
        /// Which input (`"ys"`, `"channel 2"`, ...).
        what: String,
        /// Samples.
        expected: usize,
        /// Found.
        found: usize,
    },
    /// No channel given, or no sample.
    #[error("no {what} given: give at least one sample with at least one channel")]
    Empty {
        /// `"samples"` or `"channels"`.
        what: &'static str,
    },
    /// A value is NaN or infinite.
    #[error("sample {index}, channel {channel}: value {value} is not finite: fix or drop it")]
    NonFiniteValue {
        /// 0-based sample.
        index: usize,
        /// 0-based channel.
        channel: usize,
        /// The value.
        value: f64,
    },
    /// The sparse Cholesky factorization of the normal matrix failed.
    #[error("the 2D normal equations could not be solved: {0}")]
    Factor(#[from] CholeskyError),
    /// A solve returned non-finite coefficients (an internal error).
    #[error(
        "the 2D normal equations could not be solved: channel {channel} has non-finite \
         coefficients (an internal error: please report)"
    )]
    NonFiniteCoefficients {
        /// 0-based channel.
        channel: usize,
    },
    /// A smoothing penalty with `p = 1` (Haar functions do not overlap) or not finite.
    #[error(
        "smoothing {smoothing} with p = {p}: the first-difference penalty needs p >= 2 and a \
         finite weight >= 0; use p >= 2 or smoothing 0"
    )]
    Smoothing {
        /// The weight given.
        smoothing: f64,
        /// Vanishing moments.
        p: usize,
    },
    /// Local inversion (preconditioner) failed.
    #[error(transparent)]
    Local(#[from] SolveError),
}

impl ImageFitError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ImageFitError::Tensor(e) => e.kind(),
            ImageFitError::SampleOutside { .. }
            | ImageFitError::LengthMismatch { .. }
            | ImageFitError::Empty { .. }
            | ImageFitError::NonFiniteValue { .. }
            | ImageFitError::Smoothing { .. } => crate::error::ErrorKind::InvalidInput,
            ImageFitError::Factor(e) => e.kind(),
            ImageFitError::NonFiniteCoefficients { .. } => crate::error::ErrorKind::Numerical,
            ImageFitError::Local(e) => e.kind(),
        }
    }
}

crate::error::classified!(ImageFitError);
