//! The wavelet method on the image plane: fit the samples by least squares in the tensor CDV
//! single-scale space `V_Jx (x) V_Jy` ([`crate::image::fit`]), then take each pixel's value
//! against a pixel filter, exactly ([`crate::image::pixels`]).
//!
//! * `wavelet`: the global solve of the normal equations (Jacobi PCG, or the sparse Cholesky
//!   where it does not converge: [`crate::image::fit::NormalSolver::default_cg`]);
//! * `local`: local inversion of the 2D kernel matrix, `c = K~ f` with `K~ ≈ K^+` from
//!   [`crate::solve::apply_local`] (the paper's dual kernels), on the same basis.
//!
//! **Pixel values.** Per axis the sparse matrix `B[X, k] = int phi_{J,k}(x) w(x - X - 1/2) dx
//! / int w` ([`PixelIntegrals`]) gives the image `I = B_y C B_x^T` per channel
//! ([`filter_image`]). With the box pixel filter (the default, the anti-aliased image) `B[X, k]
//! = int_X^{X+1} phi_{J,k}` is exact to rounding. With a film filter `w` (separable, so
//! `w(dx, dy) = w(dx) w(dy)`), the rows of box, triangle and Mitchell are exact to rounding
//! (piecewise cubic filters); the Gaussian and Lanczos are replaced by cubic interpolants on
//! sub-cells of 1/32 pixel, and the measured `max |w - P w|` is reported.
//!
//! **Equivalent filter.** Pixel value `I = b^T c` with `b = B_y[Y, :] (x) B_x[X, :]`
//! ([`pixel_functional`]). For the global fit `c = G^{-1} K^T f`, so `I = sum_i w_i f_i` with
//! `w_i = K_i . z`, `G z = b` ([`equivalent_filter`]); for local inversion `c = K~ f`, so
//! `w = K~^T b`: the weight each sample receives.

use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

use super::equivalent_filter::{
    equivalent_filter, pixel_functional, FitNormalEquations, SampleWeight,
};
use super::filters::FilmFilterKind;
use super::fit::{
    fit_samples, kernel_matrix_2d, ImageFit, ImageFitError, ImageFitParams, ImageLevels,
    ImageSolveReport, NormalSolver,
};
use super::pixels::{filter_image, FilterQuadrature, PixelError, PixelIntegrals};
use super::{ImageSamples, PixelImage};
use crate::basis::tensor::TensorLevelParams;
use crate::solve::{local_inversion, LocalInversionParams, SolveError};

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
            rho: TensorLevelParams::default().rho,
            ridge: 1e-9,
            smoothing: 0.0,
        }
    }
}

/// How the coefficients of the wavelet method are found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum CoefficientSolve {
    /// The global solve of the normal equations (Jacobi PCG, the sparse Cholesky where it does not converge).
    Global,
    /// Local inversion of the kernel matrix (the paper's dual kernels).
    Local,
}

/// Why the wavelet method could not produce pixels.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum WaveletError {
    /// The fit (basis, samples, solve).
    #[error(transparent)]
    Fit(#[from] ImageFitError),
    /// The pixel integrals or the pixel values.
    #[error(transparent)]
    Pixels(#[from] PixelError),
    /// The local inversion of the equivalent filter.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// The pixel of an equivalent filter lies outside the image.
    #[error(
        "pixel ({x}, {y}) is outside the {width} x {height} image: give a pixel X,Y with \
         0 <= X < W and 0 <= Y < H"
    )]
    PixelOutside {
        /// Column asked for.
        x: usize,
        /// Row asked for.
        y: usize,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
    },
}

/// Weights of magnitude at most this are left out of an equivalent filter's list (the weights
/// of the global fit decay exponentially away from the pixel but never vanish); the sum of all
/// weights is reported separately.
pub const WEIGHT_FLOOR: f64 = 1e-14;

