//! The adaptive engine's output pixels (issue 13): the fit as a control variate, box pixels
//! plus the mean residual of each pixel's samples where it is significant
//! (`src/image/adaptive/correction.rs`). The mathematics, not snapshots: no residual, no
//! correction; a constant residual moves its pixel by itself; a mean residual within
//! `z sigma sqrt(ch / n)` moves nothing; the default output is then clamped to the range of
//! the samples in each pixel's 3x3 neighbourhood.

mod common;

use rkwave::image::adaptive::correction::{
    add_significant_mean_residual, clamp_to_local_range, output_pixels, PixelEstimate, RESIDUAL_Z,
};
use rkwave::image::adaptive::{refine_image, AdaptiveImage, AdaptiveParams, NoisyOracle};
use rkwave::image::ImagePlane;

// `polynomial`: in the coarse space every tree holds, so the fit reproduces it and its
// residuals are rounding.
use common::scenes::{polynomial, straight_edge};
use rkwave::image::adaptive::{OutputParams, StopParams};

const W: usize = 32;
const H: usize = 32;

fn run(oracle: &dyn rkwave::image::adaptive::ImageOracle) -> AdaptiveImage {
    let plane = ImagePlane::new(W, H).unwrap();
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        output: OutputParams {
            pixels: PixelEstimate::ResidualCorrected,
            ..AdaptiveParams::default().output
        },
        ..AdaptiveParams::default()
    };
    refine_image(oracle, plane, &params).unwrap()
}

/// Per pixel: the samples' count and the mean of `f_i - f~(x_i)`, the fit evaluated point by
/// point ([`rkwave::image::adaptive::TreeFit::evaluate`], not the residual routine of the
/// correction).
fn mean_residuals(run: &AdaptiveImage) -> (Vec<usize>, Vec<f64>) {
    let mut n = vec![0usize; W * H];
    let mut sum = vec![0.0; W * H];
    for i in 0..run.xs.len() {
        let (x, y) = (run.xs[i], run.ys[i]);
        let p = (y.floor() as usize).min(H - 1) * W + (x.floor() as usize).min(W - 1);
        n[p] += 1;
        sum[p] += run.values[0][i] - run.fit.evaluate(&run.tree, x, y).unwrap()[0];
    }
    let mean = sum
        .iter()
        .zip(&n)
        .map(|(s, &k)| s / k.max(1) as f64)
        .collect();
    (n, mean)
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
}

/// (a) Noise-free samples of a function the fit represents: the residuals are rounding, so
/// the output is the fit's box pixels to `1e-12` (values O(1), the tree fit's `cond(G)` below
/// `1e3`: residuals below `1e3 * 2^-52 * 64`), whatever the test decides to correct.
#[test]
fn no_residual_no_correction() {
    let run = run(&polynomial);
    assert_eq!(run.report.pixels.estimate, PixelEstimate::ResidualCorrected);
    let sampled = run.report.pixels.sampled;
    assert!(sampled > 0 && sampled <= W * H, "{sampled} pixels sampled");
    let fit = run.fit_pixels().unwrap();
    let err = largest_difference(&run.image.channels[0], &fit.channels[0]);
    assert!(err <= 1e-12, "corrected - fit up to {err:e}");
    assert!(
        run.report.pixels.largest <= 1e-12,
        "{:?}",
        run.report.pixels
    );
}

/// (b) The fit held, every sample of one pixel shifted by `d` (far beyond the significance
/// level of the noise-free run): that pixel moves by exactly the mean residual, `d` up to the
/// rounding of the other residuals (`1e-12`, as in (a)); every other pixel keeps its value
/// bit for bit, and the count of corrected pixels includes it.
#[test]
fn a_constant_offset_moves_its_pixel_by_the_offset() {
    let run = run(&polynomial);
    let d = 0.05;
    // the pixel with the most samples (where the refiner put them depends on the rounding
    // of a noise-free run's residuals)
    let pixel = |x: f64, y: f64| y.floor() as usize * W + x.floor() as usize;
    let mut counts = vec![0usize; W * H];
    for (&x, &y) in run.xs.iter().zip(&run.ys) {
        counts[pixel(x, y)] += 1;
    }
    let target = (0..W * H).max_by_key(|&p| (counts[p], p)).unwrap();
    let mut values = run.values.clone();
    let mut inside = 0;
    for ((&x, &y), v) in run.xs.iter().zip(&run.ys).zip(&mut values[0]) {
        if pixel(x, y) == target {
            *v += d;
            inside += 1;
        }
    }
    assert!(inside >= 2, "the pixel needs samples ({inside})");
    let sigma = run.report.pixels.sigma;
    assert!(RESIDUAL_Z * sigma < d, "sigma {sigma:e} hides the offset");
    let (fit, shifted, report) = output_pixels(
        &run.tree,
        &run.fit,
        &run.xs,
        &run.ys,
        &values,
        PixelEstimate::ResidualCorrected,
        sigma,
        RESIDUAL_Z,
    )
    .unwrap();
    let moved = shifted.channels[0][target] - fit.channels[0][target];
    assert!((moved - d).abs() <= 1e-12, "moved by {moved}, offset {d}");
    for p in (0..W * H).filter(|&p| p != target) {
        assert_eq!(
            shifted.channels[0][p].to_bits(),
            run.image.channels[0][p].to_bits()
        );
    }
    assert!(
        report.corrected >= 1 && report.largest >= d - 1e-12,
        "{report:?}"
    );
    // the fit only: the box pixels, nothing counted
    let (_, plain, none) = output_pixels(
        &run.tree,
        &run.fit,
        &run.xs,
        &run.ys,
        &values,
        PixelEstimate::FitOnly,
        sigma,
        RESIDUAL_Z,
    )
    .unwrap();
    assert_eq!(plain, fit);
    assert_eq!((none.corrected, none.sampled), (0, 0));
}

