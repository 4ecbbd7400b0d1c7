//! Why an image-plane job refused or failed, with the messages that name the parameter at
//! fault, and the range checks that make them.

use std::fmt;

use thiserror::Error;

use crate::error::{ErrorKind, Fix, Param};
use crate::image::estimate::EstimateError;
use crate::image::plan::ProtocolError;
use crate::image::tiles::TiledError;
use crate::image::{ImageMethod, ImagePlane, UniformEstimate, WaveletError};
use crate::resources::ResourceError;

/// Why an image-plane job refused or failed. Each variant names the parameter at fault as
/// data ([`Param`]), so each front end names it in its own terms.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum JobError {
    /// A parameter outside its range.
    #[error("{}{value}{rule}", named(*param))]
    OutOfRange {
        /// The parameter.
        param: Param,
        /// Its value as given.
        value: String,
        /// The rule, starting with its own separator (`" must be in [0, 1)"`).
        rule: &'static str,
    },
    /// Two parameters that ask for different things.
    #[error("{} {reason}: drop {} or {}", Fix::Set(*first), Fix::Set(*first), Fix::Set(*second))]
    Conflict {
        /// The parameter named first.
        first: Param,
        /// The other.
        second: Param,
        /// Why they conflict.
        reason: &'static str,
    },
    /// The request would need more memory than the limit: refused before allocating.
    #[error(
        "reconstructing {samples} samples onto {plane} pixels by {by} ({parts}) would need \
         about {} of memory, above the limit of {}: a smaller {}, fewer samples, or {} / a \
         lower {} (or raise the memory limit)",
        crate::resources::format_bytes(*needed),
        crate::resources::format_bytes(*limit as f64),
        Fix::Set(Param::Resolution),
        Fix::MethodLocal,
        Fix::Set(Param::P)
    )]
    TooLarge {
        /// Samples of the request.
        samples: usize,
        /// The image.
        plane: ImagePlane,
        /// What the pixels were to be made by.
        by: By,
        /// The estimate's parts, in words.
        parts: String,
        /// Estimated bytes.
        needed: f64,
        /// The limit in bytes.
        limit: u64,
    },
    /// A parameter the request needs and lacks.
    #[error("{what}: set {} {how}", Fix::Set(*param))]
    Missing {
        /// The parameter.
        param: Param,
        /// What needs it.
        what: &'static str,
        /// The other ways to give it, in words.
        how: &'static str,
    },
    /// An image size other than the plan's.
    #[error(
        "{}{given}: the plan is for {plan}; drop {} or give the plan's",
        named(Param::Resolution),
        Fix::Set(Param::Resolution)
    )]
    OtherPlane {
        /// The size given.
        given: ImagePlane,
        /// The plan's.
        plan: ImagePlane,
    },
    /// A plan that would need more memory than the limit: refused before allocating.
    #[error("{}", too_large(*plane, *budget, *functions, parts, *needed, *limit))]
    PlanTooLarge {
        /// The image.
        plane: ImagePlane,
        /// The sample budget.
        budget: usize,
        /// Functions of the basis at the depth limit.
        functions: f64,
        /// The estimate's parts, in words.
        parts: String,
        /// Estimated bytes.
        needed: f64,
        /// The limit in bytes.
        limit: u64,
    },
    /// The plan's state machine refused the call (samples of another plan, parameters
    /// other than the plan's, the refiner's ranges, the fit).
    #[error(transparent)]
    Plan(#[from] ProtocolError),
    /// A tiled fit asked to drop non-finite samples.
    #[error("{}", keeps_nonfinite())]
    TilesKeepNonFinite,
    /// A halo given without tiles.
    #[error(
        "{} is the halo of the tiles of a tiled plan: set {} with it, or drop {}",
        Fix::Set(Param::Halo),
        Fix::Set(Param::Tile),
        Fix::Set(Param::Halo)
    )]
    HaloWithoutTiles,
    /// A round of a tiled plan asked to drop non-finite samples.
    #[error("{}", plan_keeps_nonfinite())]
    TiledPlanKeepsNonFinite,
    /// A tile grid refused (its size, its halo).
    #[error("{}: {source}", Fix::Set(*param))]
    TileGrid {
        /// The parameter at fault.
        param: Param,
        /// Why.
        source: TiledError,
    },
    /// The tiled fit failed (reading the samples, a tile's fit, the memory).
    #[error(transparent)]
    Tiled(TiledError),
    /// A memory limit that cannot be read ([`ResourceError::BadLimit`]).
    #[error(transparent)]
    Resources(ResourceError),
    /// The pixel estimate failed (too few samples for it, or its fit failed).
    #[error(transparent)]
    Estimate(#[from] EstimateError),
    /// The fit or the film failed.
    #[error(transparent)]
    Wavelet(#[from] WaveletError),
}

impl JobError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> ErrorKind {
        match self {
            JobError::OutOfRange { .. }
            | JobError::Conflict { .. }
            | JobError::Missing { .. }
            | JobError::OtherPlane { .. }
            | JobError::TilesKeepNonFinite
            | JobError::HaloWithoutTiles
            | JobError::TiledPlanKeepsNonFinite => ErrorKind::InvalidInput,
            JobError::TileGrid { source, .. } | JobError::Tiled(source) => source.kind(),
            JobError::TooLarge { .. } | JobError::PlanTooLarge { .. } => ErrorKind::ResourceLimit,
            JobError::Plan(e) => e.kind(),
            JobError::Resources(e) => e.kind(),
            JobError::Estimate(e) => e.kind(),
            JobError::Wavelet(e) => e.kind(),
        }
    }
}