/// What the local inversion did.
#[derive(Debug, Clone, Serialize)]
pub struct LocalReport {
    /// Groups of pivots factored.
    pub groups: usize,
    /// Groups whose singular values were cut.
    pub cut_groups: usize,
    /// Kernel rows with no nonzero (samples outside every support).
    pub empty_rows: usize,
    /// Seconds building `K` and applying `K~`.
    pub seconds: f64,
}

/// How pixel values were taken from the fit.
#[derive(Debug, Clone, Serialize)]
pub struct PixelValuesReport {
    /// The pixel filter: `box` (the integral over the pixel) or a film filter's name.
    pub filter: String,
    /// `true` when every row of `B` is exact to rounding (box, triangle, Mitchell).
    pub exact: bool,
    /// `max |w - P w|` of the film filter against its cubic interpolants (0 when exact).
    pub weight_error: f64,
    /// In words.
    pub description: String,
}

/// What the wavelet solve reports.
#[derive(Debug, Clone, Serialize)]
pub struct WaveletReport {
    /// Number of basis functions `nx ny`.
    pub functions: usize,
    /// Single-scale levels `(Jx, Jy)`.
    pub levels: (u32, u32),
    /// The solve of the fit (its stage times; for the local method, what the normal
    /// equations found about unsampled functions).
    pub solve: Option<ImageSolveReport>,
    /// The local inversion (method `local`).
    pub local: Option<LocalReport>,
    /// How pixel values were taken.
    pub pixel_values: PixelValuesReport,
    /// Fallbacks, lowered levels and ridges, in words.
    pub notes: Vec<String>,
}

/// The pixels of a wavelet fit and its timings.
#[derive(Debug, Clone)]
pub struct WaveletOutput {
    /// Filtered pixels.
    pub image: PixelImage,
    /// Seconds fitting.
    pub fit_s: f64,
    /// Seconds computing pixel values.
    pub pixels_s: f64,
    /// The solve's report.
    pub report: WaveletReport,
}

/// The fit parameters of the wavelet methods: `p`, CDV's family for it, automatic levels at
/// `rho` samples per function, the relative ridge, the global solve (Jacobi PCG, Cholesky fallback) or local
/// inversion with default parameters.
pub fn fit_params(params: &WaveletParams, solve: CoefficientSolve) -> ImageFitParams {
    let mut fit = ImageFitParams {
        p: params.p,
        levels: ImageLevels::Auto(TensorLevelParams {
            rho: params.rho,
            ..TensorLevelParams::default()
        }),
        ridge: params.ridge,
        smoothing: params.smoothing,
        ..ImageFitParams::default()
    };
    if solve == CoefficientSolve::Local {
        fit.solver = NormalSolver::Local(LocalInversionParams::default());
    }
    fit
}

fn solve_notes(r: &ImageSolveReport) -> Vec<String> {
    let mut notes = vec![];
    if let (Some(pin), true) = (&r.pinned, r.smoothing > 0.0) {
        notes.push(format!(
            "{} functions without samples in their support: filled from their neighbours by \
             the smoothing penalty (weight {:e}) over their cells ({:.1} pixels, {:.2}% of the \
             image, within x {:.1}..{:.1}, y {:.1}..{:.1})",
            r.unsampled,
            r.smoothing,
            pin.area_px,
            100.0 * pin.fraction,
            pin.x.0,
            pin.x.1,
            pin.y.0,
            pin.y.1
        ));
    } else if let Some(pin) = &r.pinned {
        notes.push(format!(
            "{} functions without samples in their support: coefficients pinned to 0, so the \
             reconstruction falls to 0 over their cells ({:.1} pixels, {:.2}% of the image, \
             within x {:.1}..{:.1}, y {:.1}..{:.1}; no coarser level is fitted there)",
            r.unsampled,
            pin.area_px,
            100.0 * pin.fraction,
            pin.x.0,
            pin.x.1,
            pin.y.0,
            pin.y.1
        ));
    }
    if r.undersampled > 0 {
        notes.push(format!(
            "{} functions with fewer samples than neighbours (undersampled), ridge {:e}",
            r.undersampled, r.ridge
        ));
    }
    if let Some(f) = &r.factor {
        if f.replaced_pivots > 0 {
            notes.push(format!(
                "{} Cholesky pivots replaced (undetermined directions set to about 0)",
                f.replaced_pivots
            ));
        }
        if f.ridge_retries > 0 {
            notes.push(format!(
                "Cholesky retried {} times with the ridge times 100 (final ridge {:e})",
                f.ridge_retries, r.ridge
            ));
        }
    }
    if let Some(why) = r.cg.as_ref().and_then(|cg| cg.fallback.as_ref()) {
        notes.push(why.clone());
    }
    if let Some(local) = &r.local {
        notes.extend(local.warnings());
    }
    notes
}

