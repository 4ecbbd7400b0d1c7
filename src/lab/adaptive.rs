//! Adaptive wavelet against film filters at equal total samples.
//!
//! For one scene and an average of `s` samples per pixel (budget `B = s W H`):
//!
//! * the adaptive wavelet image ([`crate::image::adaptive::refine_image`], budget `B`): its output pixels, by
//!   default the fit as a control variate ([`crate::image::adaptive::correction`]: exact box pixels of the fit
//!   plus the significant mean residual per pixel, clamped to the local sample range);
//! * the fit's exact box pixels alone (row `adaptive wavelet, fit only`), and the fit plus the
//!   mean residual without the range clamp (row `adaptive wavelet, unclamped`);
//! * every film filter and the uniform wavelet engine on `s` stratified samples per pixel
//!   (the renderer's baseline at the same cost);
//! * every film filter on the adaptive sample set (weighted splatting): separates what the
//!   sample placement buys from what the reconstruction buys.
//!
//! With noise `sigma > 0` every sample value carries Gaussian noise of that deviation, the
//! adaptive ones through [`crate::image::adaptive::NoisyOracle`] (seeded by the seed and the position), the
//! stratified ones as in the uniform experiment; the refiner is not told `sigma` (it
//! estimates the noise from its fits' residuals, [`crate::image::adaptive::significance`]).
//!
//! All against the box-filtered ground truth ([`crate::image::truth`]).

use serde::Serialize;

use super::experiment::{run_method, sample_scene, ImageRunError, SamplingParams, TruthParams};
use crate::error::{Fix, Param};
use crate::image::adaptive::{
    refine_image, AdaptiveError, AdaptiveImage, AdaptiveParams, AdaptiveReport, ImageOracle,
    NoisyOracle, SceneOracle, StopParams,
};
use crate::image::filters::FilmFilterKind;
use crate::image::job::memory::tree_request;
use crate::image::metrics::{compare, ImageMetrics};
use crate::image::sampler::Sampler;
use crate::image::scene::Scene;
use crate::image::truth::truth_cached;
use crate::image::{ImageMethod, WaveletParams};
use crate::image::{ImagePlane, ImageSamples, PixelImage};
use crate::resources::{Advice, ImageRequest};

/// Why an adaptive comparison failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum AdaptiveRunError {
    /// The adaptive engine.
    #[error(transparent)]
    Adaptive(#[from] AdaptiveError),
    /// The baselines.
    #[error(transparent)]
    Run(#[from] ImageRunError),
    /// Samples could not be wrapped (an internal error).
    #[error(transparent)]
    Image(#[from] crate::image::ImageError),
}

pub use crate::image::adaptive::correction::RESIDUAL_Z;

/// The method name of the adaptive fit's box pixels alone.
pub const FIT_ONLY: &str = "adaptive wavelet, fit only";

/// The method name of the adaptive fit plus the significant mean residual, not clamped to the
/// local sample range.
pub const UNCLAMPED: &str = "adaptive wavelet, unclamped";

/// One row of the comparison.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveRow {
    /// `adaptive wavelet` (the output pixels), [`FIT_ONLY`], `wavelet`, or a film filter's
    /// name.
    pub method: String,
    /// `adaptive` or `stratified`.
    pub samples_from: &'static str,
    /// Samples used.
    pub samples: usize,
    /// Against the truth.
    pub metrics: ImageMetrics,
    /// Fallbacks in words.
    pub notes: Vec<String>,
}

/// The comparison on one scene.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveComparison {
    /// Scene name.
    pub scene: String,
    /// Resolution.
    pub plane: ImagePlane,
    /// Average samples per pixel.
    pub spp: usize,
    /// Standard deviation of the noise of every sample value (0: noise-free).
    pub noise: f64,
    /// The adaptive run.
    pub adaptive: AdaptiveReport,
    /// Every method.
    pub rows: Vec<AdaptiveRow>,
    /// The best film filter on stratified samples, and its PSNR.
    pub best_uniform_film: (String, f64),
    /// Adaptive wavelet PSNR minus the best uniform film filter's.
    pub gain_db: f64,
    /// Seconds: the adaptive run, end to end (without the rebuilds of
    /// [`crate::image::adaptive::FitParams::measure_rebuild`]).
    pub adaptive_s: f64,
}

/// The images of the comparison (for figures), beside the report.
pub struct AdaptiveOutput {
    /// The report.
    pub comparison: AdaptiveComparison,
    /// The adaptive run (tree, samples, fit).
    pub run: AdaptiveImage,
    /// The adaptive wavelet's output pixels.
    pub image: PixelImage,
    /// The truth.
    pub truth: PixelImage,
}

