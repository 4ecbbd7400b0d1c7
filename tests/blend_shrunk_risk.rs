//! The plan's `blend` (`src/image/adaptive/correction.rs`, module docs, *Blend*): `shrunk`'s
//! SURE takes the divergence `d_S = d_pre d_H`, the correction's bound `d_pre = 1` times the
//! Haar shrinkage's exact divergence `d_H` in `[0, 1]`. So the divergence used never exceeds
//! the bound 1 (the risk is never above the one the bound gave, `(S - m)² + v`), and under
//! noise, where the shrinkage kills coefficients, it is below 1.

mod common;

use rkwave::image::adaptive::correction::{
    output_pixels, PixelEstimate, RESIDUAL_Z, SHRUNK_DIVERGENCE_BOUND,
};
use rkwave::image::adaptive::{
    refine_image, AdaptiveParams, NoisyOracle, OutputParams, StopParams,
};
use rkwave::image::ImagePlane;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use common::scenes::{jittered, straight_edge};

/// An adaptive run on the straight edge under Gaussian noise `sigma`, 4 samples a pixel,
/// plus two noisy jittered samples in every pixel (so `auto` and the blend run), its output
/// pixels by `blend`.
fn blend_report(sigma: f64) -> rkwave::image::adaptive::correction::ResidualCorrection {
    let plane = ImagePlane::new(32, 32).unwrap();
    let oracle = NoisyOracle {
        inner: &straight_edge,
        sigma,
        seed: 3,
    };
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        output: OutputParams {
            pixels: PixelEstimate::Blend,
            ..AdaptiveParams::default().output
        },
        ..AdaptiveParams::default()
    };
    let run = refine_image(&oracle, plane, &params).unwrap();
    let (jx, jy) = jittered(32, 32, 2, 5);
    let mut rng = Pcg64::seed_from_u64(6);
    let (mut xs, mut ys, mut values) = (run.xs.clone(), run.ys.clone(), run.values.clone());
    for (&x, &y) in jx.iter().zip(&jy) {
        // a standard normal deviate (Box–Muller)
        let u: f64 = rng.random::<f64>().max(1e-300);
        let z = (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * rng.random::<f64>()).cos();
        xs.push(x);
        ys.push(y);
        values[0].push(straight_edge(x, y) + sigma * z);
    }
    let (_, _, report) = output_pixels(
        &run.tree,
        &run.fit,
        &xs,
        &ys,
        &values,
        PixelEstimate::Blend,
        run.report.pixels.sigma,
        RESIDUAL_Z,
    )
    .unwrap();
    report
}

#[test]
fn shrunk_divergence_lies_in_zero_to_its_bound_and_below_it_under_noise() {
    let report = blend_report(0.05);
    if let Some(reason) = &report.auto_fallback {
        panic!("the blend fell back: {reason}");
    }
    let d = report
        .blend_shrunk_divergence
        .expect("the mean divergence of a blend that did not fall back");
    assert!((0.0..=SHRUNK_DIVERGENCE_BOUND).contains(&d), "{d}");
    // noise 0.05 on a 0/1 edge: the universal threshold kills most fine coefficients
    assert!(d < SHRUNK_DIVERGENCE_BOUND, "{d}");
    assert!(
        report.note().contains("exact one, mean"),
        "{}",
        report.note()
    );
}
