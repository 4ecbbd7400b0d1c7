//! The uniform reconstruction job: validate, decide the pixel estimate, check the memory from
//! the sizes, then reconstruct ([`UniformJob`]).

use std::fmt;

use crate::error::{Fix, Param};
use crate::image::estimate::{EstimateReport, PixelStatistics};
use crate::image::filters::FilmFilterKind;
use crate::image::{
    reconstruct, reconstruct_estimated, ImageMethod, ImagePlane, ImageReconstruction, ImageSamples,
    UniformEstimate, WaveletParams,
};
use crate::resources::{ImageRequest, ResourceError};

use super::memory::{estimate_request, method_request, uniform_request};
use super::{check_p, in_range, By, ImageParams, JobError};

/// The pixel estimate a job makes and why: asked for, the default
/// ([`UniformEstimate::Auto`]), or the fit because fit parameters were asked for
/// ([`PixelChoice::because`] non-empty; its `Display` is the note that says so).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PixelChoice {
    /// The estimate.
    pub estimate: UniformEstimate,
    /// The fit parameters asked for without a pixel estimate, which made the fit the
    /// default (empty when the estimate was asked for, or is the default `auto`).
    pub because: Vec<Param>,
}

impl PixelChoice {
    /// The estimate of `params` (a film filter makes none: `None`).
    pub fn of(params: &ImageParams) -> Option<PixelChoice> {
        if matches!(params.method, ImageMethod::Film(_)) {
            return None;
        }
        if let Some(estimate) = params.pixels {
            return Some(PixelChoice {
                estimate,
                because: Vec::new(),
            });
        }
        let because = params.fit_asked();
        let estimate = if because.is_empty() {
            UniformEstimate::Auto
        } else {
            UniformEstimate::Fit
        };
        Some(PixelChoice { estimate, because })
    }

    /// The note a front end prints, when the default was changed by the parameters asked.
    pub fn note(&self) -> Option<String> {
        (!self.because.is_empty()).then(|| self.to_string())
    }
}

impl fmt::Display for PixelChoice {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.because.is_empty() {
            return write!(f, "pixels: {}", self.estimate);
        }
        let names: Vec<String> = self
            .because
            .iter()
            .map(|&p| Fix::Set(p).to_string())
            .collect();
        write!(
            f,
            "pixels: the least-squares fit, because {} (read by the fit only) was given without \
             {}; the default without them is {} (films chosen per pixel by SURE), which uses no \
             fit",
            names.join(", "),
            Fix::Set(Param::Pixels),
            Fix::PixelsAuto
        )
    }
}

/// A validated uniform reconstruction: the method, the fit's parameters and the pixel
/// estimate decided, nothing allocated yet (module docs of [`crate::image::job`]).
#[derive(Debug, Clone)]
pub struct UniformJob {
    plane: ImagePlane,
    method: ImageMethod,
    wavelet: WaveletParams,
    pixels: Option<PixelChoice>,
    shrink: crate::image::estimate::ShrinkParams,
}

/// What a [`UniformJob`] made.
#[derive(Debug)]
pub struct UniformOutput {
    /// The pixels and the report of the method that made them.
    pub reconstruction: ImageReconstruction,
    /// The pixel estimate's report (`None` for a film filter).
    pub estimate: Option<EstimateReport>,
    /// The method whose pixels these are: the one asked for, or the box film where the
    /// estimate used no fit.
    pub method: ImageMethod,
    /// The estimate decided and why (`None` for a film filter).
    pub pixels: Option<PixelChoice>,
}

impl UniformJob {
    /// Validates `params` for an image `plane` and decides the defaults: `p` in 1 to 4,
    /// `rho > 0`, the ridge in `[0, 1)`, the smoothing `>= 0` (all finite); a pixel estimate
    /// only on the fit's path. Allocates nothing.
    pub fn new(plane: ImagePlane, params: &ImageParams) -> Result<UniformJob, JobError> {
        let defaults = WaveletParams::default();
        let fit = params.fit;
        let rho = fit.rho.unwrap_or(defaults.rho);
        let rho = in_range(
            Param::Rho,
            rho,
            rho.is_finite() && rho > 0.0,
            " must be a positive number of samples per tensor function (the image fit's \
             default is 4)",
        )?;
        let ridge = fit.ridge.unwrap_or(defaults.ridge);
        let ridge = in_range(
            Param::Ridge,
            ridge,
            ridge.is_finite() && (0.0..1.0).contains(&ridge),
            " must be in [0, 1) (the image fit's default is 1e-9)",
        )?;
        let smoothing = fit.smoothing.unwrap_or(defaults.smoothing);
        let smoothing = in_range(
            Param::Smoothing,
            smoothing,
            smoothing.is_finite() && smoothing >= 0.0,
            " must be a finite weight >= 0 (0: the least-squares fit)",
        )?;
        let wavelet = WaveletParams {
            p: check_p(fit.p.unwrap_or(defaults.p))?,
            pixel_filter: None,
            rho,
            ridge,
            smoothing,
        };
        if matches!(params.method, ImageMethod::Film(_)) && params.pixels.is_some() {
            return Err(JobError::Conflict {
                first: Param::Pixels,
                second: Param::Method,
                reason: "is the estimate of the wavelet path; a film filter splats the samples \
                         itself",
            });
        }
        Ok(UniformJob {
            plane,
            method: params.method,
            wavelet,
            pixels: PixelChoice::of(params),
            shrink: params.shrink,
        })
    }

