//! The error policy's shared classification: every public error enum of the crate has a
//! `kind()` returning an [`ErrorKind`], so a caller (the command line among them) decides
//! what to do by kind (retry with other parameters, more samples, a larger memory limit;
//! report a bug) without reading message text.
//!
//! The kinds, and the exit code the `rkwave` binary gives each: 2 when the caller can fix
//! the request, 1 when the machine failed.
//!
//! | kind | meaning | exit |
//! |---|---|---|
//! | [`ErrorKind::InvalidInput`] | a parameter, position, value or file content out of range | 2 |
//! | [`ErrorKind::Undetermined`] | the samples cannot determine the basis asked for | 2 |
//! | [`ErrorKind::ResourceLimit`] | refused before allocating: the memory limit or a size bound | 2 |
//! | [`ErrorKind::NotConverged`] | an iterative solve stopped at its iteration limit | 2 |
//! | [`ErrorKind::Numerical`] | the arithmetic broke down on these data (overflow, a failed factorization) | 2 |
//! | [`ErrorKind::Unreadable`] | an input file could not be opened or read | 2 |
//! | [`ErrorKind::OutputRefused`] | an output that must not be written (it exists, it is an input, its folder refuses files) | 2 |
//! | [`ErrorKind::WriteFailed`] | writing, drawing or encoding an output failed after the checks | 1 |
//! | [`ErrorKind::Internal`] | a broken internal contract: a bug to report | 1 |
//!
//! A wrapping variant (`#[error(transparent)]`) has the kind of the error it wraps. The
//! `kind()` of each enum is written out below, variant by variant, so a new variant does not
//! compile until it is classified.

use serde::Serialize;

use crate::basis::tensor::TensorError;
use crate::basis::BasisError;
use crate::domain::DomainError;
use crate::image::adaptive::protocol::ProtocolError;
use crate::image::adaptive::AdaptiveError;
use crate::image::estimate::EstimateError;
use crate::image::pixels::PixelError;
use crate::image::scene::SceneError;
use crate::image::{ImageError, ImageFitError, WaveletError};
use crate::io::image_file::ImageFileError;
use crate::io::output::OutputError;
use crate::io::IoError;
use crate::kernel::KernelError;
use crate::reconstruct::ReconstructError;
use crate::refine::RefineError;
use crate::report::scaling::ScalingError;
use crate::resources::ResourceError;
use crate::solve::cholesky::CholeskyError;
use crate::solve::SolveError;

use ErrorKind::{
    InvalidInput, NotConverged, Numerical, OutputRefused, ResourceLimit, Undetermined, Unreadable,
    WriteFailed,
};

/// What kind of failure an error is (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A parameter, a position, a value or a file's content is not what the library accepts.
    InvalidInput,
    /// The samples cannot determine the basis asked for (too few, or not where the functions
    /// live): more samples, fewer functions, or a regularized answer.
    Undetermined,
    /// Refused before allocating: the memory limit or a size bound.
    ResourceLimit,
    /// An iterative solve stopped at its iteration limit before reaching its tolerance.
    NotConverged,
    /// The arithmetic broke down on these data: an overflow or a factorization that failed.
    Numerical,
    /// An input file (samples, a scene, a plan's state) could not be opened or read.
    Unreadable,
    /// An output that must not be written: it exists and overwriting is not allowed, it is
    /// one of the inputs, or its folder refuses new files (checked before computing).
    OutputRefused,
    /// Writing, drawing or encoding an output failed after the checks passed.
    WriteFailed,
    /// A broken internal contract: a bug to report.
    Internal,
}

impl ErrorKind {
    /// Whether the caller can fix the failure by changing the request (every kind but
    /// [`ErrorKind::WriteFailed`] and [`ErrorKind::Internal`]).
    pub fn is_caller_fixable(self) -> bool {
        !matches!(self, ErrorKind::WriteFailed | ErrorKind::Internal)
    }
}

impl BasisError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            BasisError::UnsupportedOrder { .. }
            | BasisError::CoarseAboveFine { .. }
            | BasisError::CoarseLevelTooSmall { .. }
            | BasisError::FineLevelTooDeep { .. }
            | BasisError::PositionOutside { .. } => InvalidInput,
            BasisError::Construction { .. } => ErrorKind::Internal,
        }
    }
}

impl TensorError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            TensorError::ZeroResolution { .. }
            | TensorError::LevelOutOfRange { .. }
            | TensorError::PositionOutside { .. } => InvalidInput,
            TensorError::Basis(e) => e.kind(),
        }
    }
}

