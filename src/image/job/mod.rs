//! The image plane's front door: one library call per job a user meets, which validates the
//! parameters, decides the defaults, estimates the memory and refuses before it allocates,
//! then does the work. The command line (`rkwave reconstruct --dim 2`) and the Python module
//! (`rkwave.reconstruct_image`) call these and only parse and print, so both give the same
//! refusals and the same decisions for the same request.
//!
//! * [`UniformJob`]: scattered samples `(x_i, y_i, f_i)` to the pixels of a `W x H` image on
//!   the uniform path ([`crate::image::reconstruct_estimated`]: a pixel estimate, by default
//!   a film per pixel chosen by SURE; the least-squares fit; or a film filter). Built once
//!   from [`ImageParams`] ([`UniformJob::new`], no allocation beyond the parameters), checked
//!   against the memory limit from the sizes alone ([`UniformJob::check_memory`], before the
//!   samples are read or converted), then run ([`UniformJob::run`]).
//! * [`TiledJob`]: the same fit tile by tile, the samples read in chunks from a file
//!   ([`crate::image::tiles`]), for images whose fit does not fit in memory at once.
//! * The plan's jobs ([`PlanStart`], [`PlanRound`], [`PlanFinal`]): a renderer's adaptive
//!   loop, one call per step, on the plan's state machine ([`crate::image::plan`]).
//! * [`memory`]: the memory requests of every image-plane path; [`text`]: notes wrapped at
//!   a readable width for the front ends to print.
//!
//! Messages name the parameter at fault as data ([`crate::error::Param`] through
//! [`crate::error::Fix::Set`]): the command line spells it as its flag (`--rho`), Python as
//! its keyword (`rho=`).
//!
//! Why `image::job`: the jobs sit on top of the image plane's stages (estimates, fits,
//! films) and beside them, below the front ends; they are image-plane code, so they live in
//! `image/`, but in a room of their own so that the stages never call back into them.

pub mod memory;
mod plan;
pub mod text;
mod tiled;
pub mod tiled_plan;
mod uniform;

pub use plan::{PlanBudget, PlanFinal, PlanOptions, PlanRound, PlanSolver, PlanStart};
pub use tiled::{TileOptions, TiledJob, TiledRun};
pub use uniform::{PixelChoice, UniformJob, UniformOutput};

use std::fmt;

use thiserror::Error;

use crate::error::{ErrorKind, Fix, Param};
use crate::image::estimate::{EstimateError, ShrinkParams};
use crate::image::plan::ProtocolError;
use crate::image::tiles::TiledError;
use crate::image::{ImageMethod, ImagePlane, UniformEstimate, WaveletError};
use crate::resources::ResourceError;

/// The parameters of an image-plane job, in the few groups a user meets. Every `Option` left
/// `None` takes the library's default, and counts as not asked for (the default pixel
/// estimate depends on which fit parameters were asked for: [`PixelChoice`]).
#[derive(Debug, Clone)]
pub struct ImageParams {
    /// How samples become pixels: the least-squares fit ([`ImageMethod::Wavelet`], the default),
    /// its local inversion ([`ImageMethod::Local`]: faster on large images, slightly less
    /// accurate where samples are sparse) or a film filter ([`ImageMethod::Film`], the renderer's
    /// baseline; no fit, no pixel estimate).
    pub method: ImageMethod,
    /// The least-squares fit's basis and regularization (read only where the fit runs).
    pub fit: FitOptions,
    /// The pixel estimate of the fit's path; `None`: [`UniformEstimate::Auto`] (a film per
    /// pixel chosen by SURE, then Haar shrinkage; no fit unless a pixel lacks samples), or
    /// the fit when a fit parameter was asked for ([`PixelChoice`]).
    pub pixels: Option<UniformEstimate>,
    /// The shrinkage of the noise-aware estimates (threshold scale, levels).
    pub shrink: ShrinkParams,
    /// Settings a front end has that only the fit reads and that these fields do not hold
    /// (the command line's `--family`, `--levels`, `--method global`): asking for them asks
    /// for the fit, as setting a field of [`FitOptions`] does.
    pub also_asked: Vec<Param>,
}

/// The least-squares fit's options (`None`: the default, not asked for).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FitOptions {
    /// Vanishing moments `p`, 1 to 4 (default 2): higher orders reproduce smoother detail
    /// at the cost of wider functions (more samples per function, a slower solve).
    pub p: Option<usize>,
    /// Samples per tensor function (default 4): larger values choose coarser levels (less
    /// noise, less detail).
    pub rho: Option<f64>,
    /// Relative ridge of the normal equations, in `[0, 1)` (default `1e-9`): larger values
    /// pull poorly sampled functions to zero.
    pub ridge: Option<f64>,
    /// Smoothing weight `>= 0` (default 0, the plain least squares): larger values trade
    /// detail for less noise.
    pub smoothing: Option<f64>,
}

impl Default for ImageParams {
    fn default() -> Self {
        ImageParams {
            method: ImageMethod::Wavelet,
            fit: FitOptions::default(),
            pixels: None,
            shrink: ShrinkParams::default(),
            also_asked: Vec::new(),
        }
    }
}

impl ImageParams {
    /// The fit parameters asked for, in the order the messages list them (`p`, the family,
    /// the method, the levels, `rho`, the ridge, the smoothing).
    pub fn fit_asked(&self) -> Vec<Param> {
        let set = [
            (Param::P, self.fit.p.is_some()),
            (Param::Family, self.also_asked.contains(&Param::Family)),
            (
                Param::Method,
                self.method == ImageMethod::Local || self.also_asked.contains(&Param::Method),
            ),
            (Param::Levels, self.also_asked.contains(&Param::Levels)),
            (Param::Rho, self.fit.rho.is_some()),
            (Param::Ridge, self.fit.ridge.is_some()),
            (Param::Smoothing, self.fit.smoothing.is_some()),
        ];
        set.into_iter()
            .filter_map(|(param, asked)| asked.then_some(param))
            .collect()
    }
}

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
    #[error("{}", plan::too_large(*plane, *budget, *functions, parts, *needed, *limit))]
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
    #[error("{}", tiled::keeps_nonfinite())]
    TilesKeepNonFinite,
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
            | JobError::TilesKeepNonFinite => ErrorKind::InvalidInput,
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
fn in_range<T: fmt::Display>(
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

#[cfg(test)]
mod tests;
