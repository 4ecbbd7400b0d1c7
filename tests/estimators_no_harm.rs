//! Do no harm by construction (issue 38): the default uniform pixels (`auto`) against the
//! per-pixel mean of the same samples on random synthetic textures with and without noise,
//! their range and the stored Mitsuba renders.

mod common;

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::estimate::{
    reconstruct_estimated, EstimateReport, PixelStatistics, ShrinkParams, UniformEstimate,
};
use rkwave::image::{ImageMethod, ImagePlane, ImageSamples, PixelImage, WaveletParams};

/// A standard normal deviate (Box–Muller).
fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// A random texture with analytic pixel integrals: a constant, separable sinusoids
/// `a sin(kx x + px) sin(ky y + py)` with frequencies up to 3 cycles a pixel (far past
/// Nyquist) and axis-aligned steps `b 1{x > x0}` / `b 1{y > y0}` (edges inside pixels).
struct Texture {
    base: f64,
    waves: Vec<(f64, f64, f64, f64, f64)>,
    steps: Vec<(bool, f64, f64)>,
}

impl Texture {
    fn random(rng: &mut Pcg64, w: usize) -> Self {
        let two_pi = 2.0 * std::f64::consts::PI;
        let waves = (0..rng.random_range(1..4))
            .map(|_| {
                let f = |rng: &mut Pcg64| two_pi * rng.random_range(0.01..3.0);
                (
                    rng.random_range(0.05..0.3),
                    f(rng),
                    rng.random_range(0.0..two_pi),
                    f(rng),
                    rng.random_range(0.0..two_pi),
                )
            })
            .collect();
        let steps = (0..rng.random_range(0..4))
            .map(|_| {
                (
                    rng.random(),
                    rng.random_range(0.0..w as f64),
                    rng.random_range(-0.4..0.4),
                )
            })
            .collect();
        Self {
            base: rng.random_range(0.3..0.7),
            waves,
            steps,
        }
    }

    fn value(&self, x: f64, y: f64) -> f64 {
        let mut v = self.base;
        for &(a, kx, px, ky, py) in &self.waves {
            v += a * (kx * x + px).sin() * (ky * y + py).sin();
        }
        for &(along_x, at, b) in &self.steps {
            let t = if along_x { x } else { y };
            if t > at {
                v += b;
            }
        }
        v
    }

    /// The mean over the pixel `[X, X + 1) x [Y, Y + 1)`.
    fn integral(&self, px: usize, py: usize) -> f64 {
        let (x0, y0) = (px as f64, py as f64);
        // int_a^{a+1} sin(k t + p) dt = (cos(k a + p) - cos(k (a + 1) + p)) / k
        let one = |k: f64, p: f64, a: f64| ((k * a + p).cos() - (k * (a + 1.0) + p).cos()) / k;
        let mut v = self.base;
        for &(a, kx, px_, ky, py_) in &self.waves {
            v += a * one(kx, px_, x0) * one(ky, py_, y0);
        }
        for &(along_x, at, b) in &self.steps {
            let t0 = if along_x { x0 } else { y0 };
            v += b * (t0 + 1.0 - at).clamp(0.0, 1.0);
        }
        v
    }
}

/// `g x g` jittered samples a pixel of a random texture plus Gaussian noise `sigma`, three
/// channels (the texture scaled by 1, 0.5 and 2: a dynamic range), and the pixel integrals.
fn textured(w: usize, h: usize, g: usize, sigma: f64, seed: u64) -> (ImageSamples, Vec<Vec<f64>>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let tex = Texture::random(&mut rng, w);
    sampled(&tex, w, h, g, sigma, &mut rng)
}

