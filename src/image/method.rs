//! Samples to pixels, the library's entry point on the image plane: [`reconstruct`] turns
//! scattered samples `(x_i, y_i, f_i)` into a [`PixelImage`] by one [`ImageMethod`] and reports what
//! it did.
//!
//! * [`ImageMethod::Wavelet`] and [`ImageMethod::Local`]: the least-squares fit in the tensor CDV
//!   single-scale space (global solve, or local inversion `c = K~ f`), then each pixel's exact
//!   integral against the pixel filter ([`super::wavelet`]);
//! * [`ImageMethod::Film`]: a film filter's weighted average `I(X, Y) = sum_i w_i f_i / sum_i w_i`,
//!   `w_i = f(x_i - X - 1/2) f(y_i - Y - 1/2)` ([`super::splat`]).
//!
//! [`sample_weights`] gives the same linear map for one pixel: `I(X, Y) = sum_i w_i f_i`.

use std::fmt;
use std::str::FromStr;
use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

use super::equivalent_filter::SampleWeight;
use super::filters::{FilmFilterKind, ParseFilmFilterError};
use super::splat::{splat, SplatReport};
use super::wavelet::{
    wavelet_equivalent_filter, wavelet_image, CoefficientSolve, WaveletError, WaveletParams,
    WaveletReport,
};
use super::{ImageSamples, PixelImage};

/// A way of turning samples into pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(into = "String")]
pub enum ImageMethod {
    /// The wavelet least-squares fit (global solve of the normal equations), box-filtered
    /// exactly over each pixel.
    Wavelet,
    /// The wavelet fit by local inversion (dual kernels), box-filtered exactly.
    Local,
    /// A film filter by weighted splatting.
    Film(FilmFilterKind),
}

impl ImageMethod {
    /// Every method, wavelet first.
    pub fn all() -> Vec<ImageMethod> {
        let mut v = vec![ImageMethod::Wavelet, ImageMethod::Local];
        v.extend(FilmFilterKind::ALL.map(ImageMethod::Film));
        v
    }

    /// The lowercase name (`wavelet`, `local`, `box`, ...).
    pub fn name(self) -> &'static str {
        match self {
            ImageMethod::Wavelet => "wavelet",
            ImageMethod::Local => "local",
            ImageMethod::Film(k) => k.name(),
        }
    }
}

impl From<ImageMethod> for String {
    fn from(m: ImageMethod) -> String {
        m.name().to_string()
    }
}

impl fmt::Display for ImageMethod {
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

impl FromStr for ImageMethod {
    type Err = ParseMethodError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "wavelet" => Ok(ImageMethod::Wavelet),
            "local" => Ok(ImageMethod::Local),
            other => other
                .parse::<FilmFilterKind>()
                .map(ImageMethod::Film)
                .map_err(|ParseFilmFilterError { .. }| ParseMethodError {
                    name: s.to_string(),
                }),
        }
    }
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

/// The pixels of one method and what it did.
#[derive(Debug, Clone)]
pub struct ImageReconstruction {
    /// The pixels.
    pub image: PixelImage,
    /// Seconds by stage.
    pub time_s: StageTimes,
    /// Basis functions (wavelet methods).
    pub functions: Option<usize>,
    /// The film filter's fallbacks (film methods).
    pub splat: Option<SplatReport>,
    /// The wavelet solve's report (wavelet methods).
    pub solve: Option<WaveletReport>,
    /// Every fallback, lowered level or cut-off, in words.
    pub notes: Vec<String>,
}

/// Reconstructs the pixels of `samples` by `method`; `wavelet` sets the wavelet methods (a
/// film filter ignores it).
pub fn reconstruct(
    method: ImageMethod,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
) -> Result<ImageReconstruction, WaveletError> {
    let start = Instant::now();
    let solve = match method {
        ImageMethod::Wavelet => CoefficientSolve::Global,
        ImageMethod::Local => CoefficientSolve::Local,
        ImageMethod::Film(kind) => {
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
            return Ok(ImageReconstruction {
                image,
                time_s: StageTimes {
                    fit: 0.0,
                    pixels: t,
                    total: t,
                },
                functions: None,
                splat: Some(report),
                solve: None,
                notes,
            });
        }
    };
    let out = wavelet_image(samples, wavelet, solve)?;
    let total = start.elapsed().as_secs_f64();
    Ok(ImageReconstruction {
        image: out.image,
        time_s: StageTimes {
            fit: out.fit_s,
            pixels: out.pixels_s,
            total,
        },
        functions: Some(out.report.functions),
        splat: None,
        notes: out.report.notes.clone(),
        solve: Some(out.report),
    })
}

/// The equivalent reconstruction filter of pixel `(px, py)` under `method`: the weight of
/// every sample with a nonzero weight. For a film filter `w_i = f(dx_i) f(dy_i) / sum_j
/// f(dx_j) f(dy_j)` over the samples within the radius (the plain formula; the fallbacks of
/// [`splat`] are not reproduced).
pub fn sample_weights(
    method: ImageMethod,
    samples: &ImageSamples,
    wavelet: &WaveletParams,
    px: usize,
    py: usize,
) -> Result<Vec<SampleWeight>, WaveletError> {
    let plane = samples.plane();
    if px >= plane.width() || py >= plane.height() {
        return Err(WaveletError::PixelOutside {
            x: px,
            y: py,
            width: plane.width(),
            height: plane.height(),
        });
    }
    let solve = match method {
        ImageMethod::Wavelet => CoefficientSolve::Global,
        ImageMethod::Local => CoefficientSolve::Local,
        ImageMethod::Film(kind) => return Ok(film_weights(kind, samples, px, py)),
    };
    wavelet_equivalent_filter(samples, wavelet, solve, px, py)
}

/// `w_i = f(dx_i) f(dy_i) / sum_j f(dx_j) f(dy_j)` of film filter `kind` at pixel `(px, py)`.
fn film_weights(
    kind: FilmFilterKind,
    samples: &ImageSamples,
    px: usize,
    py: usize,
) -> Vec<SampleWeight> {
    let f = kind.build();
    let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
    let mut out: Vec<SampleWeight> = samples
        .xs()
        .iter()
        .zip(samples.ys())
        .enumerate()
        .filter(|(_, (x, y))| (*x - cx).abs() <= f.radius() && (*y - cy).abs() <= f.radius())
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
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_parse() {
        assert_eq!(
            "Lanczos".parse::<ImageMethod>(),
            Ok(ImageMethod::Film(FilmFilterKind::Lanczos))
        );
        assert_eq!("local".parse::<ImageMethod>(), Ok(ImageMethod::Local));
        assert!("bilinear".parse::<ImageMethod>().is_err());
    }
}
