//! Noise-aware pixel estimates (`rkwave::image::estimate`): the Haar transform's identities,
//! the shrinkage's properties, the clamp as a projection, and the command line's report.
//!
//! Tolerances: the transform is a product of 2 x 2 rotations, `L` per axis (`L <= log2(side +
//! offset) + 1` levels); each rotation moves a value by at most a few `eps` relative to the
//! largest value it touches, so a forward and an inverse transform stay within `C L eps
//! max|v|` with `C = 16` (4 rotations per value per level — x and y, forward and back — each
//! within 2 eps, a factor 2 to spare).

mod common;
use common::rkwave;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::estimate::{
    clamp_to_sample_range, reconstruct_estimated, shrink_channel, universal_threshold,
    EstimateError, EstimateReport, Haar2d, PixelStatistics, ShrinkParams, UniformEstimate,
};
use rkwave::image::{
    reconstruct, ImageMethod, ImagePlane, ImageReconstruction, ImageSamples, PixelImage,
    WaveletParams,
};

/// Image sizes with odd sides, one-pixel lines and a power of two: the borders' truncated
/// blocks are exercised at every offset.
const SIZES: [(usize, usize); 6] = [(1, 1), (1, 9), (13, 7), (16, 16), (17, 5), (32, 3)];

fn levels(w: usize, h: usize) -> f64 {
    ((w.max(h) + 4) as f64).log2().ceil() + 1.0
}

fn random_image(rng: &mut Pcg64, n: usize) -> Vec<f64> {
    (0..n).map(|_| rng.random_range(-1.0..1.0)).collect()
}