impl DomainError {
    /// The kind of this error ([`crate::error`]): always [`ErrorKind::InvalidInput`].
    pub fn kind(&self) -> ErrorKind {
        match self {
            DomainError::NotFinite { .. }
            | DomainError::NotIncreasing { .. }
            | DomainError::TooWide { .. }
            | DomainError::TooNarrow { .. }
            | DomainError::Parse { .. } => InvalidInput,
        }
    }
}

impl KernelError {
    /// The kind of this error ([`crate::error`]): always [`ErrorKind::InvalidInput`].
    pub fn kind(&self) -> ErrorKind {
        match self {
            KernelError::PositionOutside { .. } | KernelError::Empty => InvalidInput,
        }
    }
}

impl ResourceError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ResourceError::TooLarge { .. } => ResourceLimit,
            ResourceError::BadLimit { .. } => InvalidInput,
        }
    }
}

impl CholeskyError {
    /// The kind of this error ([`crate::error`]): a failed factorization is numerical.
    pub fn kind(&self) -> ErrorKind {
        match self {
            CholeskyError::Symbolic { .. } | CholeskyError::NotPositive { .. } => Numerical,
        }
    }
}

impl SolveError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            SolveError::Undersampled { .. } | SolveError::RankDeficient { .. } => Undetermined,
            SolveError::Resources(e) => e.kind(),
            SolveError::Factorization { .. }
            | SolveError::DenseSvd { .. }
            | SolveError::NonFiniteOutput { .. } => Numerical,
            SolveError::DimensionMismatch { .. }
            | SolveError::InvalidParameter { .. }
            | SolveError::NonFiniteInput { .. } => InvalidInput,
            SolveError::TooLarge { .. } => ResourceLimit,
            SolveError::NotConverged { .. } => NotConverged,
        }
    }
}

impl ReconstructError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ReconstructError::Basis(e) => e.kind(),
            ReconstructError::Kernel(e) => e.kind(),
            ReconstructError::Solve(e) => e.kind(),
            ReconstructError::Undersampled { .. } => Undetermined,
            ReconstructError::Resources(e) => e.kind(),
            ReconstructError::NonFiniteValue { .. } | ReconstructError::LengthMismatch { .. } => {
                InvalidInput
            }
        }
    }
}

impl ScalingError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ScalingError::GridTooSmall { .. } => InvalidInput,
            ScalingError::Reconstruct(e) => e.kind(),
        }
    }
}

impl RefineError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            RefineError::InvalidParameter { .. }
            | RefineError::MaxDepthBelowBase { .. }
            | RefineError::BudgetBelowBase { .. }
            | RefineError::NonFiniteValue { .. }
            | RefineError::Unresolvable { .. } => InvalidInput,
            RefineError::RankDeficient { .. } => Undetermined,
            RefineError::Basis(e) => e.kind(),
            RefineError::Kernel(e) => e.kind(),
            RefineError::Solve(e) => e.kind(),
            RefineError::Reconstruct(e) => e.kind(),
        }
    }
}

impl OutputError {
    /// The kind of this error ([`crate::error`]): always [`ErrorKind::OutputRefused`].
    pub fn kind(&self) -> ErrorKind {
        match self {
            OutputError::Exists { .. }
            | OutputError::Appeared { .. }
            | OutputError::SameFile { .. }
            | OutputError::NotWritable { .. } => OutputRefused,
        }
    }
}

impl IoError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            IoError::Read { .. } => Unreadable,
            IoError::Write { .. } => WriteFailed,
            IoError::NotUtf8 { .. }
            | IoError::Empty { .. }
            | IoError::MissingHeader { .. }
            | IoError::BadHeader { .. }
            | IoError::ColumnCount { .. }
            | IoError::NotANumber { .. }
            | IoError::NonFinite { .. }
            | IoError::BadMagic { .. }
            | IoError::UnsupportedVersion { .. }
            | IoError::BadNpyHeader { .. }
            | IoError::UnsupportedDtype { .. }
            | IoError::Truncated { .. }
            | IoError::ShapeMismatch { .. }
            | IoError::OutOfDomain { .. }
            | IoError::InvalidSampleSet { .. }
            | IoError::ImageColumns { .. } => InvalidInput,
            IoError::ImageSamples { source, .. } => source.kind(),
        }
    }
}

impl ImageFileError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ImageFileError::UnknownFormat { .. } => InvalidInput,
            ImageFileError::Write { .. } => WriteFailed,
            ImageFileError::Output(e) => e.kind(),
        }
    }
}