/// The pixel matrices `(B_x, B_y)` of a fit for `filter` (`None` or the box: exact box
/// integrals) and how they were made.
pub fn pixel_matrices(
    fit: &ImageFit,
    filter: Option<FilmFilterKind>,
) -> Result<(PixelIntegrals, PixelIntegrals, PixelValuesReport), PixelError> {
    let (w, h) = (fit.basis().width(), fit.basis().height());
    match filter {
        None | Some(FilmFilterKind::Box) => {
            let bx = PixelIntegrals::new(fit.scale_x(), w)?;
            let by = PixelIntegrals::new(fit.scale_y(), h)?;
            let report = PixelValuesReport {
                filter: "box".into(),
                exact: true,
                weight_error: 0.0,
                description: "exact integral of the reconstruction over each pixel".into(),
            };
            Ok((bx, by, report))
        }
        Some(kind) => {
            let f = kind.build();
            let q = FilterQuadrature::default();
            let bx = PixelIntegrals::filtered(fit.scale_x(), w, f.as_ref(), q)?;
            let by = PixelIntegrals::filtered(fit.scale_y(), h, f.as_ref(), q)?;
            let exact = f.cubic_pieces().is_some();
            let weight_error = bx.weight_error().max(by.weight_error());
            let description = if exact {
                format!(
                    "film filter {kind} applied to the reconstruction, exact (piecewise cubic \
                     filter), renormalized over the image at its border"
                )
            } else {
                format!(
                    "film filter {kind} applied to the reconstruction: the filter replaced by \
                     cubic interpolants on sub-cells of {} pixel (max |w - Pw| = {weight_error:.1e}, \
                     relative to w(0) = {:.3}), integrated exactly; renormalized over the image \
                     at its border",
                    q.sub_cell,
                    f.eval(0.0)
                )
            };
            let report = PixelValuesReport {
                filter: kind.name().into(),
                exact,
                weight_error,
                description,
            };
            Ok((bx, by, report))
        }
    }
}

/// Fits `samples` (the global solve or local inversion) and filters every pixel.
pub fn wavelet_image(
    samples: &ImageSamples,
    params: &WaveletParams,
    solve: CoefficientSolve,
) -> Result<WaveletOutput, WaveletError> {
    let t0 = Instant::now();
    let fit = fit_samples(samples, &fit_params(params, solve))?;
    let fit_s = t0.elapsed().as_secs_f64();
    let notes = solve_notes(&fit.report);
    let mut solve = fit.report.clone();
    let local_report = solve.local.take().map(|s| LocalReport {
        groups: s.n_groups,
        cut_groups: s.cut_groups,
        empty_rows: s.empty_rows,
        seconds: solve.timings.factor_s,
    });
    let t1 = Instant::now();
    let (bx, by, pixel_values) = pixel_matrices(&fit, params.pixel_filter)?;
    let mut image = PixelImage::zeros(samples.plane(), fit.channels());
    for (out, c) in image.channels.iter_mut().zip(&fit.coefficients) {
        *out = filter_image(&by, &bx, c)?;
    }
    let pixels_s = t1.elapsed().as_secs_f64();
    Ok(WaveletOutput {
        image,
        fit_s,
        pixels_s,
        report: WaveletReport {
            functions: fit.basis().len(),
            levels: fit.basis().levels(),
            solve: Some(solve),
            local: local_report,
            pixel_values,
            notes,
        },
    })
}