fn standard_normal(rng: &mut Pcg64) -> f64 {
    // Box-Muller.
    let (u, v): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

fn coefficients(haar: &Haar2d, image: &[f64]) -> Vec<f64> {
    let c = haar.forward(image);
    let mut all = c.approximation.clone();
    for level in &c.levels {
        all.extend(level.values().copied());
    }
    all
}

#[test]
fn the_transform_is_an_orthonormal_matrix_for_every_size_and_offset() {
    for (w, h) in SIZES {
        for (ox, oy) in [(0, 0), (1, 0), (2, 3), (3, 1)] {
            let haar = Haar2d::new(w, h, ox, oy);
            // Column k of W: the coefficients of the k-th unit image.
            let cols: Vec<Vec<f64>> = (0..w * h)
                .map(|k| {
                    let mut e = vec![0.0; w * h];
                    e[k] = 1.0;
                    coefficients(&haar, &e)
                })
                .collect();
            assert!(cols.iter().all(|c| c.len() == w * h), "{w}x{h}: square");
            let tol = 16.0 * levels(w, h) * f64::EPSILON;
            for a in 0..w * h {
                for b in 0..w * h {
                    let dot: f64 = cols[a].iter().zip(&cols[b]).map(|(x, y)| x * y).sum();
                    let want = if a == b { 1.0 } else { 0.0 };
                    assert!(
                        (dot - want).abs() <= tol,
                        "{w}x{h} offset ({ox}, {oy}): <W e_{a}, W e_{b}> = {dot}"
                    );
                }
            }
        }
    }
}

#[test]
fn parseval_and_perfect_reconstruction_on_random_images() {
    let mut rng = Pcg64::seed_from_u64(28);
    for (w, h) in SIZES.into_iter().chain([(128, 128), (100, 37)]) {
        for (ox, oy) in [(0, 0), (3, 2)] {
            let haar = Haar2d::new(w, h, ox, oy);
            let image = random_image(&mut rng, w * h);
            let energy: f64 = image.iter().map(|v| v * v).sum();
            let coeff: f64 = coefficients(&haar, &image).iter().map(|v| v * v).sum();
            let tol = 16.0 * levels(w, h) * f64::EPSILON;
            assert!(
                (coeff - energy).abs() <= tol * energy,
                "{w}x{h}: Parseval {coeff} against {energy}"
            );
            let back = haar.inverse(&haar.forward(&image));
            for (a, b) in back.iter().zip(&image) {
                assert!((a - b).abs() <= tol, "{w}x{h}: inverse {a} against {b}");
            }
        }
    }
}

#[test]
fn zero_threshold_is_the_identity_and_a_constant_image_is_untouched() {
    let mut rng = Pcg64::seed_from_u64(7);
    for (w, h) in SIZES.into_iter().chain([(64, 48)]) {
        let tol = 16.0 * levels(w, h) * f64::EPSILON;
        let image = random_image(&mut rng, w * h);
        let same = shrink_channel(&image, w, h, 0.0, 4);
        for (a, b) in same.iter().zip(&image) {
            assert!((a - b).abs() <= tol, "{w}x{h}: t = 0 moved {b} to {a}");
        }
        // A constant has no detail: any threshold leaves it (scale 3.5, so tol * 3.5).
        let constant = vec![3.5; w * h];
        for a in shrink_channel(&constant, w, h, 1e6, 4) {
            assert!((a - 3.5).abs() <= 3.5 * tol, "{w}x{h}: constant became {a}");
        }
    }
}

#[test]
fn universal_shrinkage_removes_nine_tenths_of_white_noise() {
    // Pure Gaussian noise of sigma = 0.2 on 128 x 128 pixels, the threshold sigma sqrt(2 ln N):
    // the chance that one detail coefficient of noise alone exceeds it is ~ 1 / (N sqrt(pi ln N))
    // and those that do are shrunk by t, so almost nothing is left: 90% removed is a loose bound
    // that any error in the thresholds or in the normalisation of the transform (a coefficient
    // of noise at sqrt 2 sigma, say) breaks.
    let (w, h, sigma) = (128, 128, 0.2);
    let mut rng = Pcg64::seed_from_u64(2028);
    let noise: Vec<f64> = (0..w * h)
        .map(|_| sigma * standard_normal(&mut rng))
        .collect();
    let t = universal_threshold(sigma, w * h, 1.0);
    let out = shrink_channel(&noise, w, h, t, 4);
    let before: f64 = noise.iter().map(|v| v * v).sum();
    let after: f64 = out.iter().map(|v| v * v).sum();
    assert!(
        after <= 0.1 * before,
        "energy left {after} of {before} ({:.1}%)",
        100.0 * after / before
    );
}

/// `spp` samples in each pixel of a `w x h` plane at stratified positions, one channel:
/// `signal(x, y) + sigma N(0, 1)`.
fn noisy_samples(
    w: usize,
    h: usize,
    spp: usize,
    sigma: f64,
    signal: impl Fn(f64, f64) -> f64,
) -> ImageSamples {
    let mut rng = Pcg64::seed_from_u64(99);
    let (mut xs, mut ys, mut vs) = (vec![], vec![], vec![]);
    for py in 0..h {
        for px in 0..w {
            for _ in 0..spp {
                let (x, y) = (
                    px as f64 + rng.random::<f64>(),
                    py as f64 + rng.random::<f64>(),
                );
                xs.push(x);
                ys.push(y);
                vs.push(signal(x, y) + sigma * standard_normal(&mut rng));
            }
        }
    }
    ImageSamples::new(ImagePlane::new(w, h).unwrap(), xs, ys, vec![vs]).unwrap()
}

#[test]
fn the_pooled_noise_level_is_the_standard_error_of_a_pixel_mean() {
    // sigma 0.3 at 4 spp: a pixel mean's standard error is 0.15. The median of s² / n over 4096
    // pixels, s² with 3 degrees of freedom (a scaled chi-square, median 2.37 / 3 = 0.789 of
    // its mean), so sigma_c = 0.15 sqrt(0.789) = 0.133; its sampling error over 4096 pixels is
    // about 2% — 0.12 to 0.145 holds it.
    let samples = noisy_samples(64, 64, 4, 0.3, |_, _| 0.5);
    let sigma = PixelStatistics::new(&samples).noise_level().unwrap()[0];
    assert!((0.12..0.145).contains(&sigma), "sigma_c = {sigma}");
}

/// `reconstruct_estimated` with the wavelet method and default parameters.
fn estimate(
    samples: &ImageSamples,
    e: UniformEstimate,
) -> Result<(ImageReconstruction, EstimateReport), EstimateError> {
    reconstruct_estimated(
        e,
        ImageMethod::Wavelet,
        samples,
        &WaveletParams::default(),
        &ShrinkParams::default(),
    )
}

#[test]
fn shrunk_pixels_beat_the_box_on_a_noisy_smooth_scene_and_report_their_threshold() {
    let signal = |x: f64, y: f64| 0.5 + 0.3 * (x / 10.0).sin() * (y / 13.0).cos();
    let samples = noisy_samples(64, 64, 4, 0.3, signal);
    let go = |e| estimate(&samples, e).unwrap();
    let (boxed, _) = go(UniformEstimate::Box);
    let (shrunk, report) = go(UniformEstimate::Shrunk);
    // Error against the pixel centre's value (the signal varies by < 0.02 across a pixel,
    // far below the noise of a mean, 0.15).
    let err = |img: &PixelImage| -> f64 {
        (0..64 * 64)
            .map(|p| {
                let (x, y) = ((p % 64) as f64 + 0.5, (p / 64) as f64 + 0.5);
                (img.channels[0][p] - signal(x, y)).powi(2)
            })
            .sum()
    };
    // The box's error energy is the noise, 4096 x 0.0225; shrinkage of a smooth signal
    // removes most of it: at least half is a loose bound.
    assert!(err(&shrunk.image) < 0.5 * err(&boxed.image));
    let t = report.threshold.as_ref().unwrap()[0];
    let s = report.noise_level.as_ref().unwrap()[0];
    assert_eq!(t, universal_threshold(s, 64 * 64, 1.0));
    assert!(report.description.contains("universal threshold"));
}

#[test]
fn box_is_the_pixel_mean_and_fit_is_reconstruct_unchanged() {
    let samples = noisy_samples(12, 9, 3, 0.1, |x, y| x * y / 50.0);
    let stats = PixelStatistics::new(&samples);
    let go = |e| estimate(&samples, e).unwrap().0;
    assert_eq!(go(UniformEstimate::Box).image.channels, stats.mean);
    let plain = reconstruct(ImageMethod::Wavelet, &samples, &WaveletParams::default()).unwrap();
    assert_eq!(go(UniformEstimate::Fit).image, plain.image, "bit for bit");
}

#[test]
fn the_clamp_is_a_projection_onto_each_pixels_sample_range() {
    let samples = noisy_samples(16, 16, 4, 0.5, |x, _| if x < 8.0 { 0.1 } else { 20.0 });
    let stats = PixelStatistics::new(&samples);
    let mut rng = Pcg64::seed_from_u64(3);
    let original = PixelImage {
        plane: samples.plane(),
        channels: vec![(0..256).map(|_| rng.random_range(-5.0..25.0)).collect()],
    };
    let mut once = original.clone();
    let moved = clamp_to_sample_range(&mut once, &stats);
    assert!(moved > 0);
    for p in 0..256 {
        let (v, lo, hi) = (once.channels[0][p], stats.min[0][p], stats.max[0][p]);
        assert!(lo <= v && v <= hi, "pixel {p}: {v} outside [{lo}, {hi}]");
        // A value inside its range does not move; one outside goes to the nearest end.
        let o = original.channels[0][p];
        assert_eq!(v, o.clamp(lo, hi));
    }
    let mut twice = once.clone();
    assert_eq!(clamp_to_sample_range(&mut twice, &stats), 0, "idempotent");
    assert_eq!(twice, once);
}

#[test]
fn empty_pixels_and_single_samples_are_refused_with_the_way_out() {
    let plane = ImagePlane::new(2, 2).unwrap();
    let one_each = ImageSamples::new(
        plane,
        vec![0.5, 1.5, 0.5, 1.5],
        vec![0.5, 0.5, 1.5, 1.5],
        vec![vec![1.0, 2.0, 3.0, 4.0]],
    )
    .unwrap();
    let go = estimate;
    let err = go(&one_each, UniformEstimate::Shrunk).unwrap_err();
    assert!(matches!(err, EstimateError::NoSpread), "{err}");
    assert!(err.to_string().contains("at least 2 samples per pixel"));
    let three = ImageSamples::new(
        plane,
        vec![0.5, 1.5, 0.5],
        vec![0.5, 0.5, 1.5],
        vec![vec![1.0, 2.0, 3.0]],
    )
    .unwrap();
    let err = go(&three, UniformEstimate::Box).unwrap_err();
    assert!(
        matches!(
            err,
            EstimateError::EmptyPixels {
                count: 1,
                x: 1,
                y: 1,
                ..
            }
        ),
        "{err}"
    );
    // The library names the parameter, not the command line's flag (the front ends spell it).
    assert!(
        err.to_string().contains("set ImageParams::pixels to `fit`"),
        "{err}"
    );
}

#[test]
fn the_command_line_reports_the_noise_level_and_threshold() {
    let dir = std::env::temp_dir().join(format!("rkwave-pixel-estimates-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let input = dir.join("samples.csv");
    let samples = noisy_samples(8, 8, 4, 0.2, |x, _| x / 8.0);
    let mut csv = String::from("x,y,v\n");
    for i in 0..samples.len() {
        csv += &format!(
            "{},{},{}\n",
            samples.xs()[i],
            samples.ys()[i],
            samples.channel(0)[i]
        );
    }
    std::fs::write(&input, csv).unwrap();
    let output = dir.join("out.npy");
    let (inp, out) = (input.to_str().unwrap(), output.to_str().unwrap());
    let base = [
        "reconstruct",
        "--dim",
        "2",
        "--resolution",
        "8x8",
        "--input",
        inp,
        "--output",
        out,
        "--force",
    ];
    let json = rkwave(&[&base[..], &["--pixels", "shrunk", "--json"]].concat());
    assert!(
        json.status.success(),
        "{}",
        String::from_utf8_lossy(&json.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    let pixels = &report["pixels"];
    assert_eq!(pixels["estimate"], "shrunk");
    let sigma = pixels["noise_level"][0].as_f64().unwrap();
    let t = pixels["threshold"][0].as_f64().unwrap();
    // serde_json's default float parser may be one ulp off the printed shortest decimal.
    let want = universal_threshold(sigma, 64, 1.0);
    assert!(
        (t - want).abs() <= 4.0 * f64::EPSILON * want,
        "{t} against {want}"
    );
    assert_eq!(report["method"], "box");
    let text = rkwave(&[&base[..], &["--pixels", "shrunk"]].concat());
    let stdout = String::from_utf8_lossy(&text.stdout);
    assert!(stdout.contains("universal threshold"), "{stdout}");
    let bad = rkwave(&[&base[..], &["--pixels", "median"]].concat());
    assert_eq!(bad.status.code(), Some(2), "a user error");
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        stderr.contains("fit, fit-clamped, box or shrunk"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