/// Where the fit cannot follow the scene (a noise-free edge: the fit rings inside the finest
/// cells), every pixel moves by its mean residual, computed here point by point from the fit
/// (`1e-12`: the same sums in the same order, evaluated by another route), or not at all.
#[test]
fn pixels_move_by_their_mean_residual() {
    let run = run(&straight_edge);
    let fit = run.fit_pixels().unwrap();
    let (n, mean) = mean_residuals(&run);
    let threshold = |p: usize| RESIDUAL_Z * run.report.pixels.sigma / (n[p] as f64).sqrt();
    let mut corrected = 0;
    for p in 0..W * H {
        let moved = run.image.channels[0][p] - fit.channels[0][p];
        if n[p] > 0 && mean[p].abs() > threshold(p) + 1e-12 {
            assert!(
                (moved - mean[p]).abs() <= 1e-12,
                "pixel {p}: {moved} vs {}",
                mean[p]
            );
            corrected += 1;
        } else if n[p] == 0 || mean[p].abs() < threshold(p) - 1e-12 {
            assert_eq!(moved, 0.0, "pixel {p} moved by {moved}");
        }
    }
    assert!(corrected > 0);
    assert_eq!(corrected, run.report.pixels.corrected);
}

/// (c) Under noise (deviation 0.05 on the polynomial: all detail is noise), a pixel whose
/// mean residual is within `z sigma / sqrt(n)` (`sigma` the noise test's estimate) keeps the
/// fit's value bit for bit; beyond it, it moves by the mean (`1e-12`). Few pixels pass: a
/// mean of `n` residuals of deviation at most `sigma` exceeds 3 standard errors with
/// probability 0.27% each (the fit absorbs part of the noise, so fewer); at most 1% of the
/// 1024 pixels are allowed, for the estimate of `sigma` (within 25%, see
/// `tests/image_adaptive_noise.rs`).
#[test]
fn insignificant_mean_residuals_are_not_added() {
    let oracle = NoisyOracle {
        inner: &polynomial,
        sigma: 0.05,
        seed: 5,
    };
    let run = run(&oracle);
    let sigma = run.report.pixels.sigma;
    assert!((0.0375..0.0625).contains(&sigma), "estimated sigma {sigma}");
    let fit = run.fit_pixels().unwrap();
    let (n, mean) = mean_residuals(&run);
    let mut corrected = 0;
    for p in 0..W * H {
        let t = RESIDUAL_Z * sigma / (n[p] as f64).sqrt();
        let moved = run.image.channels[0][p] - fit.channels[0][p];
        if mean[p].abs() < t - 1e-12 {
            assert_eq!(
                run.image.channels[0][p].to_bits(),
                fit.channels[0][p].to_bits(),
                "pixel {p}: mean {} within {t}",
                mean[p]
            );
        } else if mean[p].abs() > t + 1e-12 {
            assert!((moved - mean[p]).abs() <= 1e-12);
            corrected += 1;
        }
    }
    assert_eq!(corrected, run.report.pixels.corrected);
    assert!(
        corrected * 100 <= W * H,
        "{corrected} of {} pixels corrected on pure noise",
        W * H
    );
}

/// The default output clamps the corrected pixels to the range of the samples in their 3x3
/// neighbourhood: on an edge (where the fit rings) every pixel lies in that range, pixels
/// inside it keep the corrected value bit for bit, and the clamp moved some pixels (counted).
#[test]
fn the_default_output_is_clamped_to_the_local_sample_range() {
    let plane = ImagePlane::new(W, H).unwrap();
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        ..AdaptiveParams::default()
    };
    assert_eq!(params.output.pixels, PixelEstimate::ResidualClamped);
    let clamped = refine_image(&straight_edge, plane, &params).unwrap();
    let corrected = run(&straight_edge);
    assert_eq!(clamped.xs, corrected.xs);
    let mut range = vec![(f64::INFINITY, f64::NEG_INFINITY); W * H];
    for (i, (&x, &y)) in clamped.xs.iter().zip(&clamped.ys).enumerate() {
        let (px, py) = ((x as usize).min(W - 1), (y as usize).min(H - 1));
        for qy in py.saturating_sub(1)..(py + 2).min(H) {
            for qx in px.saturating_sub(1)..(px + 2).min(W) {
                let r = &mut range[qy * W + qx];
                *r = (r.0.min(clamped.values[0][i]), r.1.max(clamped.values[0][i]));
            }
        }
    }
    let mut moved = 0;
    for (p, &(lo, hi)) in range.iter().enumerate() {
        let (a, b) = (clamped.image.channels[0][p], corrected.image.channels[0][p]);
        if lo > hi {
            assert_eq!(a, b);
            continue;
        }
        assert!(lo <= a && a <= hi, "pixel {p}: {a} outside [{lo}, {hi}]");
        assert_eq!(a, b.clamp(lo, hi));
        moved += usize::from((a - b).abs() > 1e-9);
    }
    let report = &clamped.report.pixels;
    assert!(moved > 0);
    assert_eq!(report.clamped, moved);
    assert_eq!(report.corrected, corrected.report.pixels.corrected);
}

