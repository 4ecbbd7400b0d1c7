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

pub mod blend_sure;
pub mod correction;
mod error;
#[cfg(feature = "plot")]
pub mod figure;
pub mod final_gate;
pub mod fit;
mod indicator;
pub(crate) mod oracle;
mod refiner;
pub mod significance;

/// The plan's solver choice under the memory limit, for the plan's state machine.
pub(crate) use crate::solve::tree::solver::{fallback_note, fitting_solver};
/// The tree system (`K_T^T K_T`, its PCG and Schwarz solves) lives in the solver layer,
/// [`crate::solve::tree`]; its modules keep their paths here.
pub use crate::solve::tree::{gram, pcg, schwarz};

pub use crate::adaptive::marking;
pub use crate::adaptive::{Cell, QuadTree};
pub use crate::adaptive::{MarkingParams, StopParams, TreeParams};
pub use correction::{PixelEstimate, ResidualCorrection};
pub use error::AdaptiveError;
pub use fit::{
    fit_tree, fit_tree_channels, fit_tree_updating, fit_tree_with, ChannelSolve, FitState, TreeFit,
    TreeFitReport,
};
pub use gram::TreeGram;
pub(crate) use oracle::mix64;
pub use oracle::{position_normal, ImageOracle, NoisyOracle, SceneOracle};
pub use pcg::TreeSolver;
pub use refiner::{
    empty_pixels, pixel_shortfall, refine_image, slot_sobol, AdaptiveImage, AdaptiveParams,
    AdaptiveReport, AdaptiveTimes, Decision, FitParams, GrowthParams, ImagePlan, ImageRound,
    ImageSampling, IndicatorParams, NoiseParams, OutputParams, ParsePatternError, PlanProgress,
    PositionPattern, QuadTreeParams, RebuildCost, Round, RoundTimes, SamplePositions,
    SHARE_MAX_SPP,
};
pub use significance::{NoiseLevel, Significance};
