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
//! A wrapping variant (`#[error(transparent)]`) has the kind of the error it wraps. Each
//! enum's `kind()` is written beside its definition, variant by variant, so a new variant
//! does not compile until it is classified; this module holds only the kinds and the typed
//! fixes (`fix`), and depends on no other module of the crate (a leaf).

use serde::Serialize;

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

/// An error the library classifies: its [`ErrorKind`], so a front end maps every error the
/// same way (an exit code, an exception class) without a list of the library's error types.
/// Each error enum implements it beside its definition, from its own `kind()`.
pub trait Classified: std::error::Error {
    /// The kind of this error.
    fn kind(&self) -> ErrorKind;
}

/// `impl Classified for $t` from `$t`'s own `kind()` (written beside each error enum).
macro_rules! classified {
    ($t:ty) => {
        impl $crate::error::Classified for $t {
            fn kind(&self) -> $crate::error::ErrorKind {
                <$t>::kind(self)
            }
        }
    };
}
pub(crate) use classified;

pub(crate) mod fix;
pub use fix::{spelled, Fix, Param, Spelling};
