//! Fireflies (issue 28, item 3): a rare sample `10^3`-`10^5` times its neighbours, common in
//! path tracing, must stay local to its pixel. One is planted in a noisy flat image (32 x 32,
//! 8 stratified samples per pixel, values `0.5 + N(0, 0.05^2)`); each pixel estimate is
//! computed with and without it, and the *spread* is the number of pixels other than the
//! firefly's own whose value moved by more than the noise level of a pixel mean,
//! `sigma / sqrt(n_P) = 0.05 / sqrt(8)`.
//!
//! What each estimate does with the spike `F` (`F = 1e3 ... 1e5` times the mean):
//!
//! - `box` (the pixel mean) moves only its pixel: spread 0 by construction.
//! - `fit-clamped` clamps every pixel to its own samples' range, so a pixel without the
//!   firefly stays within its range whatever the fit rings; but within that range the
//!   least-squares ringing moves the pixels of the firefly's supports (a bounded spread).
//! - `fit` (least squares) rings across the supports of every function whose support
//!   holds the sample.
//! - `shrunk` keeps the spike's Haar detail (it is far above the threshold) and soft-thresholds
//!   each kept coefficient by `t`, which moves the pixels of the dyadic blocks holding the
//!   firefly by `~t / 2^j` at level `j`: a few blocks around it.
//!
//! Measured (seed 28, p = 2): `fit` moves 11, 23, 36 pixels at `F = 1e3, 1e4, 1e5` (by up to
//! 9.2, 92, 922: ringing across the supports); `fit-clamped` the same pixels but by at most
//! 0.10-0.12 (each within its own samples' range); `shrunk` 6 pixels by at most 0.043 whatever
//! `F`; `box` none. The test asserts those contracts with margins: `box` moves no other pixel;
//! `shrunk` at most the 8 pixels of the firefly's 3 x 3 neighbourhood, each by less than 3
//! noise levels; `fit-clamped` at most the `7 x 7 - 1 = 48` pixels of two supports around the
//! firefly and each by less than `6 sigma` (the range of 8 normal samples exceeds that with
//! probability below 1e-3). Not fixed: the clamped fit still moves the pixels of the spike's
//! supports within their ranges (a robust fit, or the spike's pixel fitted alone, would).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::estimate::{reconstruct_estimated, ShrinkParams, UniformEstimate};
use rkwave::image::{ImageMethod, ImagePlane, ImageSamples, WaveletParams};

const SIDE: usize = 32;
const SPP: usize = 8;
const MEAN: f64 = 0.5;
const SIGMA: f64 = 0.05;
/// The firefly's pixel.
const FIREFLY: (usize, usize) = (15, 17);

fn standard_normal(rng: &mut Pcg64) -> f64 {
    // Box-Muller.
    let (u, v): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// The noisy flat image's samples (2 x 4 strata per pixel), the firefly's sample index.
fn flat_samples(seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>, usize) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut xs, mut ys, mut vs) = (Vec::new(), Vec::new(), Vec::new());
    let mut firefly = 0;
    for py in 0..SIDE {
        for px in 0..SIDE {
            for k in 0..SPP {
                let (sx, sy) = ((k % 2) as f64, (k / 2) as f64);
                let x = px as f64 + (sx + rng.random::<f64>()) / 2.0;
                let y = py as f64 + (sy + rng.random::<f64>()) / 4.0;
                if (px, py) == FIREFLY && k == 3 {
                    firefly = xs.len();
                }
                xs.push(x);
                ys.push(y);
                vs.push(MEAN + SIGMA * standard_normal(&mut rng));
            }
        }
    }
    (xs, ys, vs, firefly)
}

/// Pixels other than the firefly's whose value moved by more than the noise level, and the
/// largest such move.
fn spread(estimate: UniformEstimate, factor: f64) -> (usize, f64) {
    let plane = ImagePlane::new(SIDE, SIDE).unwrap();
    let (xs, ys, vs, firefly) = flat_samples(28);
    let image = |vs: Vec<f64>| {
        let samples = ImageSamples::new(plane, xs.clone(), ys.clone(), vec![vs]).unwrap();
        let (done, _) = reconstruct_estimated(
            estimate,
            ImageMethod::Wavelet,
            &samples,
            &WaveletParams::default(),
            &ShrinkParams::default(),
        )
        .unwrap();
        done.image.channels[0].clone()
    };
    let clean = image(vs.clone());
    let mut hot = vs;
    hot[firefly] = MEAN * factor;
    let dirty = image(hot);
    let noise = SIGMA / (SPP as f64).sqrt();
    let own = FIREFLY.1 * SIDE + FIREFLY.0;
    let moved: Vec<f64> = clean
        .iter()
        .zip(&dirty)
        .enumerate()
        .filter(|&(i, _)| i != own)
        .map(|(_, (a, b))| (a - b).abs())
        .filter(|&d| d > noise)
        .collect();
    (moved.len(), moved.iter().cloned().fold(0.0, f64::max))
}

#[test]
fn a_firefly_stays_local_in_the_box_and_noise_aware_estimates() {
    for factor in [1e3, 1e4, 1e5] {
        let mut line = format!("firefly {factor:.0e} x:");
        for estimate in UniformEstimate::ALL {
            let (n, worst) = spread(estimate, factor);
            line.push_str(&format!(
                " {estimate}: {n} pixels (largest move {worst:.3e});"
            ));
            match estimate {
                UniformEstimate::Box => assert_eq!(n, 0, "{line}"),
                UniformEstimate::Shrunk => {
                    assert!(
                        n <= 8 && worst < 3.0 * SIGMA / (SPP as f64).sqrt(),
                        "{line}"
                    )
                }
                UniformEstimate::FitClamped => assert!(n <= 48 && worst < 6.0 * SIGMA, "{line}"),
                _ => {}
            }
        }
        println!("{line}");
    }
}