/// Images of the output's size the adaptive comparison holds at its peak: the adaptive
/// image, its fit-only and unclamped variants, the truth, the depth and sample figures and
/// the film filters' images on the two sample sets, one after the other.
const ADAPTIVE_IMAGES: usize = 8;

/// The memory request of the adaptive comparison at a budget of `budget` samples on `plane`:
/// the tree fit at the depth limit of `params` with its positions and
/// `ADAPTIVE_IMAGES` (8) images ([`tree_request`]).
pub fn adaptive_request(plane: ImagePlane, budget: usize, params: &AdaptiveParams) -> ImageRequest {
    let mut request = tree_request(plane, 3, budget as f64, params, ADAPTIVE_IMAGES);
    request.positions = budget as f64;
    request
}

/// Runs the comparison on `scene` at `spp` samples per pixel on average, sample values with
/// Gaussian noise of deviation `noise` (0: none).
pub fn compare_adaptive(
    scene: &Scene,
    plane: ImagePlane,
    spp: usize,
    noise: f64,
    params: &AdaptiveParams,
    truth: &TruthParams,
) -> Result<AdaptiveOutput, AdaptiveRunError> {
    let budget = spp * plane.pixels();
    if !(noise.is_finite() && noise >= 0.0) {
        return Err(AdaptiveError::Parameter {
            parameter: "noise sigma",
            value: noise.to_string(),
            expected: "a finite deviation >= 0",
        }
        .into());
    }
    // Before the truth and the samples: the tree fit at the depth limit, the budget's
    // positions and the images ([`adaptive_request`]).
    adaptive_request(plane, budget, params)
        .estimate()
        .check_advised(
            || format!("the adaptive image of {plane} at a budget of {budget} samples"),
            || {
                Advice::Fixes(
                    "a smaller {}, {} or {}, or {}",
                    vec![
                        Fix::Set(Param::Budget),
                        Fix::Set(Param::Spp),
                        Fix::Set(Param::Resolution),
                        Fix::SolverPcg,
                    ],
                )
            },
        )
        .map_err(ImageRunError::from)?;
    let (truth_image, _, _) = truth_cached(&truth.cache, scene, plane, truth.rate);
    let t = std::time::Instant::now();
    let params = AdaptiveParams {
        stop: StopParams {
            budget,
            ..params.stop
        },
        ..*params
    };
    let clean = SceneOracle { scene, plane };
    let noisy = NoisyOracle {
        inner: &clean,
        sigma: noise,
        seed: params.sampling.seed.wrapping_add(1),
    };
    let oracle: &dyn ImageOracle = if noise > 0.0 { &noisy } else { &clean };
    let run = refine_image(oracle, plane, &params)?;
    let image = run.image.clone();
    // the measured rebuilds (a diagnostic) are not the run's
    let adaptive_s = t.elapsed().as_secs_f64() - run.report.times.rebuild_s;
    let fit_only = run.fit_pixels()?;
    let mut rows = vec![
        AdaptiveRow {
            method: "adaptive wavelet".into(),
            samples_from: "adaptive",
            samples: run.xs.len(),
            metrics: compare(&image, &truth_image),
            notes: run.report.notes.clone(),
        },
        AdaptiveRow {
            method: FIT_ONLY.into(),
            samples_from: "adaptive",
            samples: run.xs.len(),
            metrics: compare(&fit_only, &truth_image),
            notes: vec!["the fit's box pixels, no residual correction".into()],
        },
    ];
    let sigma = run.report.pixels.sigma;
    let (_, unclamped, correction) = crate::image::adaptive::correction::output_pixels(
        &run.tree,
        &run.fit,
        &run.xs,
        &run.ys,
        &run.values,
        crate::image::adaptive::PixelEstimate::ResidualCorrected,
        sigma,
        params.output.residual_z,
    )?;
    rows.push(AdaptiveRow {
        method: UNCLAMPED.into(),
        samples_from: "adaptive",
        samples: run.xs.len(),
        metrics: compare(&unclamped, &truth_image),
        notes: vec![correction.note()],
    });
    let uniform = sample_scene(
        scene,
        &SamplingParams {
            plane,
            spp,
            sampler: Sampler::Stratified,
            noise,
            seed: params.sampling.seed,
        },
    )?;
    let adaptive_set =
        ImageSamples::new(plane, run.xs.clone(), run.ys.clone(), run.values.clone())?;
    let wavelet = WaveletParams::default();
    let mut methods = vec![ImageMethod::Wavelet];
    methods.extend(FilmFilterKind::ALL.map(ImageMethod::Film));
    for (set, from) in [(&uniform, "stratified"), (&adaptive_set, "adaptive")] {
        for &m in &methods {
            if from == "adaptive" && m == ImageMethod::Wavelet {
                continue;
            }
            let r = run_method(m, set, &wavelet, &truth_image)?;
            rows.push(AdaptiveRow {
                method: m.name().into(),
                samples_from: from,
                samples: set.len(),
                metrics: r.metrics,
                notes: r.notes,
            });
        }
    }
    let best = rows
        .iter()
        .filter(|r| r.samples_from == "stratified" && r.method != "wavelet")
        .max_by(|a, b| a.metrics.psnr.total_cmp(&b.metrics.psnr))
        .map(|r| (r.method.clone(), r.metrics.psnr))
        .expect("five film filters ran");
    let gain_db = rows[0].metrics.psnr - best.1;
    Ok(AdaptiveOutput {
        comparison: AdaptiveComparison {
            scene: scene.name().to_string(),
            plane,
            spp,
            noise,
            adaptive: run.report.clone(),
            rows,
            best_uniform_film: best,
            gain_db,
            adaptive_s,
        },
        run,
        image,
        truth: truth_image,
    })
}

