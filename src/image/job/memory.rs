//! Every image-plane job's memory, estimated from its sizes before its work: the pixels,
//! channels, samples, `p` and the fit of the request become one [`ImageRequest`]
//! ([`crate::resources`] builds it), whose [`crate::resources::ImageEstimate`] the job
//! refuses above the memory limit ([`super::JobError::TooLarge`]) before it allocates.

use crate::image::adaptive::{AdaptiveParams, TreeSolver};
use crate::image::film_weights::film_cache_bytes;
use crate::image::{ImageMethod, ImagePlane, UniformEstimate};
use crate::resources::{ImageRequest, ImageSolve};

/// The uniform fit (`ImageMethod::Wavelet`, or local inversion with `local`) of `samples`
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
/// per-pixel sample variances a film candidate reads ([`crate::image::estimate::auto`]).
/// Its per-pixel statistics (counts, means, spreads: fewer than these images) are covered.
const AUTO_WORKING_IMAGES: usize = 13;

/// A pixel estimate that uses no fit (`auto`, `box`, `shrunk`) of `samples` samples onto
/// `plane`: the samples, their bins by pixel (8 bytes a sample, counted as half a position),
/// `auto`'s cached film factors ([`film_cache_bytes`], counted as positions of 16 bytes) and
/// the estimate's images; no basis.
pub fn estimate_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    estimate: UniformEstimate,
) -> ImageRequest {
    let (working, cache) = match estimate {
        UniformEstimate::Auto => (
            AUTO_WORKING_IMAGES,
            film_cache_bytes(plane.height(), samples),
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

/// `method`'s reconstruction of `samples` samples of `channels` on `plane`, `images` output
/// images held: the fit's request, or for a film filter the samples, the splat's cached film
/// factors (as positions of 16 bytes) and the images, without a solve.
pub fn method_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    method: ImageMethod,
    p: usize,
    rho: f64,
    images: usize,
) -> ImageRequest {
    let request = uniform_request(
        plane,
        channels,
        samples,
        p,
        rho,
        method == ImageMethod::Local,
        images,
    );
    match method {
        ImageMethod::Film(_) => ImageRequest {
            solve: ImageSolve::None,
            positions: request.positions + film_cache_bytes(plane.height(), samples) / 16.0,
            ..request
        },
        _ => request,
    }
}

/// The adaptive tree fit of `samples` samples on `plane` at the depth limit of `params`
/// ([`ImageRequest::tree`]): the assembled normal matrix and its factor unless the solver is
/// matrix-free PCG.
pub fn tree_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    params: &AdaptiveParams,
    images: usize,
) -> ImageRequest {
    ImageRequest::tree(
        (plane.width(), plane.height()),
        channels,
        samples,
        params.tree.p,
        params.quad.below_pixel,
        params.tree.rho,
        !matches!(params.fit.solver, TreeSolver::Pcg { .. }),
        images,
    )
}
