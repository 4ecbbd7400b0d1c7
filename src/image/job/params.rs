//! The parameters of an image-plane job, in the few groups a user meets.

use crate::error::Param;
use crate::image::estimate::ShrinkParams;
use crate::image::{ImageMethod, UniformEstimate};

/// The parameters of an image-plane job, in the few groups a user meets. Every `Option` left
/// `None` takes the library's default, and counts as not asked for (the default pixel
/// estimate depends on which fit parameters were asked for: `PixelChoice`).
#[derive(Debug, Clone)]
pub struct ImageParams {
    /// How samples become pixels: the least-squares fit ([`ImageMethod::Wavelet`], the default),
    /// its local inversion ([`ImageMethod::Local`]: faster on large images, slightly less
    /// accurate where samples are sparse) or a film filter ([`ImageMethod::Film`], the renderer's
    /// baseline; no fit, no pixel estimate).
    pub method: ImageMethod,
    /// The least-squares fit's basis and regularization (read only where the fit runs).
    pub fit: FitOptions,
    /// The pixel estimate of the fit's path; `None`: [`UniformEstimate::Auto`] (a film per
    /// pixel chosen by SURE, then Haar shrinkage; no fit unless a pixel lacks samples), or
    /// the fit when a fit parameter was asked for (`PixelChoice`).
    pub pixels: Option<UniformEstimate>,
    /// The shrinkage of the noise-aware estimates (threshold scale, levels).
    pub shrink: ShrinkParams,
    /// Settings a front end has that only the fit reads and that these fields do not hold
    /// (the command line's `--family`, `--levels`, `--method global`): asking for them asks
    /// for the fit, as setting a field of [`FitOptions`] does.
    pub also_asked: Vec<Param>,
}

/// The least-squares fit's options (`None`: the default, not asked for).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FitOptions {
    /// Vanishing moments `p`, 1 to 4 (default 2): higher orders reproduce smoother detail
    /// at the cost of wider functions (more samples per function, a slower solve).
    pub p: Option<usize>,
    /// Samples per tensor function (default 4): larger values choose coarser levels (less
    /// noise, less detail).
    pub rho: Option<f64>,
    /// Relative ridge of the normal equations, in `[0, 1)` (default `1e-9`): larger values
    /// pull poorly sampled functions to zero.
    pub ridge: Option<f64>,
    /// Smoothing weight `>= 0` (default 0, the plain least squares): larger values trade
    /// detail for less noise.
    pub smoothing: Option<f64>,
}

impl Default for ImageParams {
    fn default() -> Self {
        ImageParams {
            method: ImageMethod::Wavelet,
            fit: FitOptions::default(),
            pixels: None,
            shrink: ShrinkParams::default(),
            also_asked: Vec::new(),
        }
    }
}

impl ImageParams {
    /// The fit parameters asked for, in the order the messages list them (`p`, the family,
    /// the method, the levels, `rho`, the ridge, the smoothing).
    pub fn fit_asked(&self) -> Vec<Param> {
        let set = [
            (Param::P, self.fit.p.is_some()),
            (Param::Family, self.also_asked.contains(&Param::Family)),
            (
                Param::Method,
                self.method == ImageMethod::Local || self.also_asked.contains(&Param::Method),
            ),
            (Param::Levels, self.also_asked.contains(&Param::Levels)),
            (Param::Rho, self.fit.rho.is_some()),
            (Param::Ridge, self.fit.ridge.is_some()),
            (Param::Smoothing, self.fit.smoothing.is_some()),
        ];
        set.into_iter()
            .filter_map(|(param, asked)| asked.then_some(param))
            .collect()
    }
}
