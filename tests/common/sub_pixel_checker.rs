//! Texture past the pixel scale for the plan's final-image tests: a random sub-pixel checker
//! (cells of a third of a pixel, so every pixel integral is a deterministic mix the fit cannot
//! resolve) plus Gaussian noise, sampled as a plan samples (the adaptive run's positions, deep
//! where the tree deepens, plus a second set of 2 to 12 jittered samples a pixel, uneven by
//! pixel), and the final image's squared error against the pixel integrals next to the box's.

use rkwave::image::adaptive::correction::{
    output_pixels, PixelEstimate, ResidualCorrection, RESIDUAL_Z,
};
use rkwave::image::adaptive::{
    refine_image, AdaptiveParams, NoisyOracle, OutputParams, StopParams,
};
use rkwave::image::ImagePlane;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// The image's side in pixels.
pub const SIDE: usize = 32;

/// The random sub-pixel checker of `seed`: cells of 1/3 pixel, values in {0.1, 0.5, 0.9}.
pub fn checker(seed: u64) -> impl Fn(f64, f64) -> f64 + Sync {
    let cells = 3 * SIDE;
    let mut rng = Pcg64::seed_from_u64(seed);
    let table: Vec<f64> = (0..cells * cells)
        .map(|_| [0.1, 0.5, 0.9][rng.random_range(0..3)])
        .collect();
    move |x: f64, y: f64| {
        let i = ((x * 3.0) as usize).min(cells - 1);
        let j = ((y * 3.0) as usize).min(cells - 1);
        table[j * cells + i]
    }
}

/// A standard normal draw (Box–Muller).
pub fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * rng.random::<f64>()).cos()
}

/// (final image's squared error, the box's, the report) for one seed and noise level, the
/// final image's output pixels by `estimate`. The truth is each pixel's integral by a 24 x 24
/// midpoint rule (exact for the checker's cells up to their boundaries).
pub fn run(seed: u64, sigma: f64, estimate: PixelEstimate) -> (f64, f64, ResidualCorrection) {
    let plane = ImagePlane::new(SIDE, SIDE).unwrap();
    let f = checker(seed);
    let oracle = NoisyOracle {
        inner: &f,
        sigma,
        seed: seed + 100,
    };
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        output: OutputParams {
            pixels: estimate,
            ..AdaptiveParams::default().output
        },
        ..AdaptiveParams::default()
    };
    let run = refine_image(&oracle, plane, &params).unwrap();
    let mut rng = Pcg64::seed_from_u64(seed + 200);
    let (mut xs, mut ys, mut values) = (run.xs.clone(), run.ys.clone(), run.values.clone());
    for p in 0..plane.pixels() {
        let k = rng.random_range(2..=12);
        for _ in 0..k {
            let x = (p % SIDE) as f64 + rng.random::<f64>();
            let y = (p / SIDE) as f64 + rng.random::<f64>();
            xs.push(x);
            ys.push(y);
            values[0].push(f(x, y) + sigma * normal(&mut rng));
        }
    }
    let (_, image, report) = output_pixels(
        &run.tree,
        &run.fit,
        &xs,
        &ys,
        &values,
        estimate,
        run.report.pixels.sigma,
        RESIDUAL_Z,
    )
    .unwrap();
    let (mut sum, mut count) = (vec![0.0; plane.pixels()], vec![0usize; plane.pixels()]);
    for ((&x, &y), &v) in xs.iter().zip(&ys).zip(&values[0]) {
        let (px, py) = plane.pixel_of(x, y);
        sum[py * SIDE + px] += v;
        count[py * SIDE + px] += 1;
    }
    let (mut err_final, mut err_box) = (0.0, 0.0);
    for p in 0..plane.pixels() {
        let q = 24;
        let truth = (0..q * q)
            .map(|k| {
                let x = (p % SIDE) as f64 + ((k % q) as f64 + 0.5) / q as f64;
                let y = (p / SIDE) as f64 + ((k / q) as f64 + 0.5) / q as f64;
                f(x, y)
            })
            .sum::<f64>()
            / (q * q) as f64;
        err_final += (image.channels[0][p] - truth).powi(2);
        err_box += (sum[p] / count[p] as f64 - truth).powi(2);
    }
    (err_final, err_box, report)
}