    /// The image.
    pub fn plane(&self) -> ImagePlane {
        self.plane
    }

    /// The fit's parameters, defaults filled in.
    pub fn wavelet(&self) -> &WaveletParams {
        &self.wavelet
    }

    /// The pixel estimate decided (`None` for a film filter).
    pub fn pixels(&self) -> Option<&PixelChoice> {
        self.pixels.as_ref()
    }

    /// The memory of `samples` samples of `channels` channels, from the sizes alone (call it
    /// before reading or converting the samples): the fit's where the estimate is the fit;
    /// otherwise the estimate's own, which also covers the per-pixel statistics
    /// [`UniformEstimate::Auto`] reads to decide whether it falls back to the fit (that
    /// fallback's fit is checked by [`UniformJob::run`] once the samples are known).
    pub fn check_memory(&self, channels: usize, samples: usize) -> Result<(), JobError> {
        let m = samples as f64;
        let (request, by) = match &self.pixels {
            None => (
                method_request(
                    self.plane,
                    channels,
                    m,
                    self.method,
                    self.wavelet.p,
                    self.wavelet.rho,
                    1,
                ),
                By::Method(self.method),
            ),
            Some(choice) if choice.estimate.uses_fit() => {
                (self.fit_request(channels, m), { By::Method(self.method) })
            }
            Some(choice) => (
                estimate_request(self.plane, channels, m, choice.estimate),
                By::Estimate(choice.estimate),
            ),
        };
        self.check(&request, samples, by)
    }

    /// Reconstructs `samples` (on this job's plane): the memory checked first
    /// ([`UniformJob::check_memory`], then the fit's where `auto` falls back to it), then the
    /// pixel estimate, or the method itself for a film filter.
    pub fn run(&self, samples: &ImageSamples) -> Result<UniformOutput, JobError> {
        let (channels, m) = (samples.channels(), samples.len());
        self.check_memory(channels, m)?;
        let Some(choice) = &self.pixels else {
            let reconstruction = reconstruct(self.method, samples, &self.wavelet)?;
            return Ok(UniformOutput {
                reconstruction,
                estimate: None,
                method: self.method,
                pixels: None,
            });
        };
        if choice.estimate == UniformEstimate::Auto {
            // The rule of `auto`'s fallback to the fit (crate::image::estimate::auto): a
            // pixel without samples, or fewer than half the pixels with two.
            let stats = PixelStatistics::new(samples);
            let falls_back =
                stats.empty_pixels() > 0 || 2 * stats.pixels_with_spread() < self.plane.pixels();
            drop(stats);
            if falls_back {
                let request = self.fit_request(channels, m as f64);
                self.check(&request, m, By::Method(self.method))?;
            }
        }
        let (reconstruction, estimated) = reconstruct_estimated(
            choice.estimate,
            self.method,
            samples,
            &self.wavelet,
            &self.shrink,
        )?;
        let method = if estimated.estimate.uses_fit() {
            self.method
        } else {
            ImageMethod::Film(FilmFilterKind::Box)
        };
        Ok(UniformOutput {
            reconstruction,
            estimate: Some(estimated),
            method,
            pixels: Some(choice.clone()),
        })
    }

    fn fit_request(&self, channels: usize, m: f64) -> ImageRequest {
        uniform_request(
            self.plane,
            channels,
            m,
            self.wavelet.p,
            self.wavelet.rho,
            self.method == ImageMethod::Local,
            1,
        )
    }

    fn check(&self, request: &ImageRequest, samples: usize, by: By) -> Result<(), JobError> {
        let estimate = request.estimate();
        match estimate.check(String::new, String::new) {
            Ok(()) => Ok(()),
            Err(ResourceError::TooLarge { needed, limit, .. }) => Err(JobError::TooLarge {
                samples,
                plane: self.plane,
                by,
                parts: estimate.parts(),
                needed,
                limit,
            }),
            Err(e) => Err(JobError::Resources(e)),
        }
    }
}