/// The weight of every sample in pixel `(px, py)` of the wavelet reconstruction (the global
/// fit or local inversion) with the pixel filter of `params` (module docs); weights of
/// magnitude at most [`WEIGHT_FLOOR`] are left out.
pub fn wavelet_equivalent_filter(
    samples: &ImageSamples,
    params: &WaveletParams,
    solve: CoefficientSolve,
    px: usize,
    py: usize,
) -> Result<Vec<SampleWeight>, WaveletError> {
    // The global fit's factor is needed for G z = b; local inversion needs only the basis.
    let fit = fit_samples(samples, &fit_params(params, CoefficientSolve::Global))?;
    let (bx, by, _) = pixel_matrices(&fit, params.pixel_filter)?;
    let weights = if solve == CoefficientSolve::Local {
        let k = kernel_matrix_2d(fit.basis(), samples.xs(), samples.ys())?;
        let li = local_inversion(&k, &LocalInversionParams::default())?;
        if px >= bx.pixels() || py >= by.pixels() {
            return Err(WaveletError::PixelOutside {
                x: px,
                y: py,
                width: bx.pixels(),
                height: by.pixels(),
            });
        }
        let b = pixel_functional(&by, &bx, px, py);
        // K~ is P x m in CSC: column i holds the dual kernel of sample i, w_i = K~[:, i] . b.
        li.pinv
            .outer_iterator()
            .map(|col| col.iter().map(|(k, v)| v * b[k]).sum())
            .collect()
    } else {
        let normal = FitNormalEquations::new(&fit, samples.xs(), samples.ys())?;
        equivalent_filter(&normal, &by, &bx, px, py)?.weights
    };
    Ok(weights
        .into_iter()
        .enumerate()
        .filter(|(_, w)| w.abs() > WEIGHT_FLOOR)
        .map(|(index, weight)| SampleWeight {
            index,
            x: samples.xs()[index],
            y: samples.ys()[index],
            weight,
        })
        .collect())
}