/// `g x g` jittered samples a pixel of `tex` plus Gaussian noise `sigma`, three channels (the
/// texture scaled by 1, 0.5 and 2), and the pixel integrals.
fn sampled(
    tex: &Texture,
    w: usize,
    h: usize,
    g: usize,
    sigma: f64,
    rng: &mut Pcg64,
) -> (ImageSamples, Vec<Vec<f64>>) {
    let scale = [1.0, 0.5, 2.0];
    let (mut xs, mut ys) = (vec![], vec![]);
    let mut values = vec![vec![]; 3];
    for py in 0..h {
        for px in 0..w {
            for j in 0..g {
                for i in 0..g {
                    let x = px as f64 + (i as f64 + rng.random::<f64>()) / g as f64;
                    let y = py as f64 + (j as f64 + rng.random::<f64>()) / g as f64;
                    let f = tex.value(x, y);
                    for (c, v) in values.iter_mut().enumerate() {
                        v.push(scale[c] * (f + sigma * normal(rng)));
                    }
                    xs.push(x);
                    ys.push(y);
                }
            }
        }
    }
    let truth = scale
        .iter()
        .map(|s| (0..w * h).map(|p| s * tex.integral(p % w, p / w)).collect())
        .collect();
    let plane = ImagePlane::new(w, h).unwrap();
    (ImageSamples::new(plane, xs, ys, values).unwrap(), truth)
}

fn auto(samples: &ImageSamples) -> (PixelImage, EstimateReport) {
    let (r, report) = reconstruct_estimated(
        UniformEstimate::Auto,
        ImageMethod::Wavelet,
        samples,
        &WaveletParams::default(),
        &ShrinkParams::default(),
    )
    .unwrap();
    assert_eq!(report.estimate, UniformEstimate::Auto, "no fallback");
    (r.image, report)
}

/// Squared error summed over pixels and channels.
fn sse(image: &[Vec<f64>], truth: &[Vec<f64>]) -> f64 {
    image
        .iter()
        .zip(truth)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)))
        .sum()
}

/// On random textures past Nyquist with edges, with and without noise, at 4 and 16 samples a
/// pixel: the error of `auto` against the pixel integrals is at most the box's estimated risk
/// (`sum_P sum_c v_{P,c}`, the report's `box_risk` times the pixels) times 1.1, and at most the
/// box's actual error times 1.1.
///
/// Tolerance 10 %: the gate compares SUREs over 81-pixel windows, which estimate the risk with
/// a relative error of the order of `sqrt(2 / 81) = 16 %` per window before averaging over the
/// image's windows, and picks the least of 11 candidates there (an optimism of the same order
/// per window); over 48 x 48 = 2304 pixels (28 disjoint windows) what is left is a few
/// percent, and the box's own error fluctuates by `sqrt(2 / 6912) = 1.7 %` around its risk.
/// The noise-free cases (sigma = 0: only the jitter's variance, texture inside the pixels)
/// are the ones that catch a noise level taken from textured pixels.
#[test]
fn auto_never_exceeds_the_box_risk_on_random_textures() {
    let (w, h) = (48, 48);
    let mut worst: f64 = 0.0;
    for seed in 0..16u64 {
        let g = if seed % 2 == 0 { 2 } else { 4 };
        let sigma = [0.0, 0.02, 0.1, 0.3][(seed / 2 % 4) as usize];
        let (samples, truth) = textured(w, h, g, sigma, 1000 + seed);
        let (image, report) = auto(&samples);
        let stats = PixelStatistics::new(&samples);
        let err_auto = sse(&image.channels, &truth);
        let err_box = sse(&stats.mean, &truth);
        let box_risk = report.box_risk.unwrap() * (w * h) as f64;
        worst = worst.max(err_auto / err_box);
        assert!(
            err_auto <= 1.1 * box_risk && err_auto <= 1.1 * err_box,
            "seed {seed} (g {g}, sigma {sigma}): auto {err_auto:.4e}, box {err_box:.4e}, box's \
             estimated risk {box_risk:.4e}"
        );
    }
    eprintln!("worst ratio of auto's error to the box's: {worst:.3}");
}

/// A dark texture with bright bars: base 0.01-0.05, faint waves, and steps of +0.5 to +3 up and
/// back down again 1 to 4 pixels later (a glyph's stroke, a bright stripe), so that most
/// pixels are dark and sit beside bright ones: where relMSE weighs an error most.
fn dark_beside_bright(rng: &mut Pcg64, w: usize) -> Texture {
    let two_pi = 2.0 * std::f64::consts::PI;
    let waves = (0..2)
        .map(|_| {
            let f = |rng: &mut Pcg64| two_pi * rng.random_range(0.01..3.0);
            (
                rng.random_range(0.0..0.01),
                f(rng),
                rng.random_range(0.0..two_pi),
                f(rng),
                rng.random_range(0.0..two_pi),
            )
        })
        .collect();
    let mut steps = vec![];
    for _ in 0..rng.random_range(4..10) {
        let along_x: bool = rng.random();
        let at = rng.random_range(0.0..w as f64);
        let b = rng.random_range(0.5..3.0);
        steps.push((along_x, at, b));
        steps.push((along_x, at + rng.random_range(1.0..4.0), -b));
    }
    Texture {
        base: rng.random_range(0.01..0.05),
        waves,
        steps,
    }
}

