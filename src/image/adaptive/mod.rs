//! Adaptive sampling on the image plane (docs/design.md §6–7): a quadtree of the
//! non-standard tensor basis that spends samples where the scene needs them.
//!
//! * [`QuadTree`] (in the adaptive core, [`crate::adaptive`], with Dörfler marking
//!   ([`marking`]) and the stop reasons shared with 1D): the 2D wavelet tree, active functions
//!   closed under "parent present", local depth per region, slots (leaves) and their samples;
//! * [`fit`]: least squares on the tree (sparse Cholesky of `K_T^T K_T`, all channels from
//!   one factor) and exact box pixels through the 2D synthesis;
//! * [`gram`]: `K_T^T K_T`, assembled in parallel, deterministically, and updated between
//!   rounds;
//! * `indicator`: predicted coefficients of the missing children, per slot;
//! * [`significance`]: which of them stand out of the samples' noise (probe fits);
//! * `refiner`: the rounds ([`ImagePlan::step`], one round; [`refine_image`], the loop):
//!   fit, indicate, mark (Dörfler, within the budget), deepen, add samples in the new slots
//!   so that every slot keeps `ceil(rho)` samples; stop at a tolerance, the depth limit or
//!   the sample budget;
//!   (a renderer outside the process drives the same rounds through the plan's state machine,
//!   `image::plan`);
//! * [`correction`]: the output pixels, the fit as a control variate (box pixels plus the
//!   significant mean residual of each pixel's samples; the default output);
//! * `figure`: the image, the local depth and the samples side by side.

pub mod correction;
mod diagonal;
#[cfg(feature = "plot")]
pub mod figure;
pub mod fit;
pub mod gram;
mod indicator;
mod operator;
pub mod pcg;
mod refiner;
pub mod schwarz;
pub mod significance;
mod single_scale;
mod solver;

/// The plan's solver choice under the memory limit, for the plan's state machine.
pub(crate) use solver::{fallback_note, fitting_solver};

pub use crate::adaptive::marking;
/// The quadtree under its old path, for the solver modules' `super::tree` imports.
use crate::adaptive::tree::quad as tree;
pub use crate::adaptive::{Cell, QuadTree};
pub use crate::adaptive::{MarkingParams, StopParams, TreeParams};
pub use correction::{PixelEstimate, ResidualCorrection};
pub use fit::{fit_tree, fit_tree_updating, fit_tree_with, FitState, TreeFit, TreeFitReport};
pub use gram::TreeGram;
pub use pcg::TreeSolver;
pub use refiner::{
    empty_pixels, pixel_shortfall, refine_image, slot_sobol, AdaptiveImage, AdaptiveParams,
    AdaptiveReport, AdaptiveTimes, Decision, FitParams, GrowthParams, ImagePlan, ImageRound,
    ImageSampling, IndicatorParams, NoiseParams, OutputParams, ParsePatternError, PlanProgress,
    PositionPattern, QuadTreeParams, RebuildCost, Round, RoundTimes, SamplePositions,
};
pub use significance::{NoiseLevel, Significance};

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

/// A scene as seen by the refiner: the values of every channel at a point of the image
/// (pixel units).
pub trait ImageOracle: Sync {
    /// Number of channels.
    fn channels(&self) -> usize;
    /// The values at `(x, y)` into `out` (`channels()` entries).
    fn sample(&self, x: f64, y: f64, out: &mut [f64]);
}

/// A built-in scene on a plane (RGB, noise-free).
pub struct SceneOracle<'a> {
    /// The scene.
    pub scene: &'a crate::image::scene::Scene,
    /// The image plane.
    pub plane: crate::image::ImagePlane,
}

impl ImageOracle for SceneOracle<'_> {
    fn channels(&self) -> usize {
        3
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        out.copy_from_slice(&self.scene.radiance_on(self.plane, x, y));
    }
}

/// Any `Fn(x, y) -> f64` is a one-channel oracle.
impl<F: Fn(f64, f64) -> f64 + Sync> ImageOracle for F {
    fn channels(&self) -> usize {
        1
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        out[0] = self(x, y);
    }
}

/// 64-bit mix (SplitMix64's finaliser).
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A standard normal deviate that is a function of `seed`, the position's bits and the index
/// `k` (Box–Muller on two uniforms from a 64-bit mix): the same position always gets the same
/// deviate, whatever the order or the process that asks.
pub fn position_normal(seed: u64, x: f64, y: f64, k: usize) -> f64 {
    let h = mix64(seed ^ mix64(x.to_bits() ^ mix64(y.to_bits() ^ mix64(k as u64 + 1))));
    let (a, b) = (mix64(h), mix64(h ^ 0x9E37_79B9_7F4A_7C15));
    // 53-bit uniforms, u1 in (0, 1], u2 in [0, 1)
    let u1 = ((a >> 11) + 1) as f64 / (1u64 << 53) as f64;
    let u2 = (b >> 11) as f64 / (1u64 << 53) as f64;
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// An oracle with Gaussian noise, a renderer's Monte Carlo estimate in miniature:
/// `f(x, y) + sigma n_c(x, y)` per channel `c`, `n_c` standard normal deviates seeded by the
/// seed and the position ([`position_normal`]), so the in-process loop and a renderer driving
/// the file protocol see the same values, and runs are deterministic.
pub struct NoisyOracle<'a> {
    /// The noise-free oracle.
    pub inner: &'a dyn ImageOracle,
    /// Standard deviation `sigma` of the noise.
    pub sigma: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl ImageOracle for NoisyOracle<'_> {
    fn channels(&self) -> usize {
        self.inner.channels()
    }
    fn sample(&self, x: f64, y: f64, out: &mut [f64]) {
        self.inner.sample(x, y, out);
        if self.sigma > 0.0 {
            for (c, v) in out.iter_mut().enumerate() {
                *v += self.sigma * position_normal(self.seed, x, y, c);
            }
        }
    }
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
