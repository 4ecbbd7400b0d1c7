//! Every image-plane command's memory, checked before its work: the sizes of the request
//! (pixels, channels, samples, `p`, the fit) become one [`ImageRequest`]
//! ([`rkwave::resources`] builds it), whose [`rkwave::resources::ImageEstimate`] is refused
//! above the memory limit with its parts and the flag to change (exit 2), before the samples
//! are read or generated and before the fit.

use std::path::Path;

use rkwave::image::ImagePlane;
use rkwave::resources::{ImageRequest, ImageSolve, ResourceError};

use super::CliError;

/// Refuses `request` above the memory limit; `what` names it, `fix` the flag to change.
pub fn check(request: &ImageRequest, what: String, fix: &str) -> Result<(), CliError> {
    request
        .estimate()
        .check(|| what, || fix.to_string())
        .map_err(CliError::from)
}

/// Before a sample file is read ([`rkwave::resources::check_reading`]).
pub fn check_reading(path: &Path) -> Result<(), CliError> {
    rkwave::resources::check_reading(path, || "split the samples or raise --memory-limit".into())
        .map_err(CliError::from)
}

/// The uniform fit (`Method::Wavelet`, or local inversion with `local`) of `samples`
/// samples on `plane`, `images` output images held ([`ImageRequest::uniform`]).
pub fn uniform_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    p: usize,
    rho: f64,
    local: bool,
    images: usize,
) -> ImageRequest {
    ImageRequest::uniform(
        (plane.width(), plane.height()),
        channels,
        samples,
        p,
        rho,
        local,
        images,
    )
}

/// Images of the output's size `auto` holds beside the output: the value and the variance of
/// each of its five films, the noise of the pixel means, the chosen films' image and the
/// per-pixel sample variances a film candidate reads ([`rkwave::image::estimate::auto`]).
const AUTO_WORKING_IMAGES: usize = 13;

/// A pixel estimate that uses no fit (`auto`, `box`, `shrunk`) of `samples` samples onto
/// `plane` (the file's reading is checked before, [`check_reading`]): the samples, their bins
/// by pixel (8 bytes a sample, counted as half a position), `auto`'s cached film factors
/// ([`rkwave::image::film_weights::film_cache_bytes`], counted as positions of 16 bytes) and
/// the estimate's images; no basis.
pub fn estimate_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    estimate: rkwave::image::UniformEstimate,
) -> ImageRequest {
    let (working, cache) = match estimate {
        rkwave::image::UniformEstimate::Auto => (
            AUTO_WORKING_IMAGES,
            rkwave::image::film_weights::film_cache_bytes(plane.height(), samples),
        ),
        _ => (1, 0.0),
    };
    ImageRequest {
        pixels: plane.pixels() as f64,
        channels,
        samples,
        from_file: false,
        positions: samples / 2.0 + cache / 16.0,
        solve: ImageSolve::None,
        images: 1 + working,
    }
}

/// `method`'s fit of `spp` samples per pixel on `plane` (3 channels, a scene's), with the
/// samples generated (no file) and `images` output images held.
pub fn method_request(
    plane: ImagePlane,
    spp: usize,
    method: rkwave::image::Method,
    p: usize,
    rho: f64,
    images: usize,
) -> ImageRequest {
    use rkwave::image::Method;
    let samples = spp as f64 * plane.pixels() as f64;
    let request = uniform_request(plane, 3, samples, p, rho, method == Method::Local, images);
    match method {
        Method::Film(_) => ImageRequest {
            solve: ImageSolve::None,
            // The splat's cached film factors, as positions of 16 bytes.
            positions: request.positions
                + rkwave::image::film_weights::film_cache_bytes(plane.height(), samples) / 16.0,
            ..request
        },
        _ => request,
    }
}

/// The adaptive tree fit of `samples` samples on `plane` at its depth limit (`direct`: the
/// assembled normal matrix and its factor; otherwise matrix-free; [`ImageRequest::tree`]).
#[allow(clippy::too_many_arguments)]
pub fn tree_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    p: usize,
    below_pixel: u32,
    rho: f64,
    direct: bool,
    images: usize,
) -> ImageRequest {
    ImageRequest::tree(
        (plane.width(), plane.height()),
        channels,
        samples,
        p,
        below_pixel,
        rho,
        direct,
        images,
    )
}

/// The larger of two requests (commands that run their parts one after the other).
pub fn larger(a: ImageRequest, b: ImageRequest) -> ImageRequest {
    a.larger(b)
}

impl From<ResourceError> for CliError {
    fn from(e: ResourceError) -> Self {
        CliError::Resources(e)
    }
}
