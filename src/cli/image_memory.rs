//! Every image-plane command's memory, checked before its work: the sizes of the request
//! (pixels, channels, samples, `p`, the fit) become one [`ImageRequest`], whose
//! [`rkwave::resources::ImageEstimate`] is refused above the memory limit with its parts and
//! the flag to change (exit 2), before the samples are read or generated and before the fit.

use std::path::Path;

use rkwave::image::ImagePlane;
use rkwave::resources::{
    tree_levels, uniform_image_functions, ImageRequest, ImageSolve, ResourceError,
};

use super::CliError;

/// Refuses `request` above the memory limit; `what` names it, `fix` the flag to change.
pub fn check(request: &ImageRequest, what: String, fix: &str) -> Result<(), CliError> {
    request
        .estimate()
        .check(|| what, || fix.to_string())
        .map_err(CliError::from)
}

/// Before a sample file is read: reading holds its bytes, the decoded table and the samples
/// (three copies of an `.npy` file's data; a CSV number takes at least two bytes of text and
/// eight in memory, so four times its bytes each for the table and the samples).
pub fn check_reading(path: &Path) -> Result<(), CliError> {
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(()); // the reader names a missing file
    };
    let bytes = meta.len() as f64;
    let is_npy = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    let needed = if is_npy { 3.0 * bytes } else { 9.0 * bytes };
    rkwave::resources::check(
        || {
            format!(
                "reading {} ({})",
                path.display(),
                rkwave::resources::format_bytes(bytes)
            )
        },
        needed,
        || "split the samples or raise --memory-limit".into(),
    )
    .map_err(CliError::from)
}

/// The uniform fit (`Method::Wavelet`, or local inversion with `local`) of `samples`
/// samples on `plane`, `images` output images held.
pub fn uniform_request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    p: usize,
    rho: f64,
    local: bool,
    images: usize,
) -> ImageRequest {
    let functions = uniform_image_functions(p, plane.width(), plane.height(), samples, rho);
    let solve = if local {
        ImageSolve::Local { p, functions }
    } else {
        ImageSolve::Uniform { p, functions }
    };
    request(plane, channels, samples, solve, images)
}

/// `samples` samples of `channels` on `plane` (generated or already read), fitted by
/// `solve`, `images` output images held.
fn request(
    plane: ImagePlane,
    channels: usize,
    samples: f64,
    solve: ImageSolve,
    images: usize,
) -> ImageRequest {
    ImageRequest {
        pixels: plane.pixels() as f64,
        channels,
        samples,
        from_file: false,
        positions: 0.0,
        solve,
        images,
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
            ..request
        },
        _ => request,
    }
}

/// The adaptive tree fit of `samples` samples on `plane` at its depth limit (`direct`: the
/// assembled normal matrix and its factor; otherwise matrix-free).
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
    let levels = tree_levels(p, plane.width(), plane.height(), below_pixel);
    let solve = if direct {
        ImageSolve::TreeDirect { p, levels, rho }
    } else {
        ImageSolve::TreePcg { p, levels, rho }
    };
    request(plane, channels, samples, solve, images)
}

/// The larger of two requests (commands that run their parts one after the other).
pub fn larger(a: ImageRequest, b: ImageRequest) -> ImageRequest {
    if b.estimate().total() > a.estimate().total() {
        b
    } else {
        a
    }
}

impl From<ResourceError> for CliError {
    fn from(e: ResourceError) -> Self {
        CliError::Resources(e)
    }
}