impl ImageError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ImageError::AbsurdResolution { .. } => ResourceLimit,
            ImageError::EmptyResolution { .. }
            | ImageError::ParseResolution { .. }
            | ImageError::PositionLengths { .. }
            | ImageError::ChannelCount { .. }
            | ImageError::ChannelLength { .. }
            | ImageError::OutsideImage { .. }
            | ImageError::NonFiniteValue { .. }
            | ImageError::NonFiniteSamples { .. } => InvalidInput,
        }
    }
}

impl ImageFitError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ImageFitError::Tensor(e) => e.kind(),
            ImageFitError::SampleOutside { .. }
            | ImageFitError::LengthMismatch { .. }
            | ImageFitError::Empty { .. }
            | ImageFitError::NonFiniteValue { .. }
            | ImageFitError::Smoothing { .. } => InvalidInput,
            ImageFitError::Factor(e) => e.kind(),
            ImageFitError::NonFiniteCoefficients { .. } => Numerical,
            ImageFitError::Local(e) => e.kind(),
        }
    }
}

impl PixelError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            PixelError::Basis(e) => e.kind(),
            PixelError::DomainMismatch { .. }
            | PixelError::NoPixels
            | PixelError::CoefficientLength { .. }
            | PixelError::VanishingWeight { .. }
            | PixelError::SubCell { .. }
            | PixelError::PixelOutside { .. }
            | PixelError::SampleLengths { .. }
            | PixelError::SampleOutside { .. } => InvalidInput,
        }
    }
}

impl WaveletError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            WaveletError::Fit(e) => e.kind(),
            WaveletError::Pixels(e) => e.kind(),
            WaveletError::Solve(e) => e.kind(),
            WaveletError::PixelOutside { .. } => InvalidInput,
        }
    }
}

impl EstimateError {
    /// The kind of this error ([`crate::error`]): a failed fit keeps its own; pixels without
    /// the samples an estimate needs are undetermined.
    pub fn kind(&self) -> ErrorKind {
        match self {
            EstimateError::Wavelet(e) => e.kind(),
            EstimateError::EmptyPixels { .. } | EstimateError::NoSpread => Undetermined,
        }
    }
}

impl SceneError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            SceneError::Read { .. } | SceneError::Image { .. } => Unreadable,
            SceneError::Json { .. }
            | SceneError::BadField { .. }
            | SceneError::UnknownShape { .. } => InvalidInput,
        }
    }
}

impl AdaptiveError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            AdaptiveError::Parameter { .. }
            | AdaptiveError::BudgetTooSmall { .. }
            | AdaptiveError::History { .. } => InvalidInput,
            AdaptiveError::Tensor(e) => e.kind(),
            AdaptiveError::Samples(e) => e.kind(),
            AdaptiveError::Solve(e) => e.kind(),
            AdaptiveError::Pixels(e) => e.kind(),
            AdaptiveError::Resource(e) => e.kind(),
        }
    }
}

impl ProtocolError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            ProtocolError::Adaptive(e) => e.kind(),
            ProtocolError::Plane { .. }
            | ProtocolError::Mismatch { .. }
            | ProtocolError::Channels { .. }
            | ProtocolError::OtherParameters { .. }
            | ProtocolError::State { .. } => InvalidInput,
            ProtocolError::AlreadyPlanned { .. } => OutputRefused,
            ProtocolError::Read { .. } => Unreadable,
            ProtocolError::Write(e) => e.kind(),
        }
    }
}

#[cfg(feature = "plot")]
mod lab_kinds {
    use super::ErrorKind;
    use crate::lab::adaptive::AdaptiveRunError;
    use crate::lab::experiment::ImageRunError;
    use crate::plot::PlotError;

    impl PlotError {
        /// The kind of this error ([`crate::error`]).
        pub fn kind(&self) -> ErrorKind {
            match self {
                PlotError::Draw { .. } | PlotError::Write { .. } => ErrorKind::WriteFailed,
                PlotError::Output(e) => e.kind(),
            }
        }
    }

    impl ImageRunError {
        /// The kind of this error ([`crate::error`]).
        pub fn kind(&self) -> ErrorKind {
            match self {
                ImageRunError::Image(e) => e.kind(),
                ImageRunError::Parameter { .. } => ErrorKind::InvalidInput,
                ImageRunError::Wavelet(e) => e.kind(),
            }
        }
    }

    impl AdaptiveRunError {
        /// The kind of this error ([`crate::error`]).
        pub fn kind(&self) -> ErrorKind {
            match self {
                AdaptiveRunError::Adaptive(e) => e.kind(),
                AdaptiveRunError::Run(e) => e.kind(),
                AdaptiveRunError::Image(e) => e.kind(),
            }
        }
    }
}

pub(crate) mod fix;
pub use fix::{spelled, Fix, Spelling};
