//! Noise-aware pixel estimates on the uniform path: what a pixel's
//! value is, given the samples in it and the noise they carry.
//!
//! * [`UniformEstimate::Auto`] (the default): per pixel, the candidate of least estimated
//!   risk against the box pixels (the per-pixel mean, itself a candidate) by SURE over the
//!   9 x 9 window's pixels at its level ([`gate`]): the film filters chosen by SURE
//!   ([`sure`]), heteroscedastic SureShrink of the box pixels ([`sureshrink`]), their mixtures
//!   and a robust candidate, with the noise of each pixel's mean from second
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
mod choice;
pub mod clamp;
pub mod divergence;
pub mod gate;
pub mod haar;
pub mod noise;
mod report;
pub mod robust;
pub mod shrink;
pub mod spatial;
pub mod spin;
pub mod statistics;
pub mod sure;
pub mod sure_blend;
pub mod sureshrink;
mod text;

use std::time::Instant;

use thiserror::Error;

pub use auto::{AutoReport, FilmCount};
pub use blend::{blend_by_risk, inverse_risk_weight};
pub use choice::{ParseUniformEstimateError, UniformEstimate};
pub use clamp::clamp_to_sample_range;
pub use gate::GateCount;
pub use haar::{Haar2d, HaarCoefficients};
pub use noise::{CountCalibration, CountClass, DifferenceCount, PixelNoise, StrataDifference};
pub use report::EstimateReport;
pub use robust::RobustReport;
pub use shrink::{
    shrink_channel, shrink_channel_with_divergence, soft, universal_threshold, ShrinkParams,
};
pub use statistics::PixelStatistics;
pub use sure::{choose_films, FilmChoice, FilmRisks};
use text::list;

use crate::error::{ErrorKind, Fix, Param};

use super::method::{reconstruct, ImageMethod, ImageReconstruction, StageTimes};
use super::wavelet::{WaveletError, WaveletParams};
use super::{ImageSamples, PixelImage};

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
        gate_level_ratio: None,
        estimated_risk: None,
        box_risk: None,
        robust: None,
        lambda: None,
        noise_level: None,
        pixels_with_spread: None,
        noise_estimators: None,
        pure_noise_ratio: None,
        count_calibration: None,
        spatial_check: None,
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
