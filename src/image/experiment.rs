//! The image-plane experiment: sample a scene, reconstruct pixels by every method from the
//! same samples, measure each against the box-filtered ground truth.
//!
//! One run is: samples `(x_i, y_i)` from a [`Sampler`], values
//! `f_i = L(x_i, y_i) + n_i` (optional Gaussian noise `n_i ~ N(0, sigma^2)` per channel,
//! seeded, because renderer samples are Monte Carlo estimates), then a [`Method`] turns them into pixels, timed by
//! stage, and [`metrics::compare`](super::metrics::compare) measures the result against
//! [`truth_cached`]. A [`Comparison`] runs every method on the same samples and renders its
//! table as CSV and Markdown.

use std::fmt;
use std::path::PathBuf;
use std::str::FromStr;
use std::time::Instant;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::Serialize;
use thiserror::Error;

use super::filters::{FilmFilterKind, ParseFilmFilterError};
use super::metrics::{compare, ImageMetrics};
use super::sampler::Sampler;
use super::scene::Scene;
use super::splat::{splat, SplatReport};
use super::truth::{truth_cached, TruthSource};
use super::wavelet::{wavelet_image, WaveletReport};
use super::{ImageError, ImagePlane, ImageSamples, PixelImage};

/// A way of turning samples into pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(into = "String")]
pub enum Method {
    /// The wavelet least-squares fit (global solve of the normal equations), box-filtered
    /// exactly over each pixel.
    Wavelet,
    /// The wavelet fit by local inversion (dual kernels), box-filtered exactly.
    Local,
    /// A film filter by weighted splatting.
    Film(FilmFilterKind),
}

impl Method {
    /// Every method, wavelet first.
    pub fn all() -> Vec<Method> {
        let mut v = vec![Method::Wavelet, Method::Local];
        v.extend(FilmFilterKind::ALL.map(Method::Film));
        v
    }

    /// The lowercase name (`wavelet`, `local`, `box`, ...).
    pub fn name(self) -> &'static str {
        match self {
            Method::Wavelet => "wavelet",
            Method::Local => "local",
            Method::Film(k) => k.name(),
        }
    }
}

impl From<Method> for String {
    fn from(m: Method) -> String {
        m.name().to_string()
    }
}

impl fmt::Display for Method {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A method name that is not `wavelet`, `local` or a film filter.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error(
    "unknown method `{name}`: expected wavelet, local, box, triangle, gaussian, mitchell or \
     lanczos"
)]
pub struct ParseMethodError {
    /// The name as given.
    pub name: String,
}

impl FromStr for Method {
    type Err = ParseMethodError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "wavelet" => Ok(Method::Wavelet),
            "local" => Ok(Method::Local),
            other => other.parse::<FilmFilterKind>().map(Method::Film).map_err(
                |ParseFilmFilterError { .. }| ParseMethodError {
                    name: s.to_string(),
                },
            ),
        }
    }
}

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

/// Parameters of the wavelet methods.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct WaveletParams {
    /// Vanishing moments `p` (2 or 3 are practical in 2D).
    pub p: usize,
    /// The pixel filter applied to the reconstruction: `None` is the box over the pixel (the
    /// anti-aliased image), or a film filter integrated against the fit.
    pub pixel_filter: Option<FilmFilterKind>,
    /// Target samples per single-scale function `rho = m / (nx ny)`, which sets the level per
    /// axis ([`crate::basis::tensor::auto_level`]): 4 at 4 samples per pixel is one function
    /// per pixel, 16 one per 2 x 2 pixels, 1 four per pixel.
    pub rho: f64,
    /// Relative ridge `lambda` on the equilibrated normal matrix (`G + lambda diag(G)`):
    /// `1e-9` guards undetermined directions and leaves the least-squares fit unchanged to
    /// about that relative size; larger values shrink weakly determined coefficients.
    pub ridge: f64,
    /// Relative weight of the first-difference penalty on neighbouring coefficients
    /// ([`crate::image::fit::ImageFitParams::smoothing`]); 0, the least-squares fit, by
    /// default.
    pub smoothing: f64,
}

impl Default for WaveletParams {
    fn default() -> Self {
        Self {
            p: 2,
            pixel_filter: None,
            rho: crate::basis::tensor::TensorLevelParams::default().rho,
            ridge: 1e-9,
            smoothing: 0.0,
        }
    }
}

/// The weight one sample receives in one pixel's value.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SampleWeight {
    /// Sample index.
    pub index: usize,
    /// Its x position.
    pub x: f64,
    /// Its y position.
    pub y: f64,
    /// Its weight `w_i` (`I(X, Y) = sum_i w_i f_i`).
    pub weight: f64,
}

/// The equivalent reconstruction filter of pixel `(px, py)` under `method`: the weight of
/// every sample with a nonzero weight. For a film filter `w_i = f(dx_i) f(dy_i) / sum_j
/// f(dx_j) f(dy_j)` over the samples within the radius (the plain formula; the fallbacks of
/// [`splat`] are not reproduced).
pub fn equivalent_filter(
    method: Method,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
    px: usize,
    py: usize,
) -> Result<Vec<SampleWeight>, ImageRunError> {
    let plane = samples.plane();
    if px >= plane.width() || py >= plane.height() {
        return Err(ImageRunError::Parameter {
            parameter: "pixel of the equivalent filter",
            value: format!("{px},{py}"),
            expected: "a pixel X,Y with 0 <= X < W and 0 <= Y < H",
        });
    }
    match method {
        Method::Film(kind) => {
            let f = kind.build();
            let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
            let mut out: Vec<SampleWeight> = samples
                .xs()
                .iter()
                .zip(samples.ys())
                .enumerate()
                .filter(|(_, (x, y))| {
                    (*x - cx).abs() <= f.radius() && (*y - cy).abs() <= f.radius()
                })
                .map(|(index, (&x, &y))| SampleWeight {
                    index,
                    x,
                    y,
                    weight: f.eval_2d(x - cx, y - cy),
                })
                .filter(|s| s.weight != 0.0)
                .collect();
            let total: f64 = out.iter().map(|s| s.weight).sum();
            out.iter_mut().for_each(|s| s.weight /= total);
            Ok(out)
        }
        Method::Wavelet | Method::Local => super::wavelet::wavelet_equivalent_filter(
            samples,
            wavelet,
            method == Method::Local,
            px,
            py,
        ),
    }
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
            rate: super::truth::DEFAULT_RATE,
            cache: PathBuf::from("out/truth"),
        }
    }
}