/// A Markdown table of comparisons: one line per scene and spp, PSNR of the adaptive wavelet
/// (its output pixels), the best film filter on stratified samples, the gain, the output
/// without the range clamp, the fit alone, the pixels the residual corrected and the clamp
/// moved, the uniform wavelet, and the best film filter on the adaptive samples.
pub fn adaptive_markdown(rows: &[AdaptiveComparison]) -> String {
    let mut s = String::from(
        "| scene | spp | noise | adaptive wavelet | best film (stratified) | gain dB | unclamped \
         | fit only | corrected (of sampled) | clamped | wavelet (stratified) | best film \
         (adaptive set) | functions | rounds | stop |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for c in rows {
        let psnr = |from: &str, pred: &dyn Fn(&str) -> bool| {
            c.rows
                .iter()
                .filter(|r| r.samples_from == from && pred(&r.method))
                .map(|r| (r.method.clone(), r.metrics.psnr))
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .unwrap_or_default()
        };
        let wav = psnr("stratified", &|m| m == "wavelet");
        let fit = psnr("adaptive", &|m| m == FIT_ONLY);
        let unclamped = psnr("adaptive", &|m| m == UNCLAMPED);
        let film_adaptive = psnr("adaptive", &|m| !m.starts_with("adaptive wavelet"));
        s.push_str(&format!(
            "| {} | {} | {} | {:.2} | {:.2} ({}) | {:+.2} | {:.2} | {:.2} | {} ({}) | {} | {:.2} | \
             {:.2} ({}) | {} | {} | {:?} |\n",
            c.scene,
            c.spp,
            c.noise,
            c.rows[0].metrics.psnr,
            c.best_uniform_film.1,
            c.best_uniform_film.0,
            c.gain_db,
            unclamped.1,
            fit.1,
            c.adaptive.pixels.corrected,
            c.adaptive.pixels.sampled,
            c.adaptive.pixels.clamped,
            wav.1,
            film_adaptive.1,
            film_adaptive.0,
            c.adaptive.functions,
            c.adaptive.rounds.len(),
            c.adaptive.stop,
        ));
    }
    s
}

/// A Markdown table of every row per scene: PSNR of each method on each sample set
/// (`stratified`: the renderer's uniform samples at the same count; `adaptive`: the adaptive
/// run's samples), one line per scene, spp and sample set.
pub fn adaptive_rows_markdown(rows: &[AdaptiveComparison]) -> String {
    let mut methods = vec![
        "adaptive wavelet".to_string(),
        UNCLAMPED.to_string(),
        FIT_ONLY.to_string(),
        "wavelet".to_string(),
    ];
    methods.extend(FilmFilterKind::ALL.map(|k| k.name().to_string()));
    let mut s = format!(
        "| scene | spp | noise | samples from | samples | {} |\n|---|---|---|---|---|{}\n",
        methods.join(" | "),
        "---:|".repeat(methods.len())
    );
    for c in rows {
        for from in ["stratified", "adaptive"] {
            let of = |m: &str| {
                c.rows
                    .iter()
                    .find(|r| r.samples_from == from && r.method == m)
            };
            let samples = methods.iter().find_map(|m| of(m)).map_or(0, |r| r.samples);
            let cells: Vec<String> = methods
                .iter()
                .map(|m| of(m).map_or("—".into(), |r| format!("{:.2}", r.metrics.psnr)))
                .collect();
            s.push_str(&format!(
                "| {} | {} | {} | {from} | {samples} | {} |\n",
                c.scene,
                c.spp,
                c.noise,
                cells.join(" | ")
            ));
        }
    }
    s
}

impl AdaptiveRunError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            AdaptiveRunError::Adaptive(e) => e.kind(),
            AdaptiveRunError::Run(e) => e.kind(),
            AdaptiveRunError::Image(e) => e.kind(),
        }
    }
}

crate::error::classified!(AdaptiveRunError);
