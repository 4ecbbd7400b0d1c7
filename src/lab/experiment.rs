//! The image-plane experiment: sample a scene, reconstruct pixels by every method from the
//! same samples, measure each against the box-filtered ground truth.
//!
//! One run is: samples `(x_i, y_i)` from a [`Sampler`], values `f_i = L(x_i, y_i) + n_i`
//! (optional Gaussian noise `n_i ~ N(0, sigma^2)` per channel, seeded, because renderer
//! samples are Monte Carlo estimates), then the library's [`reconstruct`] turns them into
//! pixels by one [`ImageMethod`], timed by stage, and [`compare`] measures the result against
//! [`truth_cached`]. A [`Comparison`] runs every method on the same samples (the `table`
//! module beside this one renders it).

use std::path::PathBuf;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::Serialize;
use thiserror::Error;

use crate::image::filters::FilmFilterKind;
use crate::image::metrics::{compare, ImageMetrics};
use crate::image::report::peak_memory_mb;
use crate::image::sampler::Sampler;
use crate::image::scene::Scene;
use crate::image::splat::SplatReport;
use crate::image::truth::{truth_cached, TruthSource, DEFAULT_RATE};
use crate::image::wavelet::{WaveletError, WaveletParams, WaveletReport};
use crate::image::{
    reconstruct, ImageError, ImageMethod, ImagePlane, ImageSamples, PixelImage, StageTimes,
};

/// How the samples are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SamplingParams {
    /// The image resolution.
    pub plane: ImagePlane,
    /// Samples per pixel `s` (`m = s W H`).
    pub spp: usize,
    /// The sampler.
    pub sampler: Sampler,
    /// Standard deviation of the Gaussian noise added to every sample value (0: none).
    pub noise: f64,
    /// Seed of positions and noise.
    pub seed: u64,
}

/// Where the ground truth comes from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TruthParams {
    /// Supersampling rate `n` (`n x n` jittered strata per pixel).
    pub rate: usize,
    /// Cache folder.
    pub cache: PathBuf,
}

impl Default for TruthParams {
    fn default() -> Self {
        Self {
            rate: DEFAULT_RATE,
            cache: PathBuf::from("out/truth"),
        }
    }
}

/// Why a run failed.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ImageRunError {
    /// Invalid samples or resolution.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// Invalid parameters.
    #[error("{parameter} = {value} is invalid: {expected}")]
    Parameter {
        /// The parameter name.
        parameter: &'static str,
        /// Its value as given.
        value: String,
        /// What is expected.
        expected: &'static str,
    },
    /// The wavelet fit failed.
    #[error("the wavelet reconstruction failed: {0}")]
    Wavelet(#[from] WaveletError),
    /// The run would need more memory than the limit: refused before sampling.
    #[error(transparent)]
    Resources(#[from] crate::resources::ResourceError),
}

/// Draws `m = s W H` samples of `scene`: positions from the sampler, RGB values with optional
/// noise (Box–Muller normal deviates from a PCG-64 stream seeded by `seed + 1`).
pub fn sample_scene(scene: &Scene, params: &SamplingParams) -> Result<ImageSamples, ImageRunError> {
    if params.spp == 0 || params.spp > 4096 {
        return Err(ImageRunError::Parameter {
            parameter: "samples per pixel",
            value: params.spp.to_string(),
            expected: "an integer in 1..=4096",
        });
    }
    if params.noise.is_nan() || params.noise < 0.0 || params.noise.is_infinite() {
        return Err(ImageRunError::Parameter {
            parameter: "noise sigma",
            value: params.noise.to_string(),
            expected: "a finite number >= 0",
        });
    }
    let plane = params.plane;
    let (xs, ys) = params.sampler.positions(plane, params.spp, params.seed);
    let mut values: Vec<Vec<f64>> = (0..3).map(|_| Vec::with_capacity(xs.len())).collect();
    for (&x, &y) in xs.iter().zip(&ys) {
        let v = scene.radiance_on(plane, x, y);
        for (channel, value) in values.iter_mut().zip(v) {
            channel.push(value);
        }
    }
    if params.noise > 0.0 {
        let mut rng = Pcg64::seed_from_u64(params.seed.wrapping_add(1));
        for ch in values.iter_mut() {
            for v in ch.iter_mut() {
                *v += params.noise * standard_normal(&mut rng);
            }
        }
    }
    Ok(ImageSamples::new(plane, xs, ys, values)?)
}

/// A standard normal deviate by the Box–Muller transform.
fn standard_normal(rng: &mut Pcg64) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // in (0, 1]
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// One method's image, measured.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// The method.
    pub method: ImageMethod,
    /// Metrics against the truth.
    pub metrics: ImageMetrics,
    /// Timing by stage.
    pub time_s: StageTimes,
    /// This method's total time over the Gaussian film filter's on the same samples (the
    /// issue's ratio wavelet / film), when the comparison ran the Gaussian.
    pub time_over_gaussian: Option<f64>,
    /// Number of basis functions (wavelet methods).
    pub functions: Option<usize>,
    /// The film filter's fallbacks (film methods).
    pub splat: Option<SplatReport>,
    /// The wavelet solve's report (wavelet methods).
    pub solve: Option<WaveletReport>,
    /// Every fallback, lowered level or cut-off, in words.
    pub notes: Vec<String>,
    /// The pixels.
    #[serde(skip)]
    pub image: PixelImage,
}

