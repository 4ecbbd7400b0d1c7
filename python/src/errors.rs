//! The library's errors as Python exceptions, by their [`ErrorKind`] (the engine's error
//! policy, `src/error.rs`), and its warnings through Python's `warnings`.
//!
//! | kind | Python exception |
//! |---|---|
//! | `InvalidInput`, `Undetermined`, `NotConverged`, `Numerical`, `Unreadable`, `OutputRefused` | [`RkwaveError`] (a `ValueError`) |
//! | `ResourceLimit` | [`ResourceLimitError`] (a `MemoryError`) |
//! | `WriteFailed` | `OSError` |
//! | `Internal` | `RuntimeError` (a bug to report) |
//!
//! The message is the library's, as the command line prints it after `error:`, except that
//! each fix it advises ([`Fix`], typed data in the library's errors) is spelled as this
//! module's keyword argument (`rho=`, [`keyword`]) where the command line spells its flag;
//! no message text is rewritten.

use std::ffi::CString;

use pyo3::create_exception;
use pyo3::exceptions::{PyMemoryError, PyOSError, PyRuntimeError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use rkwave::error::{spelled, Classified, ErrorKind, Fix, Param};

create_exception!(
    rkwave,
    RkwaveError,
    PyValueError,
    "A request rkwave refuses: bad input, samples that cannot determine the basis, a solve \
     that failed on these data. The message names the problem and the fix; `kind` is the \
     library's error kind (e.g. 'InvalidInput')."
);
create_exception!(
    rkwave,
    ResourceLimitError,
    PyMemoryError,
    "A request refused before allocating: it would need more memory than the limit."
);
create_exception!(
    rkwave,
    RkwaveWarning,
    PyUserWarning,
    "A fallback or warning of a fit (a lowered level, another solver, a barely supported \
     block); the same text the command line prints after `warning:` or `note:`."
);

/// `fix` as this module's callers spell it: the keyword argument that sets the parameter,
/// or the call that gets the same effect.
pub fn keyword(fix: Fix) -> &'static str {
    match fix {
        Fix::RegularizedAnswer => {
            "method=\"single\" (it sets the undetermined directions to zero and reports them)"
        }
        Fix::RegularizeOrLocal => "method=\"single\", or the local inversion",
        Fix::Cutoff => "cutoff=",
        Fix::FixedLevels => "levels=(n, N)",
        Fix::AutoLevels => "levels=\"auto\"",
        Fix::Rho | Fix::RefineRho => "rho=",
        Fix::MethodSingleScale => "method=\"single\"",
        Fix::MethodLocal => "method=\"local\"",
        Fix::MethodGlobal => "method=\"global\"",
        Fix::MethodDense => "method=\"dense\"",
        Fix::SolverQr => "solver=\"qr\"",
        Fix::DropNonfinite => "drop_nonfinite=True",
        Fix::PixelsAuto => "pixels=\"auto\"",
        Fix::SolverPcg => "solver=\"pcg\"",
        Fix::Set(param) => match param {
            Param::P => "p=",
            Param::Rho => "rho=",
            Param::Ridge => "ridge=",
            Param::Smoothing => "smoothing=",
            Param::Method => "method=",
            Param::Pixels => "pixels=",
            Param::Resolution => "resolution=",
            Param::Tile => "tile=",
            Param::Halo => "halo=",
            Param::Workers => "workers=",
            Param::State => "the Plan",
            Param::NoResidual => "no_residual=True",
            Param::Overwrite => "overwrite=True",
            Param::Budget => "budget=",
            Param::BelowPixel => "below_pixel=",
            Param::MemoryLimit => "rkwave.set_memory_limit()",
            Param::Scratch => "scratch=",
            Param::PixelShare => "pixel_share=",
            _ => param.in_library(),
        },
        _ => fix.in_library(),
    }
}

/// The Python exception of a failure of `kind` with `message` (module docs).
pub fn raise(kind: ErrorKind, message: &str) -> PyErr {
    let message = message.to_string();
    match kind {
        ErrorKind::ResourceLimit => ResourceLimitError::new_err(message),
        ErrorKind::WriteFailed => PyOSError::new_err(message),
        ErrorKind::Internal => {
            PyRuntimeError::new_err(format!("internal error, please report: {message}"))
        }
        kind => {
            let err = RkwaveError::new_err(message);
            Python::attach(|py| {
                // The kind's name as the library spells it; setting an attribute on a fresh
                // exception cannot fail short of memory exhaustion.
                let _ = err.value(py).setattr("kind", format!("{kind:?}"));
            });
            err
        }
    }
}

/// A user error ([`ErrorKind::InvalidInput`]) with `message`.
pub fn invalid(message: impl Into<String>) -> PyErr {
    raise(ErrorKind::InvalidInput, &message.into())
}

/// The Python exception of a library error: any error the library classifies
/// ([`Classified`]), mapped by its kind alone (no list of the library's error types).
pub fn to_py<E: Classified>(e: E) -> PyErr {
    raise(e.kind(), &spelled(keyword, || e.to_string()))
}

/// Issues every message in `notes` as an [`RkwaveWarning`] (stack level 1: the line that called rkwave).
pub fn warn_all(py: Python<'_>, notes: &[String]) -> PyResult<()> {
    let category = py.get_type::<RkwaveWarning>();
    for note in notes {
        let text = CString::new(note.replace('\0', " ")).expect("NUL bytes were replaced");
        PyErr::warn(py, &category, &text, 1)?;
    }
    Ok(())
}