/// Why a run failed.
#[derive(Debug, Error)]
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
    Wavelet(String),
    /// A sample table has the wrong number of columns for the image plane.
    #[error(
        "image samples need 3 to 6 columns `x, y, c1[, c2, c3, c4]` (positions in pixel \
         units, 1 to 4 channels), found {columns}"
    )]
    Columns {
        /// Columns found.
        columns: usize,
    },
}

/// Image samples from a sample table read by [`crate::io::read_samples`]: its position column
/// is `x`, its first value column `y`, the others the channels.
pub fn image_samples_from_table(
    table: crate::io::SampleSet,
    plane: ImagePlane,
) -> Result<ImageSamples, ImageRunError> {
    let columns = 1 + table.channels();
    if !(3..=6).contains(&columns) {
        return Err(ImageRunError::Columns { columns });
    }
    let mut values = table.values;
    let ys = values.remove(0);
    Ok(ImageSamples::new(plane, table.positions, ys, values)?)
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

/// Seconds per stage of one method.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct StageTimes {
    /// Fitting (normal equations and solve) — 0 for film filters.
    pub fit: f64,
    /// Pixel values from the fit (exact box integrals) or the weighted splat.
    pub pixels: f64,
    /// Total of the method (sampling and truth excluded).
    pub total: f64,
}

/// One method's image, measured.
#[derive(Debug, Clone, Serialize)]
pub struct MethodResult {
    /// The method.
    pub method: Method,
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

/// Reconstructs pixels from `samples` by `method`, timed; not yet measured.
pub fn reconstruct(
    method: Method,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
) -> Result<(PixelImage, StageTimes, MethodExtras), ImageRunError> {
    let start = Instant::now();
    match method {
        Method::Film(kind) => {
            let filter = kind.build();
            let (image, report) = splat(samples, filter.as_ref());
            let t = start.elapsed().as_secs_f64();
            let mut notes = vec![];
            if report.cancelled_pixels > 0 {
                notes.push(format!(
                    "{} pixels with cancelling weights averaged with |w|",
                    report.cancelled_pixels
                ));
            }
            if report.empty_pixels > 0 {
                notes.push(format!(
                    "{} pixels without samples within the radius took the nearest samples' mean",
                    report.empty_pixels
                ));
            }
            Ok((
                image,
                StageTimes {
                    fit: 0.0,
                    pixels: t,
                    total: t,
                },
                MethodExtras {
                    splat: Some(report),
                    notes,
                    ..MethodExtras::default()
                },
            ))
        }
        Method::Wavelet | Method::Local => {
            let local = method == Method::Local;
            let out = wavelet_image(samples, wavelet, local)?;
            let total = start.elapsed().as_secs_f64();
            Ok((
                out.image,
                StageTimes {
                    fit: out.fit_s,
                    pixels: out.pixels_s,
                    total,
                },
                MethodExtras {
                    functions: Some(out.report.functions),
                    notes: out.report.notes.clone(),
                    solve: Some(out.report),
                    ..MethodExtras::default()
                },
            ))
        }
    }
}

/// What a method reports besides its pixels.
#[derive(Debug, Clone, Default)]
pub struct MethodExtras {
    /// Basis functions (wavelet methods).
    pub functions: Option<usize>,
    /// Splat fallbacks (film methods).
    pub splat: Option<SplatReport>,
    /// Solve report (wavelet methods).
    pub solve: Option<WaveletReport>,
    /// Fallbacks in words.
    pub notes: Vec<String>,
}

/// Reconstructs by `method` and measures against `truth`.
pub fn run_method(
    method: Method,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
    truth: &PixelImage,
) -> Result<MethodResult, ImageRunError> {
    let (image, time_s, extras) = reconstruct(method, samples, wavelet)?;
    Ok(MethodResult {
        method,
        metrics: compare(&image, truth),
        time_s,
        time_over_gaussian: None,
        functions: extras.functions,
        splat: extras.splat,
        solve: extras.solve,
        notes: extras.notes,
        image,
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
    methods: &[Method],
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
        .find(|r| r.method == Method::Film(FilmFilterKind::Gaussian))
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

/// Peak resident memory of this process so far (`VmHWM` of `/proc/self/status`), in MB;
/// `None` where that file does not exist.
pub fn peak_memory_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
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
    pub method: Method,
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

pub use super::table::{
    comparison_csv, comparison_markdown, comparison_times_markdown, CSV_HEADER,
};

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn methods_parse_and_noise_is_seeded() {
        assert_eq!(
            "Lanczos".parse::<Method>(),
            Ok(Method::Film(FilmFilterKind::Lanczos))
        );
        assert_eq!("local".parse::<Method>(), Ok(Method::Local));
        assert!("bilinear".parse::<Method>().is_err());
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
