//! What a pixel estimate did, for text and `--json`.

use serde::Serialize;

use super::auto::{AutoReport, FilmCount, WINDOW_HALF};
use super::choice::UniformEstimate;
use super::gate::GateCount;
use super::noise::{CountCalibration, DifferenceCount};
use super::robust::RobustReport;
use super::shrink::ShrinkParams;
use super::spatial::SpatialCheck;
use super::sure::FilmRisks;

/// What a pixel estimate did: the noise level and the thresholds used, the clamped values.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EstimateReport {
    /// The estimate asked for.
    pub requested: UniformEstimate,
    /// The estimate made (`fit` where `auto` fell back).
    pub estimate: UniformEstimate,
    /// Why `auto` fell back to `fit` (`None` when it did not).
    pub fallback: Option<String>,
    /// Pixels per film chosen by SURE (`auto` only).
    pub films: Option<Vec<FilmCount>>,
    /// The SURE window's side in pixels (`auto` only).
    pub window: Option<usize>,
    /// Estimated risk per pixel of the choice and of each film alone (`auto` only).
    pub risk: Option<FilmRisks>,
    /// Pixels per candidate of the risk gate (`auto` only: box, films, SureShrink, their
    /// mixtures).
    pub gate: Option<Vec<GateCount>>,
    /// The gate's level ratio: only the pixels of a pixel's window within this factor of its
    /// level count in its window sums (`auto` only; [`LEVEL_RATIO`](super::gate::LEVEL_RATIO)).
    pub gate_level_ratio: Option<f64>,
    /// The output's estimated risk per pixel (SURE against the box, summed over channels,
    /// averaged over pixels; `auto` only).
    pub estimated_risk: Option<f64>,
    /// The box pixels' estimated risk per pixel, `sum_c v_{P,c}` averaged over pixels (`auto`
    /// only).
    pub box_risk: Option<f64>,
    /// The robust candidate for heavy tails: what it cut, its estimated bias and the pixels the
    /// gate gave it (`auto` only; [`robust`](super::robust)).
    pub robust: Option<RobustReport>,
    /// The median SureShrink `lambda` per channel (`auto` only).
    pub lambda: Option<Vec<f64>>,
    /// Pooled noise level `sigma_c` per channel (`None` for `fit`, which does not need it).
    pub noise_level: Option<Vec<f64>>,
    /// Pixels whose noise is estimated (two samples or more; for `auto`, a block of strata),
    /// over which the noise level's median is taken.
    pub pixels_with_spread: Option<usize>,
    /// Pixels per difference estimate of the noise of a pixel's mean (`auto` only: the 2D
    /// strata's second differences, the successive differences along `x` or along `y`,
    /// [`noise`](super::noise)).
    pub noise_estimators: Option<Vec<DifferenceCount>>,
    /// The least of the three difference estimates' expectation on pure noise relative to the
    /// noise, at these sample positions (`auto` only; `c` of [`super::noise::pure_noise_ratio`]):
    /// the estimated risks fall short of the actual ones by about this factor where the pixels
    /// hold Monte Carlo noise only.
    pub pure_noise_ratio: Option<f64>,
    /// The noise of each sample count brought to the least of three's bias at the most common
    /// count (`auto` only; [`super::noise::PixelNoise::equalise_counts`]).
    pub count_calibration: Option<CountCalibration>,
    /// The check of the strata's noise against the box pixels' differences across pixels:
    /// the pixels whose noise it lowered, the median and total factor (`auto` only;
    /// [`spatial`](super::spatial)).
    pub spatial_check: Option<SpatialCheck>,
    /// Threshold `t_c = k sigma_c sqrt(2 ln N)` per channel (`shrunk` and `auto`).
    pub threshold: Option<Vec<f64>>,
    /// The shrinkage's parameters (`shrunk` and `auto`).
    pub shrink: Option<ShrinkParams>,
    /// Values (pixels x channels) the clamp moved (`fit-clamped`); for `auto`, the pixels the
    /// projection onto the range of their 3x3 neighbourhood's samples moved.
    pub clamped_values: Option<usize>,
    /// Pixels without samples, left unclamped (`fit-clamped` only).
    pub unclamped_empty_pixels: Option<usize>,
    /// Seconds for the statistics and the estimate (the fit excluded).
    pub seconds: f64,
    /// In words, with the figures.
    pub description: String,
}

impl AutoReport {
    /// Writes the fields and the description into `report`.
    pub fn fill(self, report: &mut EstimateReport) {
        report.description = self.describe();
        report.films = Some(self.films);
        report.window = Some(2 * WINDOW_HALF + 1);
        report.risk = Some(self.risk);
        report.noise_level = Some(self.sigma);
        report.pixels_with_spread = Some(self.pixels_with_blocks);
        report.noise_estimators = Some(self.noise_estimators);
        report.pure_noise_ratio = self.pure_noise_ratio;
        report.count_calibration = self.counts;
        report.spatial_check = Some(self.spatial);
        report.gate = Some(self.gate);
        report.gate_level_ratio = Some(self.level_ratio);
        report.estimated_risk = Some(self.estimated_risk);
        report.box_risk = Some(self.box_risk);
        report.lambda = Some(self.lambda);
        report.robust = Some(self.robust);
        report.clamped_values = Some(self.range_clamped);
        report.shrink = Some(self.shrink);
    }
}
