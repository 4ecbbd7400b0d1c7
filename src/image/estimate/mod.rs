//! Noise-aware pixel estimates on the uniform path: what a pixel's
//! value is, given the samples in it and the noise they carry.
//!
//! * [`UniformEstimate::Auto`] (the default): per pixel, the candidate of least estimated
//!   risk against the box pixels (the per-pixel mean, itself a candidate) by SURE over the
//!   9 x 9 window ([`gate`]): the film filters chosen by SURE ([`sure`]), heteroscedastic
//!   SureShrink of the box pixels ([`sureshrink`]), their mixtures and their projections onto
//!   each pixel's own sample range, with the noise of each pixel's mean from second
//!   differences of its stratified samples ([`noise`]); then every pixel projected onto the
//!   range of the samples in its 3 x 3 neighbourhood ([`auto`] states the steps). Where the
//!   samples do not permit it (a pixel without samples, or fewer than half the pixels with
//!   two), the fit instead, with the reason in the report.
//! * [`UniformEstimate::Fit`]: the least-squares fit's box pixels ([`crate::image::reconstruct`]),
//!   unchanged.
//! * [`UniformEstimate::FitClamped`]: the fit, each pixel clamped to the range of its own samples
//!   `[min_i v_i, max_i v_i]` ([`clamp`]): the projection that removes the fit's ringing beside a
//!   bright edge (an emitter in view) and moves no pixel already in its range.
//! * [`UniformEstimate::Box`]: the mean of each pixel's samples `m_P = (1/n_P) sum_i v_i` (the box
//!   film; [`statistics`]).
//! * [`UniformEstimate::Shrunk`]: the box pixels, soft-shrunk in the orthonormal Haar basis at the
//!   universal threshold `t_c = sigma_c sqrt(2 ln N)` and averaged over 16 shifts of the dyadic
//!   grid ([`shrink`], [`haar`]). The noise level comes from the samples themselves:
//!   `sigma_c = sqrt(median_P s²_{P,c} / n_P)`, the median over pixels of the variance of a
//!   pixel's mean, so no noise flag is needed; where the samples carry no pixel-scale noise it
//!   is near zero and the shrinkage changes nothing.
//!
//! Why these: `docs/measurements/real-renders.md`, "Prototype: noise-aware pixel estimates", and
//! the table after it measured in Rust; `docs/design.md` has the section "Noise-aware pixel
//! estimates". The noise level and the thresholds used are in the [`EstimateReport`] (text and
//! `--json`).

pub mod auto;
pub mod blend;
pub mod clamp;
pub mod gate;
pub mod haar;
pub mod noise;
pub mod robust;
pub mod shrink;
pub mod statistics;
pub mod sure;
pub mod sureshrink;

use std::fmt;
use std::str::FromStr;
use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

pub use auto::{AutoReport, FilmCount};
pub use blend::{blend_by_risk, inverse_risk_weight};
pub use clamp::clamp_to_sample_range;
pub use gate::GateCount;
pub use haar::{Haar2d, HaarCoefficients};
pub use noise::{DifferenceCount, PixelNoise, StrataDifference};
pub use robust::RobustReport;
pub use shrink::{shrink_channel, soft, universal_threshold, ShrinkParams};
pub use statistics::PixelStatistics;
pub use sure::{choose_films, FilmChoice, FilmRisks};

use crate::error::{ErrorKind, Fix, Param};

use super::method::{reconstruct, ImageMethod, ImageReconstruction, StageTimes};
use super::wavelet::{WaveletError, WaveletParams};
use super::{ImageSamples, PixelImage};

/// How a pixel's value is estimated from the samples on the uniform path (the adaptive
/// engine's output has its own choice, [`crate::image::adaptive::PixelEstimate`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize)]
#[serde(into = "String")]
pub enum UniformEstimate {
    /// Per pixel the candidate of least SURE against the box (films, SureShrink, mixtures,
    /// their own-range projections, the box), projected onto the local sample range.
    #[default]
    Auto,
    /// The least-squares fit's box pixels (the reconstruction method's output, unchanged).
    Fit,
    /// The fit clamped per pixel to the range of the pixel's samples.
    FitClamped,
    /// The mean of the pixel's samples (the box film).
    Box,
    /// The box pixels, shrunk in cycle-spun Haar at the universal threshold of the samples'
    /// own noise level.
    Shrunk,
}

impl UniformEstimate {
    /// Every estimate, the default first.
    pub const ALL: [UniformEstimate; 5] = [
        UniformEstimate::Auto,
        UniformEstimate::Fit,
        UniformEstimate::FitClamped,
        UniformEstimate::Box,
        UniformEstimate::Shrunk,
    ];

