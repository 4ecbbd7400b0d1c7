//! Adaptive sampling on the image plane (DESIGN §6–7; issue 13): a quadtree of the
//! non-standard tensor basis that spends samples where the scene needs them.
//!
//! * [`tree`]: the 2D wavelet tree, active functions closed under "parent present", local
//!   depth per region, slots (leaves) and their samples;
//! * [`fit`]: least squares on the tree (sparse Cholesky of `K_T^T K_T`, all channels from
//!   one factor) and exact box pixels through the 2D synthesis;
//! * [`indicator`]: predicted coefficients of the missing children, per slot;
//! * [`refiner`]: the rounds ([`ImagePlan::step`], one round; [`refine_image`], the loop): fit, indicate, mark (Dörfler, within the budget), deepen, add
//!   samples in the new slots so that every slot keeps `ceil(rho)` samples; stop at a
//!   tolerance, the depth limit or the sample budget;
//! * [`protocol`]: the rounds driven by a renderer through files (state, fingerprints);
//! * [`experiment`]: adaptive wavelet against film filters at equal total samples;
//! * `figure`: the image, the local depth and the samples side by side.

pub mod experiment;
#[cfg(feature = "plot")]
pub mod figure;
pub mod fit;
pub mod indicator;
pub mod marking;
pub mod pcg;
pub mod protocol;
pub mod refiner;
pub mod tree;

pub use fit::{fit_tree, fit_tree_with, TreeFit, TreeFitReport};
pub use pcg::TreeSolver;
pub use refiner::{
    refine_image, AdaptiveImage, AdaptiveParams, AdaptiveReport, Decision, ImagePlan, ImageRound,
    PlanProgress, Round, SamplePositions,
};
pub use tree::{Cell, QuadTree};

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