impl WaveletError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            WaveletError::Fit(e) => e.kind(),
            WaveletError::Pixels(e) => e.kind(),
            WaveletError::Solve(e) => e.kind(),
            WaveletError::PixelOutside { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(WaveletError);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::sampler::Sampler;
    use crate::image::ImagePlane;

    fn samples(plane: ImagePlane, f: impl Fn(f64, f64) -> f64) -> (ImageSamples, Vec<f64>) {
        let (xs, ys) = Sampler::Stratified.positions(plane, 4, 3);
        let v: Vec<f64> = xs.iter().zip(&ys).map(|(&x, &y)| f(x, y)).collect();
        (
            ImageSamples::new(plane, xs, ys, vec![v.clone()]).unwrap(),
            v,
        )
    }

    #[test]
    fn equivalent_filter_reproduces_the_pixel_and_sums_to_one() {
        let plane = ImagePlane::new(16, 12).unwrap();
        let (samples, f) = samples(plane, |x, y| (0.3 * x).sin() + 0.05 * y * y);
        use CoefficientSolve::{Global, Local};
        for (solve, filter) in [
            (Global, None),
            (Local, None),
            (Global, Some(FilmFilterKind::Gaussian)),
            (Global, Some(FilmFilterKind::Mitchell)),
        ] {
            let local = solve == Local;
            let params = WaveletParams {
                pixel_filter: filter,
                ..WaveletParams::default()
            };
            let out = wavelet_image(&samples, &params, solve).unwrap();
            let weights = wavelet_equivalent_filter(&samples, &params, solve, 7, 5).unwrap();
            // I = b^T c and sum_i w_i f_i are the same linear algebra in another order (two
            // solves with one factor, or one sparse K~); agreement to 1e-9 of values of size 1
            // (the dropped weights, below 1e-14 each, add at most m 1e-14 = 8e-12).
            let value: f64 = weights.iter().map(|w| w.weight * f[w.index]).sum();
            let pixel = out.image.get(0, 7, 5);
            assert!(
                (value - pixel).abs() < 1e-9,
                "local {local} {filter:?}: {value} against {pixel}"
            );
            // The basis reproduces constants and every pixel functional is normalized, so the
            // weights of a constant image sum to one: up to the ridge's bias of about 1e-9 for
            // the global fit; local inversion's K~ is only an approximate pseudo-inverse
            // (K~ K = I only approximately), measured 0.9966 here, so 1e-2 for it.
            let total: f64 = weights.iter().map(|w| w.weight).sum();
            let tolerance = if local { 1e-2 } else { 1e-6 };
            assert!(
                (total - 1.0).abs() < tolerance,
                "local {local} {filter:?}: {total}"
            );
        }
        // The box film filter of radius 1/2 is the box pixel.
        let boxed = WaveletParams {
            pixel_filter: Some(FilmFilterKind::Box),
            ..WaveletParams::default()
        };
        let a = wavelet_image(&samples, &WaveletParams::default(), Global).unwrap();
        let b = wavelet_image(&samples, &boxed, Global).unwrap();
        assert_eq!(a.image.channels, b.image.channels);
    }

    /// Box pixels of the fit of a tensor polynomial of degree `< p` per axis are its exact
    /// pixel integrals: the fit reproduces the polynomial (no noise, every function sampled),
    /// and `B` integrates the basis exactly. Tolerance: least squares on data of size up to 5
    /// with a relative ridge of 1e-9, whose bias is amplified at the border functions
    /// (measured 5e-8 for p = 3 on this size through the CLI), far below the 1e-3 a
    /// quadrature of the non-polynomial scaling functions would leave at edges.
    #[test]
    fn box_pixels_of_a_reproduced_polynomial_are_its_integrals() {
        // 40 x 36 pixels: at p = 3 the smallest level allowed, 5, has 32 functions per axis,
        // so every function has about 5 samples (a smaller image would be undersampled).
        let (w, h) = (40, 36);
        let plane = ImagePlane::new(w, h).unwrap();
        for p in [2usize, 3] {
            // (1 + 0.1 x + 0.05 x^2 [p = 3]) (0.5 - 0.03 y + 0.004 y^2 [p = 3])
            let q = if p == 3 { 1.0 } else { 0.0 };
            let fx = move |x: f64| 1.0 + 0.1 * x + q * 0.005 * x * x;
            let fy = move |y: f64| 0.5 - 0.03 * y + q * 0.004 * y * y;
            let ix = move |a: f64, b: f64| {
                let f = |x: f64| x + 0.05 * x * x + q * 0.005 * x * x * x / 3.0;
                f(b) - f(a)
            };
            let iy = move |a: f64, b: f64| {
                let f = |y: f64| 0.5 * y - 0.015 * y * y + q * 0.004 * y * y * y / 3.0;
                f(b) - f(a)
            };
            let (s, _) = samples(plane, |x, y| fx(x) * fy(y));
            let params = WaveletParams {
                p,
                ..WaveletParams::default()
            };
            let out = wavelet_image(&s, &params, CoefficientSolve::Global).unwrap();
            assert!(out.report.pixel_values.exact);
            let mut worst: f64 = 0.0;
            for py in 0..h {
                for px in 0..w {
                    let exact = ix(px as f64, px as f64 + 1.0) * iy(py as f64, py as f64 + 1.0);
                    worst = worst.max((out.image.get(0, px, py) - exact).abs());
                }
            }
            assert!(worst < 1e-6, "p = {p}: worst pixel error {worst:e}");
        }
    }
}