    /// The name on the command line (`auto`, `fit`, `fit-clamped`, `box`, `shrunk`).
    pub fn name(self) -> &'static str {
        match self {
            UniformEstimate::Auto => "auto",
            UniformEstimate::Fit => "fit",
            UniformEstimate::FitClamped => "fit-clamped",
            UniformEstimate::Box => "box",
            UniformEstimate::Shrunk => "shrunk",
        }
    }

    /// Whether the estimate uses the least-squares fit (otherwise only the pixels' samples).
    pub fn uses_fit(self) -> bool {
        matches!(self, UniformEstimate::Fit | UniformEstimate::FitClamped)
    }
}

impl From<UniformEstimate> for String {
    fn from(e: UniformEstimate) -> String {
        e.name().to_string()
    }
}

impl fmt::Display for UniformEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A pixel-estimate name that is not one of [`UniformEstimate::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown pixel estimate `{name}`: expected auto, fit, fit-clamped, box or shrunk")]
pub struct ParseUniformEstimateError {
    /// The name as given.
    pub name: String,
}

impl FromStr for UniformEstimate {
    type Err = ParseUniformEstimateError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_lowercase();
        UniformEstimate::ALL
            .into_iter()
            .find(|e| e.name() == t)
            .ok_or_else(|| ParseUniformEstimateError {
                name: s.to_string(),
            })
    }
}

/// Why a pixel estimate could not be made.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum EstimateError {
    /// The least-squares fit failed.
    #[error(transparent)]
    Wavelet(#[from] WaveletError),
    /// The estimate needs samples in every pixel.
    #[error(
        "pixel estimate `{estimate}` needs samples in every pixel, and {count} pixels have none \
         (the first at ({x}, {y})): render at least one sample per pixel or set {pixels} to `fit`",
        pixels = Fix::Set(Param::Pixels)
    )]
    EmptyPixels {
        /// The estimate asked for.
        estimate: UniformEstimate,
        /// Pixels without samples.
        count: usize,
        /// Column of the first.
        x: usize,
        /// Row of the first.
        y: usize,
    },
    /// No pixel has two samples, so the noise level is unknown.
    #[error(
        "pixel estimate `shrunk` takes the noise level from the spread of the samples within a \
         pixel, and no pixel has two samples: render at least 2 samples per pixel or set \
         {pixels} to `box`",
        pixels = Fix::Set(Param::Pixels)
    )]
    NoSpread,
}

impl EstimateError {
    /// The kind of this error ([`crate::error`]): a failed fit keeps its own; pixels without
    /// the samples an estimate needs are undetermined.
    pub fn kind(&self) -> ErrorKind {
        match self {
            EstimateError::Wavelet(e) => e.kind(),
            EstimateError::EmptyPixels { .. } | EstimateError::NoSpread => ErrorKind::Undetermined,
        }
    }
}

crate::error::classified!(EstimateError);

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
    /// The output's estimated risk per pixel (SURE against the box, summed over channels,
    /// averaged over pixels; `auto` only).
    pub estimated_risk: Option<f64>,
    /// The box pixels' estimated risk per pixel, `sum_c v_{P,c}` averaged over pixels (`auto`
    /// only).
    pub box_risk: Option<f64>,
    /// The robust candidate for heavy tails: what it cut, its estimated bias and the pixels the
    /// gate gave it (`auto` only; [`robust`]).
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
    /// [`noise`]).
    pub noise_estimators: Option<Vec<DifferenceCount>>,
    /// The least of the three difference estimates' expectation on pure noise relative to the
    /// noise, at these sample positions (`auto` only; `c` of [`noise::pure_noise_ratio`]): the
    /// estimated risks fall short of the actual ones by about this factor where the pixels
    /// hold Monte Carlo noise only.
    pub pure_noise_ratio: Option<f64>,
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

/// The pixels of `samples` by `estimate`: the fit by `method` (with `wavelet`) for `fit` and
/// `fit-clamped`; for `box` and `shrunk`, the pixel statistics alone (`method` not used). The
/// reconstruction's notes end with the estimate's description (except for `fit`, whose output
/// is [`reconstruct`]'s unchanged).
pub fn reconstruct_estimated(
    estimate: UniformEstimate,
    method: ImageMethod,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
    shrink: &ShrinkParams,
) -> Result<(ImageReconstruction, EstimateReport), EstimateError> {
    let start = Instant::now();
    let mut report = EstimateReport {
        requested: estimate,
        estimate,
        fallback: None,
        films: None,
        window: None,
        risk: None,
        gate: None,
        estimated_risk: None,
        box_risk: None,
        robust: None,
        lambda: None,
        noise_level: None,
        pixels_with_spread: None,
        noise_estimators: None,
        pure_noise_ratio: None,
        threshold: None,
        shrink: None,
        clamped_values: None,
        unclamped_empty_pixels: None,
        seconds: 0.0,
        description: String::new(),
    };
    if estimate == UniformEstimate::Auto {
        let t_estimate = Instant::now();
        match auto::estimate(samples, shrink) {
            Ok((image, auto_report)) => {
                auto_report.fill(&mut report);
                report.seconds = t_estimate.elapsed().as_secs_f64();
                let total = start.elapsed().as_secs_f64();
                let done = ImageReconstruction {
                    image,
                    time_s: StageTimes {
                        fit: 0.0,
                        pixels: total,
                        total,
                    },
                    functions: None,
                    splat: None,
                    solve: None,
                    notes: vec![report.description.clone()],
                };
                return Ok((done, report));
            }
            Err(reason) => {
                report.estimate = UniformEstimate::Fit;
                report.fallback = Some(reason);
            }
        }
    }
    if report.estimate == UniformEstimate::Fit {
        let mut done = reconstruct(method, samples, wavelet)?;
        report.description = "pixels: the least-squares fit's box pixels, unchanged".into();
        if let Some(reason) = &report.fallback {
            report.description = format!(
                "pixels: the least-squares fit's box pixels ({auto} fell back to fit: \
                 {reason})",
                auto = Fix::PixelsAuto
            );
            done.notes.push(report.description.clone());
        }
        return Ok((done, report));
    }
    let fitted = match estimate {
        UniformEstimate::FitClamped => Some(reconstruct(method, samples, wavelet)?),
        _ => None,
    };
    let t_estimate = Instant::now();
    let stats = PixelStatistics::new(samples);
    let sigma = stats.noise_level();
    report.noise_level = sigma.clone();
    report.pixels_with_spread = Some(stats.pixels_with_spread());
    let mut done = match (estimate, fitted) {
        (UniformEstimate::FitClamped, Some(mut fit)) => {
            let moved = clamp_to_sample_range(&mut fit.image, &stats);
            report.clamped_values = Some(moved);
            report.unclamped_empty_pixels = Some(stats.empty_pixels());
            report.description = format!(
                "pixels: the fit clamped to the range of each pixel's samples ({moved} values \
                 moved, {} pixels without samples left as fitted)",
                stats.empty_pixels()
            );
            fit
        }
        _ => ImageReconstruction {
            image: box_image(&stats, estimate)?,
            time_s: StageTimes::default(),
            functions: None,
            splat: None,
            solve: None,
            notes: vec![],
        },
    };
    if estimate == UniformEstimate::Box {
        report.description = "pixels: the mean of each pixel's samples (the box film)".into();
    }
    if estimate == UniformEstimate::Shrunk {
        let sigma = sigma.ok_or(EstimateError::NoSpread)?;
        let plane = stats.plane;
        let thresholds: Vec<f64> = sigma
            .iter()
            .map(|&s| universal_threshold(s, plane.pixels(), shrink.threshold_factor))
            .collect();
        for (channel, &t) in done.image.channels.iter_mut().zip(&thresholds) {
            *channel = shrink_channel(channel, plane.width(), plane.height(), t, shrink.shifts);
        }
        report.description = format!(
            "pixels: the box pixels shrunk (soft, orthonormal Haar, {} shifts) at the universal \
             threshold {} for the noise level sigma = {} per channel (the median variance of a \
             pixel's mean over {} pixels with 2 or more samples)",
            shrink.shifts * shrink.shifts,
            list(&thresholds),
            list(&sigma),
            stats.pixels_with_spread()
        );
        report.threshold = Some(thresholds);
        report.shrink = Some(*shrink);
    }
    report.seconds = t_estimate.elapsed().as_secs_f64();
    let total = start.elapsed().as_secs_f64();
    done.time_s = StageTimes {
        fit: if estimate.uses_fit() {
            done.time_s.fit
        } else {
            0.0
        },
        pixels: if estimate.uses_fit() {
            done.time_s.pixels + report.seconds
        } else {
            total
        },
        total,
    };
    done.notes.push(report.description.clone());
    Ok((done, report))
}

/// The box pixels of `stats`, or the first empty pixel as an error.
fn box_image(
    stats: &PixelStatistics,
    estimate: UniformEstimate,
) -> Result<PixelImage, EstimateError> {
    if let Some(p) = stats.count.iter().position(|&n| n == 0) {
        let w = stats.plane.width();
        return Err(EstimateError::EmptyPixels {
            estimate,
            count: stats.empty_pixels(),
            x: p % w,
            y: p / w,
        });
    }
    Ok(PixelImage {
        plane: stats.plane,
        channels: stats.mean.clone(),
    })
}

/// `a, b, c` with three significant digits.
fn list(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:.3e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for e in UniformEstimate::ALL {
            assert_eq!(e.name().parse::<UniformEstimate>(), Ok(e));
        }
        assert!("median".parse::<UniformEstimate>().is_err());
    }
}