crate::error::classified!(JobError);

/// What a job's pixels are made by, for its messages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum By {
    /// A method's own reconstruction (the fit, its local inversion, a film).
    Method(ImageMethod),
    /// A pixel estimate that uses no fit.
    Estimate(UniformEstimate),
}

impl fmt::Display for By {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            By::Method(m) => write!(f, "{m}"),
            By::Estimate(e) => write!(f, "{}{e}", named(Param::Pixels)),
        }
    }
}

/// `param` as the reader spells it, then the separator before its value: none after a
/// keyword's `=` (`rho=0`), a space otherwise (`--rho 0`).
fn named(param: Param) -> String {
    let name = Fix::Set(param).to_string();
    if name.ends_with('=') {
        name
    } else {
        name + " "
    }
}

/// `value` if `ok`, else [`JobError::OutOfRange`] for `param`.
pub(super) fn in_range<T: fmt::Display>(
    param: Param,
    value: T,
    ok: bool,
    rule: &'static str,
) -> Result<T, JobError> {
    if ok {
        Ok(value)
    } else {
        Err(JobError::OutOfRange {
            param,
            value: value.to_string(),
            rule,
        })
    }
}

/// Checks the image basis's vanishing moments `p` (1 to 4).
pub fn check_p(p: usize) -> Result<usize, JobError> {
    in_range(
        Param::P,
        p,
        (1..=4).contains(&p),
        ": the image plane supports p = 1 to 4 (2 or 3 are practical)",
    )
}

/// The message of [`JobError::PlanTooLarge`].
fn too_large(
    plane: ImagePlane,
    budget: usize,
    functions: f64,
    parts: &str,
    needed: f64,
    limit: u64,
) -> String {
    format!(
        "a plan of {budget} samples on {plane} pixels (a basis of {functions:.0} functions at \
         its depth limit) would need about {} of memory ({parts}; counted for one channel of \
         samples, a lower bound: each further channel needs more), above the limit of {}: a \
         smaller {}, a lower {} or a smaller {} (or raise the memory limit)",
        crate::resources::format_bytes(needed),
        crate::resources::format_bytes(limit as f64),
        Fix::Set(Param::Budget),
        Fix::Set(Param::BelowPixel),
        Fix::Set(Param::Resolution)
    )
}

/// The message of [`JobError::TilesKeepNonFinite`].
fn keeps_nonfinite() -> String {
    format!(
        "the tiled fit reads the samples in chunks and refuses non-finite values: do not ask \
         for {} with {} (remove them from the file instead)",
        Fix::DropNonfinite,
        Fix::Set(Param::Tile)
    )
}

/// The message of [`JobError::TiledPlanKeepsNonFinite`].
fn plan_keeps_nonfinite() -> String {
    format!(
        "the tiled plan refuses non-finite samples (its rounds do not count dropped samples): \
         do not ask for {} with a plan on tiles ({}); remove them from the samples, or plan \
         untiled",
        Fix::DropNonfinite,
        Fix::Set(Param::Tile)
    )
}
