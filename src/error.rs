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

/// A change that can make a refused request work, named as data: the library's messages
/// write each [`Fix`] through [`std::fmt::Display`], which spells it in the terms of whoever
/// reads the message — by default the library's own (`LevelParams::rho`); the command line
/// and the Python module install their spelling (`--rho`, `rho=`) with [`spelled`] while
/// they format an error, so no front end rewrites message text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Fix {
    /// Accept a regularized answer to an undetermined global least squares (a ridge on the
    /// singular directions, or CGLS's minimum-norm answer).
    RegularizedAnswer,
    /// Accept a regularized answer to a rank-deficient global least squares, or the local
    /// inversion, which cuts the unsupported directions.
    RegularizeOrLocal,
    /// The relative singular-value cut-off of the pseudo-inverse.
    Cutoff,
    /// Fixed levels: the fine level `N` chosen by the caller.
    FixedLevels,
    /// Automatic levels, chosen from the samples.
    AutoLevels,
    /// The oversampling rate `rho = m / P` of the automatic levels.
    Rho,
    /// The 1D refiner's samples per leaf `rho`.
    RefineRho,
    /// The single-scale global least squares (banded normal equations, then the FWT).
    MethodSingleScale,
    /// The local inversion.
    MethodLocal,
    /// The global sparse least squares on the multilevel kernel matrix.
    MethodGlobal,
    /// The dense SVD pseudo-inverse.
    MethodDense,
    /// Column-pivoted QR for the local blocks.
    SolverQr,
    /// Drop non-finite samples and count them instead of refusing the set.
    DropNonfinite,
}

impl Fix {
    /// Every fix, so a front end can check that it spells each one.
    pub const ALL: [Fix; 13] = [
        Fix::RegularizedAnswer,
        Fix::RegularizeOrLocal,
        Fix::Cutoff,
        Fix::FixedLevels,
        Fix::AutoLevels,
        Fix::Rho,
        Fix::RefineRho,
        Fix::MethodSingleScale,
        Fix::MethodLocal,
        Fix::MethodGlobal,
        Fix::MethodDense,
        Fix::SolverQr,
        Fix::DropNonfinite,
    ];

    /// The fix in the library's terms: the parameter to set and its value.
    pub fn in_library(self) -> &'static str {
        match self {
            Fix::RegularizedAnswer => {
                "GlobalLsParams::rank_policy = RankPolicy::Regularize (ridge \
                 GlobalLsParams::ridge, e.g. 1e-10) or GlobalLsParams::method = \
                 GlobalMethod::Cgls"
            }
            Fix::RegularizeOrLocal => {
                "GlobalLsParams::rank_policy = RankPolicy::Regularize, or the local inversion"
            }
            Fix::Cutoff => "`cutoff` of LocalInversionParams or Method::Dense",
            Fix::FixedLevels => "Levels::Fixed { fine, .. }",
            Fix::AutoLevels => "Levels::Auto",
            Fix::Rho => "LevelParams::rho",
            Fix::RefineRho => "RefineParams::rho",
            Fix::MethodSingleScale => "Method::SingleScale",
            Fix::MethodLocal => "Method::Local",
            Fix::MethodGlobal => "Method::Global",
            Fix::MethodDense => "Method::Dense",
            Fix::SolverQr => "Solver::Qr",
            Fix::DropNonfinite => "NonFinitePolicy::Drop",
        }
    }
}

/// How a front end spells each [`Fix`] ([`Fix::in_library`] is the library's).
pub type Spelling = fn(Fix) -> &'static str;

thread_local! {
    /// The spelling [`Fix`]'s `Display` uses on this thread.
    static SPELLING: std::cell::Cell<Spelling> = const { std::cell::Cell::new(Fix::in_library) };
}

/// Runs `format` (typically `|| error.to_string()`) with every [`Fix`] written in
/// `spelling`, on this thread only; the previous spelling is restored afterwards, also when
/// `format` panics.
pub fn spelled<R>(spelling: Spelling, format: impl FnOnce() -> R) -> R {
    struct Restore(Spelling);
    impl Drop for Restore {
        fn drop(&mut self) {
            SPELLING.with(|s| s.set(self.0));
        }
    }
    let _restore = Restore(SPELLING.with(|s| s.replace(spelling)));
    format()
}

impl std::fmt::Display for Fix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(SPELLING.with(|s| s.get())(*self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn upper(fix: Fix) -> &'static str {
        match fix {
            Fix::Rho => "RHO",
            _ => "OTHER",
        }
    }

    /// A fix reads in the library's terms, in the spelling given inside [`spelled`], and in
    /// the library's terms again afterwards, also after a panic inside.
    #[test]
    fn spelling_is_scoped() {
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
        assert_eq!(spelled(upper, || Fix::Rho.to_string()), "RHO");
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
        let nested = spelled(upper, || {
            let inner = spelled(Fix::in_library, || Fix::Rho.to_string());
            (inner, Fix::Rho.to_string())
        });
        assert_eq!(nested, ("LevelParams::rho".to_string(), "RHO".to_string()));
        let panicked = std::panic::catch_unwind(|| spelled(upper, || panic!("inside")));
        assert!(panicked.is_err());
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
    }

    /// Errors that advise a fix write it through the spelling.
    #[test]
    fn errors_spell_their_fixes() {
        let e = crate::solve::SolveError::TooLarge {
            rows: 10,
            cols: 5,
            limit: 4,
        };
        let library = e.to_string();
        assert!(
            library.contains("Method::Global or Method::SingleScale"),
            "{library}"
        );
        let other = spelled(upper, || e.to_string());
        assert!(other.contains("(OTHER or OTHER)"), "{other}");
        for fix in Fix::ALL {
            assert!(!fix.in_library().is_empty());
        }
    }
}