/// Reconstructs by `method` and measures against `truth`.
pub fn run_method(
    method: ImageMethod,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
    truth: &PixelImage,
) -> Result<MethodResult, ImageRunError> {
    let r = reconstruct(method, samples, wavelet)?;
    Ok(MethodResult {
        method,
        metrics: compare(&r.image, truth),
        time_s: r.time_s,
        time_over_gaussian: None,
        functions: r.functions,
        splat: r.splat,
        solve: r.solve,
        notes: r.notes,
        image: r.image,
    })
}

/// Every requested method on the same samples of one scene.
#[derive(Debug, Clone, Serialize)]
pub struct Comparison {
    /// Scene name.
    pub scene: String,
    /// How the samples were drawn.
    pub sampling: SamplingParams,
    /// Number of samples.
    pub samples: usize,
    /// Ground-truth supersampling rate (`n x n` per pixel).
    pub truth_rate: usize,
    /// Whether the truth came from the cache.
    pub truth_source: TruthSource,
    /// Seconds spent sampling the scene.
    pub sampling_s: f64,
    /// Seconds spent on the ground truth (reading the cache or supersampling).
    pub truth_s: f64,
    /// One row per method.
    pub results: Vec<MethodResult>,
    /// The truth image.
    #[serde(skip)]
    pub truth: PixelImage,
    /// Notes (truth cache not written, ...).
    pub notes: Vec<String>,
}

/// Runs `methods` on one sample set of `scene` and measures them.
pub fn compare_methods(
    scene: &Scene,
    sampling: &SamplingParams,
    methods: &[ImageMethod],
    wavelet: &WaveletParams,
    truth: &TruthParams,
) -> Result<Comparison, ImageRunError> {
    let t0 = Instant::now();
    let samples = sample_scene(scene, sampling)?;
    let sampling_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let (truth_image, truth_source, note) =
        truth_cached(&truth.cache, scene, sampling.plane, truth.rate);
    let truth_s = t1.elapsed().as_secs_f64();
    let mut results = methods
        .iter()
        .map(|&m| run_method(m, &samples, wavelet, &truth_image))
        .collect::<Result<Vec<_>, _>>()?;
    let gaussian = results
        .iter()
        .find(|r| r.method == ImageMethod::Film(FilmFilterKind::Gaussian))
        .map(|r| r.time_s.total);
    if let Some(g) = gaussian.filter(|&g| g > 0.0) {
        for r in &mut results {
            r.time_over_gaussian = Some(r.time_s.total / g);
        }
    }
    Ok(Comparison {
        scene: scene.name().to_string(),
        sampling: *sampling,
        samples: samples.len(),
        truth_rate: truth.rate,
        truth_source,
        sampling_s,
        truth_s,
        results,
        truth: truth_image,
        notes: note.into_iter().collect(),
    })
}