/// Issue 38's relMSE target on synthetic scenes built for its failure (dark pixels beside
/// bright bars, [`dark_beside_bright`]; 2 x 2 and 4 x 4 jittered strata; noise 0, 0.01, 0.05
/// absolute, so that the dark pixels' relative noise ranges from none to large): `auto`'s
/// relative error against the pixel integrals is at most the per-pixel mean's, no tolerance
/// (the target itself; twelve fixed seeds, measured worst ratio 0.938 at 4 x 4 strata and
/// noise 0.01). Jittered strata only: under a multi-jittered sampler (Mitsuba's) the box errs
/// less on texture than any estimate from differences of strata says, which is where the
/// suite's text rows still miss (docs/measurements/estimators.md).
#[test]
fn auto_relative_error_is_not_above_the_means_beside_bright_bars() {
    let (w, h) = (48, 48);
    let mut worst: f64 = 0.0;
    for seed in 0..12u64 {
        let g = if seed % 2 == 0 { 2 } else { 4 };
        let sigma = [0.0, 0.01, 0.05][(seed / 2 % 3) as usize];
        let mut rng = Pcg64::seed_from_u64(7000 + seed);
        let tex = dark_beside_bright(&mut rng, w);
        let (samples, truth) = sampled(&tex, w, h, g, sigma, &mut rng);
        let (image, _) = auto(&samples);
        let mean = PixelStatistics::new(&samples).mean;
        let (ra, rm) = (
            common::metrics::relmse(&image.channels, &truth),
            common::metrics::relmse(&mean, &truth),
        );
        eprintln!(
            "seed {seed} (g {g}, sigma {sigma}): auto {ra:.4e}, mean {rm:.4e}, ratio {:.3}",
            ra / rm
        );
        worst = worst.max(ra / rm);
        assert!(
            ra <= rm,
            "seed {seed} (g {g}, sigma {sigma}): auto's relative error {ra:.4e}, the mean's \
             {rm:.4e}"
        );
    }
    eprintln!("worst ratio of auto's relative error to the mean's: {worst:.3}");
}

/// On the stored Mitsuba renders (64², 4 spp), `auto` is at least the per-pixel mean of the
/// same samples less 0.1 dB (PSNR of the clipped images), and its relMSE (eps 0.01) at most
/// the mean's times 1.02 — the targets of issue 38 (the 2 % on relMSE: the reference's own
/// noise at 1024 spp, about 1/256 of a 4 spp pixel's variance, and round-off of the ratio).
/// `direct` has no Monte Carlo noise: only texture and edges inside the pixels.
#[test]
fn auto_is_not_below_the_mean_on_the_stored_renders() {
    for scene in common::stored::STORED_SCENES {
        let (s, refs) = common::stored::stored_render(scene);
        let refs = &refs;
        let (image, _) = auto(&s);
        let mean = PixelStatistics::new(&s).mean;
        let psnr = |img: &[Vec<f64>]| common::metrics::psnr(img, refs);
        let relmse = |img: &[Vec<f64>]| common::metrics::relmse(img, refs);
        let (pa, pm) = (psnr(&image.channels), psnr(&mean));
        let (ra, rm) = (relmse(&image.channels), relmse(&mean));
        assert!(pa >= pm - 0.1, "{scene}: auto {pa:.2} dB, mean {pm:.2} dB");
        assert!(
            ra <= 1.02 * rm,
            "{scene}: auto relMSE {ra:.4e}, mean {rm:.4e}"
        );
    }
}