/// The test at its threshold `z sigma sqrt(ch / n)`, on given residuals: `n = 4`,
/// `sigma = 0.1`, `z = 3`, one channel: threshold 0.15, a mean of 0.149 is not added, 0.151
/// is (exactly); three channels: the norm of the mean against `0.15 sqrt(3)`.
#[test]
fn the_threshold_is_z_standard_errors_of_the_mean() {
    let plane = ImagePlane::new(2, 1).unwrap();
    let xs = [0.1, 0.3, 0.6, 0.9, 1.1, 1.3, 1.6, 1.9];
    let ys = [0.5; 8];
    let r = |a: f64, b: f64| vec![a + 0.01, a - 0.01, a + 0.02, a - 0.02, b, b, b, b];
    let mut pixels = vec![vec![0.0; 2]];
    let (sampled, corrected, _) =
        add_significant_mean_residual(&mut pixels, plane, &xs, &ys, &[r(0.149, 0.151)], 0.1, 3.0);
    assert_eq!((sampled, corrected), (2, 1));
    assert_eq!(pixels[0][0], 0.0);
    assert!((pixels[0][1] - 0.151).abs() <= 1e-15);
    // three channels: the norm of the mean against 0.15 sqrt(3) = 0.2598; 0.0866 each
    // (norm 0.1500) is not added, 0.151 each (norm 0.2615) is
    let mut pixels = vec![vec![0.0; 2]; 3];
    let (_, corrected, _) = add_significant_mean_residual(
        &mut pixels,
        plane,
        &xs,
        &ys,
        &[r(0.0866, 0.151), r(0.0866, 0.151), r(0.0866, 0.151)],
        0.1,
        3.0,
    );
    assert_eq!(corrected, 1);
    for c in &pixels {
        assert_eq!(c[0], 0.0);
        assert!((c[1] - 0.151).abs() <= 1e-15);
    }
}

// Moved from the unit tests of `correction.rs` (its 800-line limit).

/// A pixel whose samples all carry the residual `d` moves by exactly `d` (the mean of
/// equal numbers is that number in floating point for these counts, checked to one ulp);
/// pixels whose residuals are zero do not move and are not counted.
#[test]
fn a_constant_residual_moves_its_pixel_by_itself() {
    let plane = ImagePlane::new(3, 2).unwrap();
    let d = 0.125;
    // four samples in pixel (1, 0), two in (0, 1), one on the bottom-right border
    let xs = [1.1, 1.4, 1.6, 1.9, 0.2, 0.7, 3.0];
    let ys = [0.1, 0.6, 0.3, 0.9, 1.5, 1.2, 2.0];
    let r = vec![vec![d, d, d, d, 0.0, 0.0, 0.0]];
    let mut pixels = vec![vec![0.5; 6]];
    let (sampled, corrected, largest) =
        add_significant_mean_residual(&mut pixels, plane, &xs, &ys, &r, 0.01, RESIDUAL_Z);
    assert_eq!((sampled, corrected), (3, 1));
    assert_eq!(largest, d);
    assert_eq!(pixels[0], vec![0.5, 0.5 + d, 0.5, 0.5, 0.5, 0.5]);
}

/// The clamp: a value above the neighbourhood's samples comes down to their largest, one
/// below comes up to their least, one inside stays bit for bit, and a pixel with no sample
/// in its 3x3 neighbourhood keeps its value.
#[test]
fn the_clamp_projects_onto_the_neighbourhood_range() {
    let plane = ImagePlane::new(5, 1).unwrap();
    // samples in pixels 0 and 1 only: pixels 0..=2 see them, 3 and 4 see none
    let xs = [0.5, 1.2, 1.7];
    let ys = [0.5; 3];
    let values = vec![vec![0.1, 0.8, 0.4]];
    let mut pixels = vec![vec![1.2, -0.3, 0.45, 7.0, -7.0]];
    let (clamped, largest) = clamp_to_local_range(&mut pixels, plane, &xs, &ys, &values);
    assert_eq!(pixels[0], vec![0.8, 0.1, 0.45, 7.0, -7.0]);
    assert_eq!(clamped, 2);
    assert!((largest - 0.4).abs() <= 1e-15);
}
