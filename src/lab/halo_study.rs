//! The 2D local-vs-global report for tiles: the tiled image
//! ([`crate::image::tiles::reconstruct_tiled`]) against the untiled fit solved exactly (the
//! sparse Cholesky, [`NormalSolver::Cholesky`], as every tile is; the default's CG would add
//! its own stopping error to the difference) on the same samples, per halo width, `p` and
//! noise level: `max |I_tiled - I|`, that over the value range `max I - min I` of the untiled
//! image, and `PSNR = 10 log10(range^2 / mean (I_tiled - I)^2)`; beside it the untiled fit's
//! own error against the scene's box-filtered truth (RMSE), the scale the difference must be
//! well below.

use std::time::Instant;

use serde::Serialize;

use super::experiment::{sample_scene, ImageRunError, SamplingParams};
use crate::image::fit::{fit_samples, NormalSolver};
use crate::image::pixels::filter_image;
use crate::image::scene::Scene;
use crate::image::tiles::{reconstruct_tiled, TileGeometry, TiledError, TiledInput, TiledParams};
use crate::image::truth::box_truth;
use crate::image::wavelet::{fit_params, pixel_matrices, CoefficientSolve, WaveletParams};
use crate::image::PixelImage;

/// What the study runs.
#[derive(Debug, Clone, Serialize)]
pub struct HaloStudyParams {
    /// Resolution, samples per pixel, sampler, seed (the noise is set per row).
    pub sampling: SamplingParams,
    /// Tile size `T`.
    pub tile: usize,
    /// Halo widths, pixels.
    pub halos: Vec<usize>,
    /// Vanishing moments.
    pub ps: Vec<usize>,
    /// Noise standard deviations (0: noise-free).
    pub noises: Vec<f64>,
    /// Supersampling rate of the truth (`n x n` per pixel).
    pub truth_rate: usize,
}

/// One row: one `(p, noise, halo)`.
#[derive(Debug, Clone, Serialize)]
pub struct HaloRow {
    /// Vanishing moments.
    pub p: usize,
    /// Noise standard deviation.
    pub noise: f64,
    /// Halo, pixels.
    pub halo: usize,
    /// `max |I_tiled - I|` over all pixels and channels.
    pub max_abs: f64,
    /// `max_abs` over the untiled image's value range.
    pub max_rel: f64,
    /// PSNR of the tiled image against the untiled one, peak the value range (dB).
    pub psnr_db: f64,
    /// RMSE of the untiled fit against the truth (its own error).
    pub fit_rmse: f64,
    /// Seconds of the tiled fit (the machine may be shared).
    pub tiled_s: f64,
    /// Seconds of the untiled fit.
    pub untiled_s: f64,
}

/// The study's result.
#[derive(Debug, Clone, Serialize)]
pub struct HaloStudy {
    /// The scene's name.
    pub scene: String,
    /// What was run.
    pub params: HaloStudyParams,
    /// One row per `(p, noise, halo)`.
    pub rows: Vec<HaloRow>,
}

/// Why the study failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum HaloStudyError {
    /// Sampling or the untiled fit.
    #[error(transparent)]
    Run(#[from] ImageRunError),
    /// The tiled fit.
    #[error(transparent)]
    Tiled(#[from] TiledError),
}

fn range(image: &PixelImage) -> f64 {
    let (lo, hi) = image
        .channels
        .iter()
        .flatten()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    (hi - lo).max(f64::MIN_POSITIVE)
}

fn differences(a: &PixelImage, b: &PixelImage) -> (f64, f64) {
    let (mut max, mut se, mut n) = (0.0f64, 0.0, 0usize);
    for (x, y) in a.channels.iter().flatten().zip(b.channels.iter().flatten()) {
        let d = x - y;
        max = max.max(d.abs());
        se += d * d;
        n += 1;
    }
    (max, se / n.max(1) as f64)
}

/// The untiled fit of `samples` solved by the sparse Cholesky, as box (or `params`'s filter)
/// pixels.
fn exact_untiled(
    samples: &crate::image::ImageSamples,
    wavelet: &WaveletParams,
) -> Result<PixelImage, ImageRunError> {
    let mut params = fit_params(wavelet, CoefficientSolve::Global);
    params.solver = NormalSolver::Cholesky;
    let fit = fit_samples(samples, &params).map_err(crate::image::wavelet::WaveletError::from)?;
    let (bx, by, _) = pixel_matrices(&fit, wavelet.pixel_filter)
        .map_err(crate::image::wavelet::WaveletError::from)?;
    let mut image = PixelImage::zeros(samples.plane(), fit.channels());
    for (out, c) in image.channels.iter_mut().zip(&fit.coefficients) {
        *out = filter_image(&by, &bx, c).map_err(crate::image::wavelet::WaveletError::from)?;
    }
    Ok(image)
}

/// Runs the study on `scene` (module docs).
pub fn halo_study(scene: &Scene, params: &HaloStudyParams) -> Result<HaloStudy, HaloStudyError> {
    let plane = params.sampling.plane;
    let truth = box_truth(scene, plane, params.truth_rate);
    let mut rows = Vec::new();
    for &noise in &params.noises {
        let samples = sample_scene(
            scene,
            &SamplingParams {
                noise,
                ..params.sampling
            },
        )?;
        for &p in &params.ps {
            let wavelet = WaveletParams {
                p,
                ..WaveletParams::default()
            };
            let t = Instant::now();
            let untiled = exact_untiled(&samples, &wavelet)?;
            let untiled_s = t.elapsed().as_secs_f64();
            let (_, fit_mse) = differences(&untiled, &truth);
            let r = range(&untiled);
            for &halo in &params.halos {
                let geometry = TileGeometry::new(plane, params.tile, halo)
                    .map_err(|e| TiledError::Tile(e.into()))?;
                let t = Instant::now();
                let tiled = reconstruct_tiled(
                    TiledInput::Samples(&samples),
                    &geometry,
                    &wavelet,
                    &TiledParams::default(),
                    &|_| {},
                )?;
                let tiled_s = t.elapsed().as_secs_f64();
                let (max_abs, mse) = differences(&tiled.image, &untiled);
                rows.push(HaloRow {
                    p,
                    noise,
                    halo,
                    max_abs,
                    max_rel: max_abs / r,
                    psnr_db: 10.0 * (r * r / mse).log10(),
                    fit_rmse: fit_mse.sqrt(),
                    tiled_s,
                    untiled_s,
                });
            }
        }
    }
    Ok(HaloStudy {
        scene: scene.name().to_string(),
        params: params.clone(),
        rows,
    })
}

impl HaloStudy {
    /// The rows as a Markdown table.
    pub fn markdown(&self) -> String {
        let mut out = String::from(
            "| p | noise | halo | max abs | max / range | PSNR (dB) | untiled fit RMSE vs truth | tiled s | untiled s |\n\
             |---|---|---|---|---|---|---|---|---|\n",
        );
        for r in &self.rows {
            out.push_str(&format!(
                "| {} | {} | {} | {:.2e} | {:.2e} | {:.1} | {:.2e} | {:.2} | {:.2} |\n",
                r.p,
                r.noise,
                r.halo,
                r.max_abs,
                r.max_rel,
                r.psnr_db,
                r.fit_rmse,
                r.tiled_s,
                r.untiled_s
            ));
        }
        out
    }
}