/// Random HDR samples (a few values up to 1e4 beside values near 0, the emitter's ring), at 2
/// to 5 samples a pixel on small odd planes.
fn hdr_samples() -> impl Strategy<Value = ImageSamples> {
    (3usize..12, 3usize..12, 2usize..6, any::<u64>()).prop_map(|(w, h, n, seed)| {
        let mut rng = Pcg64::seed_from_u64(seed);
        let (mut xs, mut ys, mut vs) = (vec![], vec![], vec![vec![]; 2]);
        for py in 0..h {
            for px in 0..w {
                for _ in 0..n {
                    xs.push(px as f64 + rng.random::<f64>());
                    ys.push(py as f64 + rng.random::<f64>());
                    for v in vs.iter_mut() {
                        let x: f64 = if rng.random::<f64>() < 0.05 {
                            rng.random_range(10.0..1e4)
                        } else {
                            rng.random_range(0.0..1.0)
                        };
                        v.push(x);
                    }
                }
            }
        }
        ImageSamples::new(ImagePlane::new(w, h).unwrap(), xs, ys, vs).unwrap()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Range: every `auto` pixel lies in the range of the samples in its 3x3 neighbourhood,
    /// the samples that shaped it at the finest scale (no negative radiance, no overshoot
    /// beside an emitter), exactly: the last step is that projection.
    #[test]
    fn auto_pixels_lie_in_their_neighbourhoods_sample_range(samples in hdr_samples()) {
        let (image, report) = auto(&samples);
        prop_assert!(report.description.contains("projected onto the range"));
        let plane = samples.plane();
        let (w, h) = (plane.width(), plane.height());
        let stats = PixelStatistics::new(&samples);
        for c in 0..samples.channels() {
            for py in 0..h {
                for px in 0..w {
                    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                    for qy in py.saturating_sub(1)..(py + 2).min(h) {
                        for qx in px.saturating_sub(1)..(px + 2).min(w) {
                            lo = lo.min(stats.min[c][qy * w + qx]);
                            hi = hi.max(stats.max[c][qy * w + qx]);
                        }
                    }
                    let v = image.channels[c][py * w + px];
                    prop_assert!(lo <= v && v <= hi, "({px}, {py}) c {c}: {v} not in [{lo}, {hi}]");
                }
            }
        }
    }
}

// The plan's coverage at low budgets (every pixel a sample at one sample a pixel or more,
// any plane) is tested on the whole run in tests/plan_coverage.rs.

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// The property of issue 38 over random synthetic textures plus noise (proptest: texture,
    /// strata 2 x 2 or 4 x 4, noise level in [0, 0.3]): `auto`'s squared error against the
    /// pixel integrals never exceeds the per-pixel mean's actual error, with the 10 % tolerance
    /// justified at `auto_never_exceeds_the_box_risk_on_random_textures`.
    ///
    /// Not asserted: "never exceeds the mean's *estimated* risk" (the report's `box_risk`,
    /// `sum_P sum_c v_{P,c}`), the wording. It is false with this noise estimate: `v_P`
    /// (the least of three difference estimates, `image/estimate/noise.rs`) is biased low where
    /// the texture varies inside a stratum, so at 4 x 4 strata and almost no noise the mean's
    /// estimated risk is below its actual error and `auto` (below the mean's actual error) can
    /// be above it: seed 16834185788934746027, fine, sigma 5.7e-4 gives auto 3.68e-2, the mean
    /// 3.76e-2, the mean's estimated risk 1.52e-2 (kept in the regression file, so that case
    /// runs first on every run). It cannot hold for any estimate made of differences of
    /// neighbouring strata: there the mean's error is deterministic texture inside the strata,
    /// of which the differences see 40 %; the pure-noise calibration (the report's
    /// `pure_noise_ratio`, 0.70 at 16 jittered samples) would lift the estimate to about
    /// 2.2e-2, still below auto's error (docs/measurements/estimators.md).
    #[test]
    fn auto_never_exceeds_the_means_error(
        seed in any::<u64>(),
        fine in any::<bool>(),
        sigma in 0.0f64..0.3,
    ) {
        let (w, h) = (48, 48);
        let g = if fine { 4 } else { 2 };
        let (samples, truth) = textured(w, h, g, sigma, seed);
        let (image, report) = auto(&samples);
        let stats = PixelStatistics::new(&samples);
        let err_auto = sse(&image.channels, &truth);
        let err_box = sse(&stats.mean, &truth);
        let box_risk = report.box_risk.unwrap() * (w * h) as f64;
        prop_assert!(
            err_auto <= 1.1 * err_box,
            "g {g}, sigma {sigma}: auto {err_auto:.4e}, box {err_box:.4e}, box's estimated risk \
             {box_risk:.4e}"
        );
    }
}
