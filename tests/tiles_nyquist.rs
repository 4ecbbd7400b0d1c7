//! The tiled fit near Nyquist (issue 39's failure class: "the tiled fit differing from the
//! untiled one far beyond the tile study's tolerance on a scene with detail near Nyquist").
//!
//! **The cause was the untiled fit's solver, not the tiles** (now mended: the default CG also
//! stops on the coefficients' estimated error, `default_untiled_fit_is_accurate_near_nyquist`
//! below). Above
//! `CHOLESKY_MAX_FUNCTIONS` unknowns the untiled fit solves `G z = K^T f` by Jacobi PCG to
//! the relative residual `||K^T f - G z|| <= 1e-6 ||K^T f||` (as [`NormalSolver::default_cg`] did);
//! the coefficient error that leaves is bounded only by `cond(G) 1e-6`. Near Nyquist the
//! automatic level puts two functions per pixel and two samples per function, `G` is badly
//! conditioned, and the CG's error reaches `1e-4` to `1e-2` of the value range (the suite's
//! `text` and `stripes` at 8 spp, docs/measurements/image-plane.md). Every tile solves its
//! window's system by the sparse Cholesky (exact up to rounding), so the tiled image agrees
//! with the untiled fit *solved exactly* as the tile study says it does, and its difference to
//! the CG's image is the CG's error, the same for every halo. The reference here is
//! therefore the untiled fit by the sparse Cholesky.

mod common;
use common::scenes::nyquist_value;
use rkwave::image::fit::{fit_samples, NormalSolver};
use rkwave::image::pixels::filter_image;
use rkwave::image::sampler::Sampler;
use rkwave::image::tiles::{reconstruct_tiled, TileGeometry, TiledInput, TiledParams};
use rkwave::image::wavelet::{fit_params, pixel_matrices};
use rkwave::image::{CoefficientSolve, ImagePlane, ImageSamples, WaveletParams};

/// Detail at and near Nyquist on a `n x n` image ([`nyquist_value`]), 8 stratified samples a
/// pixel.
fn nyquist_samples(n: usize, seed: u64) -> ImageSamples {
    let plane = ImagePlane::new(n, n).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, 8, seed);
    let value = |x: f64, y: f64, c: usize| nyquist_value(n, x, y, c);
    let values = (0..3)
        .map(|c| xs.iter().zip(&ys).map(|(&x, &y)| value(x, y, c)).collect())
        .collect();
    ImageSamples::new(plane, xs, ys, values).unwrap()
}

/// The untiled fit with `solver`, as box pixels (channel-major, row by row).
fn untiled(samples: &ImageSamples, solver: NormalSolver) -> Vec<Vec<f64>> {
    let mut params = fit_params(&WaveletParams::default(), CoefficientSolve::Global);
    params.solver = solver;
    let fit = fit_samples(samples, &params).unwrap();
    let (bx, by, _) = pixel_matrices(&fit, None).unwrap();
    fit.coefficients
        .iter()
        .map(|c| filter_image(&by, &bx, c).unwrap())
        .collect()
}

fn tiled(samples: &ImageSamples, tile: usize, halo: usize) -> Vec<Vec<f64>> {
    let geometry = TileGeometry::new(samples.plane(), tile, halo).unwrap();
    reconstruct_tiled(
        TiledInput::Samples(samples),
        &geometry,
        &WaveletParams::default(),
        &TiledParams::default(),
        &|_| {},
    )
    .unwrap()
    .image
    .channels
}

/// Largest difference over every channel and pixel, over the value range of `reference`.
fn relative_max(a: &[Vec<f64>], reference: &[Vec<f64>]) -> f64 {
    let all = || reference.iter().flatten().copied();
    let range = all().fold(f64::MIN, f64::max) - all().fold(f64::MAX, f64::min);
    let d = a
        .iter()
        .flatten()
        .zip(reference.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    d / range
}

/// Tiled against the untiled fit solved exactly, on detail near Nyquist at the automatic
/// (finest) level: within the tile study's tolerance, `1e-6` of the value range at the
/// default halo 12 (docs/measurements/image-plane.md: the smallest halo meeting it for p = 2
/// and 3 on the halo study's scene), for tiles of 32 and 48 and halos 12 and 24. Measured:
/// 7e-14 (tile 32, halo 12), 6e-15 (tile 48), 7e-16 (halo 24). The default solver's (CG's)
/// image was 4.4e-5 of the range from the exact fit on these samples while CG stopped on the
/// residual alone (the failure class's "difference that does not shrink with the halo"); the
/// next test holds the default to the exact fit now that it stops on the error.
#[test]
fn tiled_is_the_exact_untiled_fit_near_nyquist() {
    let samples = nyquist_samples(96, 5);
    let exact = untiled(&samples, NormalSolver::Cholesky);
    for (tile, halo) in [(32, 12), (48, 12), (32, 24)] {
        let d = relative_max(&tiled(&samples, tile, halo), &exact);
        assert!(d <= 1e-6, "tile {tile}, halo {halo}: {d:e} of the range");
    }
}

/// The untiled default (`NormalSolver::Auto`: Jacobi PCG above `CHOLESKY_MAX_FUNCTIONS`, with
/// the forward-error stop) against the exact fit on the same samples: within `1e-5` of the
/// value range. The residual stop alone left 4.4e-5 here and up to 1e-2 on the suite's
/// stripes (the failure class); the forward-error stop asks the coefficients' estimated
/// relative error (in the preconditioner's norm) to be at most `CG_FORWARD_ERROR = 1e-5`,
/// and a pixel is a local combination of a few coefficients, so its error stays near that
/// fraction of the range unless the error concentrates on a few functions (measured here
/// and stated in docs/measurements/image-plane.md).
#[test]
fn default_untiled_fit_is_accurate_near_nyquist() {
    let samples = nyquist_samples(96, 5);
    let exact = untiled(&samples, NormalSolver::Cholesky);
    let default = untiled(&samples, NormalSolver::Auto);
    let d = relative_max(&default, &exact);
    eprintln!("default solver: {d:e} of the range from the exact fit");
    assert!(d <= 1e-5, "{d:e} of the range");
}
