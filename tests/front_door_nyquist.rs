//! Issue 39's failure class "the tiled fit differing from the untiled one far beyond the tile
//! study's tolerance on a scene with detail near Nyquist", through the binary (the library's
//! side: `tests/tiles_nyquist.rs`; Python's: `python/tests/test_front_door_nyquist.py`).

mod common;

use std::path::Path;

use common::image_cli::{arg, npy_pixels, reconstruct2d, write_npy_unchecked};
use common::scenes::nyquist_value;
use common::{scratch, succeeds};
use rkwave::image::sampler::Sampler;
use rkwave::image::ImagePlane;
use rkwave::io::SampleSet;

/// The near-Nyquist samples of `tests/tiles_nyquist.rs` on `n x n`, 8 stratified samples a
/// pixel (stripes of 0.4 cycles a pixel, a chirp through 0.5, a thin line, a hash), written
/// as `x, y, r, g, b`.
fn nyquist_npy(path: &Path, n: usize) {
    let plane = ImagePlane::new(n, n).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, 8, 5);
    let value = |x: f64, y: f64, c: usize| nyquist_value(n, x, y, c);
    let mut values = vec![ys.clone()];
    values.extend((0..3).map(|c| xs.iter().zip(&ys).map(|(&x, &y)| value(x, y, c)).collect()));
    let set = SampleSet {
        positions: xs,
        values,
        names: ["y", "r", "g", "b"].map(String::from).to_vec(),
    };
    write_npy_unchecked(path, &set);
}

/// `reconstruct --dim 2 --pixels fit` untiled (the default solver, CG with the forward-error
/// stop) against `--tile 32 --halo 12` (each tile by the sparse Cholesky): within `1.1e-5` of
/// the value range — the library's two bounds added (the default untiled fit within `1e-5`
/// of the exact fit, the tiled within `1e-6` of it, `tests/tiles_nyquist.rs`). Before the
/// forward-error stop the untiled image was `4.4e-5` of the range from the exact fit here,
/// whatever the halo.
#[test]
fn tiled_and_untiled_images_agree_near_nyquist() {
    let n = 96;
    let dir = scratch("front-door", "nyquist");
    let input = dir.join("s.npy");
    nyquist_npy(&input, n);
    let resolution = format!("{n}x{n}");
    let untiled = dir.join("untiled.npy");
    let tiled = dir.join("tiled.npy");
    let mut args = reconstruct2d(&input, &untiled, &resolution);
    args.extend(["--pixels", "fit"].map(String::from));
    succeeds(&args);
    let mut args = reconstruct2d(&input, &tiled, &resolution);
    args.extend(["--pixels", "fit", "--tile", "32", "--halo", "12"].map(String::from));
    succeeds(&args);
    let count = 3 * n * n;
    let (a, b) = (npy_pixels(&untiled, count), npy_pixels(&tiled, count));
    let range =
        a.iter().fold(f64::MIN, |m, &v| m.max(v)) - a.iter().fold(f64::MAX, |m, &v| m.min(v));
    let d = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
        / range;
    eprintln!(
        "tiled against untiled: {d:e} of the range ({})",
        arg(&input)
    );
    assert!(d <= 1.1e-5, "{d:e} of the range");
}