/// Seconds by stage of one image run.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunTimes {
    /// Sampling the scene.
    pub sampling: f64,
    /// Ground truth (cache read or supersampling).
    pub truth: f64,
    /// Fitting (wavelet methods).
    pub fit: f64,
    /// Pixel values (exact box integrals, or the film filter's splat).
    pub pixels: f64,
    /// The method end to end (fit + pixels), sampling and truth excluded.
    pub method: f64,
}

/// The report of one method on one scene (what `rkwave image --json` prints).
#[derive(Debug, Clone, Serialize)]
pub struct ImageReport {
    /// Scene name.
    pub scene: String,
    /// Resolution `WxH`.
    pub resolution: String,
    /// How the samples were drawn.
    pub sampling: SamplingParams,
    /// The method.
    pub method: ImageMethod,
    /// PSNR (dB, peak 1) against the box-filtered truth.
    pub psnr: f64,
    /// RMSE.
    pub rmse: f64,
    /// Relative MSE.
    pub rel_mse: f64,
    /// SSIM.
    pub ssim: f64,
    /// Number of samples.
    pub samples: usize,
    /// Basis functions (wavelet methods).
    pub functions: Option<usize>,
    /// Seconds by stage.
    pub time_s: RunTimes,
    /// Peak resident memory of the process, MB.
    pub peak_mb: Option<f64>,
    /// The wavelet solve's report.
    pub solve: Option<WaveletReport>,
    /// The film filter's fallbacks.
    pub splat: Option<SplatReport>,
    /// Ground-truth supersampling rate (`n x n` per pixel) and where it came from.
    pub truth_rate: usize,
    /// Whether the truth was cached.
    pub truth_source: TruthSource,
    /// Every fallback or cut-off, in words.
    pub notes: Vec<String>,
}

impl ImageReport {
    /// The report of result `k` of a comparison.
    pub fn from_comparison(c: &Comparison, k: usize) -> Self {
        let r = &c.results[k];
        let mut notes = c.notes.clone();
        notes.extend(r.notes.iter().cloned());
        Self {
            scene: c.scene.clone(),
            resolution: c.sampling.plane.to_string(),
            sampling: c.sampling,
            method: r.method,
            psnr: r.metrics.psnr,
            rmse: r.metrics.rmse,
            rel_mse: r.metrics.rel_mse,
            ssim: r.metrics.ssim,
            samples: c.samples,
            functions: r.functions,
            time_s: RunTimes {
                sampling: c.sampling_s,
                truth: c.truth_s,
                fit: r.time_s.fit,
                pixels: r.time_s.pixels,
                method: r.time_s.total,
            },
            peak_mb: peak_memory_mb(),
            solve: r.solve.clone(),
            splat: r.splat,
            truth_rate: c.truth_rate,
            truth_source: c.truth_source,
            notes,
        }
    }
}

impl ImageRunError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ImageRunError::Image(e) => e.kind(),
            ImageRunError::Parameter { .. } => crate::error::ErrorKind::InvalidInput,
            ImageRunError::Wavelet(e) => e.kind(),
            ImageRunError::Resources(e) => e.kind(),
        }
    }
}

crate::error::classified!(ImageRunError);

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn noise_is_seeded() {
        let scene = Scene::from_json(
            r#"{"name":"flat","background":[0.5,0.5,0.5],"layers":[]}"#,
            Path::new("flat.json"),
        )
        .unwrap();
        let params = SamplingParams {
            plane: ImagePlane::new(8, 8).unwrap(),
            spp: 4,
            sampler: Sampler::Stratified,
            noise: 0.1,
            seed: 5,
        };
        let a = sample_scene(&scene, &params).unwrap();
        assert_eq!(a, sample_scene(&scene, &params).unwrap());
        // 256 deviates with sigma 0.1: the sample mean is within 4 sigma / 16 = 0.025 of 0.5.
        let mean = a.channel(0).iter().sum::<f64>() / 256.0;
        assert!((mean - 0.5).abs() < 0.025, "{mean}");
        let bad = SamplingParams { spp: 0, ..params };
        assert!(sample_scene(&scene, &bad).is_err());
    }
}
