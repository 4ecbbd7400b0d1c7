//! The image plane: the rectangle `[0, W] x [0, H]` in pixel units, samples `(x_i, y_i, f_i)`
//! on it, and everything that turns samples into pixels.
//!
//! Pixel `(X, Y)` (column `X`, row `Y`, both from 0) covers `[X, X + 1] x [Y, Y + 1]`; its
//! centre is `(X + 1/2, Y + 1/2)`. A sample value `f_i` has one entry per channel (1 to 4;
//! RGB scenes have 3).
//!
//! * [`ImagePlane`] is a validated resolution `W x H`.
//! * [`ImageSamples`] are validated scattered samples on a plane, stored per channel;
//!   [`nonfinite`]: a renderer's NaN or infinite values refused or dropped and counted.
//! * [`pixels`]: pixel values of a reconstruction as exact integrals against a pixel filter;
//!   [`equivalent_filter`]: the weight of each sample in one pixel's value.
//! * [`PixelImage`] is a grid of pixel values, per channel, row-major (`Y * W + X`).
//! * [`reconstruct`] is the entry point: samples to pixels by one [`ImageMethod`] (the wavelet fit,
//!   its local inversion, or a film filter), with a report of what it did ([`method`]).
//! * [`filters`]: the film filters renderers ship; [`splat`]: their weighted-average
//!   reconstruction; [`wavelet`]: the wavelet method's pixels.
//! * [`estimate`]: noise-aware pixel estimates (the fit clamped to its samples' range, the box
//!   pixels shrunk at the samples' own noise level), [`reconstruct_estimated`].
//! * [`scene`]: scenes from JSON; [`sampler`]: where samples go; [`truth`]: box-filtered
//!   ground truth; [`metrics`]: PSNR, RMSE, relative MSE, SSIM.
//! * [`report`]: typed reports of the commands that take a renderer's samples.
//!
//! The experiments that measure these methods against each other live in the lab module
//! (feature `plot`), which uses this one and is never used by it.

pub mod adaptive;
pub mod equivalent_filter;
pub mod estimate;
pub mod fit;
pub mod job;
pub mod method;
pub mod nonfinite;
pub mod pixels;
pub mod plan;

pub use estimate::{reconstruct_estimated, EstimateReport, UniformEstimate};
pub use fit::{
    fit_image, fit_samples, ImageFit, ImageFitError, ImageFitParams, ImageLevels, ImageSolveReport,
};
pub use method::{reconstruct, sample_weights, ImageMethod, ImageReconstruction, StageTimes};
pub use nonfinite::{split_finite, DroppedSamples, NonFinitePolicy};
pub use wavelet::{CoefficientSolve, WaveletError, WaveletParams};

pub mod film_weights;
pub mod filters;
pub mod metrics;
pub mod report;
pub mod sampler;
pub mod scene;
pub mod splat;
pub mod tiles;
pub mod truth;
mod types;
pub mod wavelet;

pub use types::{ImageError, ImagePlane, ImageSamples, PixelImage, MAX_CHANNELS, MAX_SIDE};
