//! Tiles with halos (`rkwave::image::tiles`) against the untiled fit, through the library.

mod common;

use rkwave::image::sampler::Sampler;
use rkwave::image::tiles::{
    fit_tile, reconstruct_tiled, window_samples, TileGeometry, TileParams, TiledInput, TiledParams,
};
use rkwave::image::wavelet::{wavelet_image, CoefficientSolve, WaveletParams};
use rkwave::image::{ImagePlane, ImageSamples, PixelImage};

fn scene_samples(w: usize, h: usize, spp: usize, seed: u64) -> ImageSamples {
    let plane = ImagePlane::new(w, h).unwrap();
    let (xs, ys) = Sampler::Stratified.positions(plane, spp, seed);
    let a: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(&x, &y)| common::scenes::straight_edge(x, y) + 0.1 * (0.3 * x).sin())
        .collect();
    let b: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(&x, &y)| (0.2 * y).cos() * x / 40.0)
        .collect();
    ImageSamples::new(plane, xs, ys, vec![a, b]).unwrap()
}

/// Every tile of the grid fitted on its window's samples, assembled into an image.
fn tiled(samples: &ImageSamples, geometry: &TileGeometry, params: &WaveletParams) -> PixelImage {
    let tp = TileParams::for_image(params, samples.plane(), samples.len()).unwrap();
    let mut image = PixelImage::zeros(samples.plane(), samples.channels());
    let w = samples.plane().width();
    for t in 0..geometry.count() {
        let s = window_samples(samples, geometry, t).unwrap();
        let tile = fit_tile(&s, geometry, t, &tp).unwrap();
        let r = tile.interior;
        for (c, px) in tile.channels.iter().enumerate() {
            for y in r.y0..r.y1 {
                for x in r.x0..r.x1 {
                    image.channels[c][y * w + x] = px[(y - r.y0) * r.width() + x - r.x0];
                }
            }
        }
    }
    image
}

fn max_diff(a: &PixelImage, b: &PixelImage) -> f64 {
    a.channels
        .iter()
        .flatten()
        .zip(b.channels.iter().flatten())
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// A window that covers the whole image is the untiled fit: the same normal equations
/// summed in another order (per thread, then reduced, against one pass), so equal up to
/// rounding amplified by the condition of the equilibrated system: 1e-9 on values of size 1.
#[test]
fn a_window_over_the_whole_image_is_the_untiled_fit() {
    let samples = scene_samples(40, 32, 4, 7);
    for p in [2, 3] {
        let params = WaveletParams {
            p,
            ..WaveletParams::default()
        };
        let untiled = wavelet_image(&samples, &params, CoefficientSolve::Global).unwrap();
        let geometry = TileGeometry::new(samples.plane(), 32, 32).unwrap();
        let image = tiled(&samples, &geometry, &params);
        let d = max_diff(&image, &untiled.image);
        assert!(d < 1e-9, "p = {p}: {d:e}");
    }
}

/// The difference to the untiled fit falls with the halo (the dual kernels decay): halo 12
/// is at least 100 times closer than halo 0 on this smooth-plus-edge scene.
#[test]
fn the_difference_falls_with_the_halo() {
    let samples = scene_samples(64, 48, 4, 11);
    let params = WaveletParams::default();
    let untiled = wavelet_image(&samples, &params, CoefficientSolve::Global).unwrap();
    let diff = |halo| {
        let g = TileGeometry::new(samples.plane(), 16, halo).unwrap();
        max_diff(&tiled(&samples, &g, &params), &untiled.image)
    };
    let (d0, d12) = (diff(0), diff(12));
    assert!(d12 * 100.0 < d0, "halo 0: {d0:e}, halo 12: {d12:e}");
}

/// A tile's pixels do not depend on the thread pool that fits it (bit for bit).
#[test]
fn a_tile_is_the_same_bits_in_any_pool() {
    let samples = scene_samples(64, 48, 4, 3);
    let g = TileGeometry::new(samples.plane(), 16, 4).unwrap();
    let tp =
        TileParams::for_image(&WaveletParams::default(), samples.plane(), samples.len()).unwrap();
    let s = window_samples(&samples, &g, 5).unwrap();
    let one = fit_tile(&s, &g, 5, &tp).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let other = pool.install(|| fit_tile(&s, &g, 5, &tp).unwrap());
    assert_eq!(one.channels, other.channels);
}

/// The three ways to the tiled image give the same bits: tile by tile from the window's
/// samples, the band scans of samples in memory, and a sample file spilled into band files
/// (bands of tile rows whose halos overlap: samples go to two or three bands) with two
/// workers and small chunks; the scratch folder is gone afterwards.
#[test]
fn spilled_bands_give_the_tiles_the_same_samples() {
    let samples = scene_samples(40, 56, 4, 11);
    let params = WaveletParams::default();
    let g = TileGeometry::new(samples.plane(), 8, 6).unwrap();
    let by_tile = tiled(&samples, &g, &params);
    let dir = common::scratch("tiles", "spill");
    let file = dir.join("s.npy");
    let set = rkwave::io::SampleSet::new(
        samples.xs().to_vec(),
        std::iter::once(samples.ys().to_vec())
            .chain(samples.values().iter().cloned())
            .collect(),
    )
    .unwrap();
    rkwave::io::write_npy(&file, &set).unwrap();
    let scratch = dir.join("scratch");
    std::fs::create_dir(&scratch).unwrap();
    let tp = TiledParams {
        workers: 2,
        chunk_rows: 777,
        scratch: Some(scratch.clone()),
    };
    let none = |_: &rkwave::image::tiles::TileReport| {};
    let scanned =
        reconstruct_tiled(TiledInput::Samples(&samples), &g, &params, &tp, &none).unwrap();
    let spilled = reconstruct_tiled(TiledInput::File(&file), &g, &params, &tp, &none).unwrap();
    assert_eq!(scanned.image.channels, by_tile.channels);
    assert_eq!(spilled.image.channels, by_tile.channels);
    let spill = spilled.report.spill.expect("a file is spilled");
    assert_eq!(spill.bands, 7);
    assert!(spill.rows > samples.len(), "halo rows go to two bands");
    assert_eq!(spilled.report.passes, 2);
    assert!(scanned.report.spill.is_none());
    assert_eq!(
        std::fs::read_dir(&scratch).unwrap().count(),
        0,
        "scratch left behind"
    );
}
