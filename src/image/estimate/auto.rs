//! `--pixels auto`: the film of least SURE per pixel ([`super::sure`]) with the noise of the
//! samples themselves ([`super::noise`]), then cycle-spun Haar shrinkage ([`super::shrink`]) of
//! the result at the universal threshold `t_c = k sigma'_c sqrt(2 ln N)`, `sigma'_c` the median
//! over pixels of the chosen films' standard deviation `sqrt(Var F_P)` in channel `c`. Where the
//! samples carry no pixel-scale noise `sigma'` is negligible and the shrinkage moves nothing
//! visible; where they carry Monte Carlo noise, it removes what the films left.
//!
//! It needs a sample in every pixel (the box pixels `m_P` are SURE's observation) and the
//! noise of at least half the pixels (two samples or more each); otherwise
//! [`estimate`] returns the reason and the caller falls back to the fit.

use serde::Serialize;

use super::noise::PixelNoise;
use super::shrink::{shrink_channel, universal_threshold, ShrinkParams};
use super::statistics::median;
use super::sure::{choose_films, FilmRisks};
use super::EstimateReport;
use crate::image::filters::FilmFilterKind;
use crate::image::splat::PixelBins;
use crate::image::{ImageSamples, PixelImage};

/// Half the side of SURE's window: `(2 h + 1)²` pixels, 17 x 17 (chosen on the Mitsuba
/// renders against 9 x 9 and 33 x 33, `docs/measurements/real-renders.md`).
pub const WINDOW_HALF: usize = 8;

/// Pixels that took one film.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct FilmCount {
    /// The film.
    pub film: FilmFilterKind,
    /// Its pixels.
    pub pixels: usize,
}

/// What `auto` found and did.
#[derive(Debug, Clone, PartialEq)]
pub struct AutoReport {
    /// Pixels per film.
    pub films: Vec<FilmCount>,
    /// Estimated risks.
    pub risk: FilmRisks,
    /// The chosen films' SURE per pixel, averaged over the window ([`super::sure::FilmChoice::window_risk`],
    /// before the shrinkage).
    pub window_risk: Vec<f64>,
    /// The noise of a pixel's mean `sigma_c` ([`PixelNoise::sigma`]).
    pub sigma: Vec<f64>,
    /// Pixels whose noise was estimated.
    pub pixels_with_blocks: usize,
    /// The chosen films' noise `sigma'_c`.
    pub output_noise: Vec<f64>,
    /// The shrinkage's thresholds.
    pub threshold: Vec<f64>,
    /// The shrinkage's parameters.
    pub shrink: ShrinkParams,
}

impl AutoReport {
    /// Writes the fields and the description into `report`.
    pub fn fill(self, report: &mut EstimateReport) {
        let films = self
            .films
            .iter()
            .map(|f| format!("{} {}", f.film, f.pixels))
            .collect::<Vec<_>>()
            .join(", ");
        report.description = format!(
            "pixels: auto, the film of least SURE over the {side} x {side} window around each \
             pixel (pixels per film: {films}) for the noise sigma = {} per channel of a pixel's \
             mean (second differences of adjacent strata, median over {} pixels); then Haar \
             shrinkage ({} shifts) at the universal threshold {} of the chosen films' noise {}",
            super::list(&self.sigma),
            self.pixels_with_blocks,
            self.shrink.shifts * self.shrink.shifts,
            super::list(&self.threshold),
            super::list(&self.output_noise),
            side = 2 * WINDOW_HALF + 1,
        );
        report.films = Some(self.films);
        report.window = Some(2 * WINDOW_HALF + 1);
        report.risk = Some(self.risk);
        report.noise_level = Some(self.sigma);
        report.pixels_with_spread = Some(self.pixels_with_blocks);
        report.output_noise = Some(self.output_noise);
        report.threshold = Some(self.threshold);
        report.shrink = Some(self.shrink);
    }
}

/// The `auto` pixels of `samples`, or why the samples do not permit them.
pub fn estimate(
    samples: &ImageSamples,
    shrink: &ShrinkParams,
) -> Result<(PixelImage, AutoReport), String> {
    let plane = samples.plane();
    let bins = PixelBins::new(samples);
    let pixels = plane.pixels();
    let empty: Vec<usize> = (0..pixels)
        .filter(|&p| bins.in_pixel(p).is_empty())
        .collect();
    if let Some(&first) = empty.first() {
        let w = plane.width();
        return Err(format!(
            "{} pixels have no sample (the first at ({}, {})), and SURE compares each film with \
             the mean of the pixel's own samples",
            empty.len(),
            first % w,
            first / w
        ));
    }
    let noise = PixelNoise::new(samples, &bins)
        .filter(|n| 2 * n.pixels_with_blocks() >= pixels)
        .ok_or_else(|| {
            let two = (0..pixels).filter(|&p| bins.in_pixel(p).len() >= 2).count();
            format!(
                "only {two} of {pixels} pixels have two samples or more, so the noise of a \
                 pixel's mean is unknown (render at least 2 samples per pixel)"
            )
        })?;
    let mean: Vec<Vec<f64>> = samples
        .values()
        .iter()
        .map(|v| {
            (0..pixels)
                .map(|p| {
                    let idx = bins.in_pixel(p);
                    idx.iter().map(|&i| v[i]).sum::<f64>() / idx.len() as f64
                })
                .collect()
        })
        .collect();
    let choice = choose_films(
        samples,
        &bins,
        &noise,
        &mean,
        &FilmFilterKind::ALL,
        WINDOW_HALF,
    );
    let output_noise: Vec<f64> = choice
        .variance
        .iter()
        .map(|v| median(&mut v.clone()).max(0.0).sqrt())
        .collect();
    let threshold: Vec<f64> = output_noise
        .iter()
        .map(|&s| universal_threshold(s, pixels, shrink.threshold_factor))
        .collect();
    let mut image = choice.image.clone();
    for (channel, &t) in image.channels.iter_mut().zip(&threshold) {
        *channel = shrink_channel(channel, plane.width(), plane.height(), t, shrink.shifts);
    }
    let films = choice
        .counts()
        .into_iter()
        .map(|(film, pixels)| FilmCount { film, pixels })
        .collect();
    Ok((
        image,
        AutoReport {
            films,
            risk: choice.risk,
            window_risk: choice.window_risk,
            sigma: noise.sigma.clone(),
            pixels_with_blocks: noise.pixels_with_blocks(),
            output_noise,
            threshold,
            shrink: *shrink,
        },
    ))
}
