//! The adaptive engine's `auto` output pixels (`src/image/adaptive/correction.rs`): the
//! uniform path's SURE film choice and shrinkage on the plan's own samples, one
//! implementation. Where every pixel holds a sample the output is the uniform `auto` of the
//! same samples bit for bit; where one does not, it is the `shrunk` output bit for bit, with
//! the reason in the report and the note.

mod common;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::adaptive::correction::{output_pixels, PixelEstimate, RESIDUAL_Z};
use rkwave::image::adaptive::{
    refine_image, AdaptiveImage, AdaptiveParams, NoisyOracle, OutputParams, StopParams,
};
use rkwave::image::estimate::auto;
use rkwave::image::estimate::ShrinkParams;
use rkwave::image::{ImagePlane, ImageSamples};

use common::scenes::{jittered, straight_edge};

const W: usize = 32;
const H: usize = 32;
const SIGMA: f64 = 0.05;

/// An adaptive run on the straight edge under Gaussian noise `SIGMA`, 4 samples per pixel.
fn run() -> AdaptiveImage {
    let plane = ImagePlane::new(W, H).unwrap();
    let oracle = NoisyOracle {
        inner: &straight_edge,
        sigma: SIGMA,
        seed: 11,
    };
    let params = AdaptiveParams {
        stop: StopParams {
            budget: 4 * plane.pixels(),
            ..AdaptiveParams::default().stop
        },
        output: OutputParams {
            pixels: PixelEstimate::Shrunk,
            ..AdaptiveParams::default().output
        },
        ..AdaptiveParams::default()
    };
    refine_image(&oracle, plane, &params).unwrap()
}

/// A standard normal deviate (Box–Muller).
fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

type Samples = (Vec<f64>, Vec<f64>, Vec<Vec<f64>>);

/// The run's samples plus two noisy jittered samples in every pixel: every pixel holds at
/// least two, as `auto` needs.
fn with_a_sample_everywhere(run: &AdaptiveImage) -> Samples {
    let (jx, jy) = jittered(W, H, 2, 5);
    let mut rng = Pcg64::seed_from_u64(6);
    let (mut xs, mut ys, mut values) = (run.xs.clone(), run.ys.clone(), run.values.clone());
    for (&x, &y) in jx.iter().zip(&jy) {
        xs.push(x);
        ys.push(y);
        values[0].push(straight_edge(x, y) + SIGMA * normal(&mut rng));
    }
    (xs, ys, values)
}

#[test]
fn auto_is_the_uniform_auto_of_the_same_samples() {
    let run = run();
    let (xs, ys, values) = with_a_sample_everywhere(&run);
    let (_, image, report) = output_pixels(
        &run.tree,
        &run.fit,
        &xs,
        &ys,
        &values,
        PixelEstimate::Auto,
        run.report.pixels.sigma,
        RESIDUAL_Z,
    )
    .unwrap();
    let plane = ImagePlane::new(W, H).unwrap();
    let samples = ImageSamples::new(plane, xs, ys, values).unwrap();
    let (uniform, uniform_report) = auto::estimate(&samples, &ShrinkParams::default()).unwrap();
    for (a, b) in image.channels[0].iter().zip(&uniform.channels[0]) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    assert_eq!(report.estimate, PixelEstimate::Auto);
    assert_eq!(report.auto_fallback, None);
    let films = report.films.as_ref().expect("the films chosen");
    assert_eq!(films, &uniform_report.films);
    assert_eq!(films.iter().map(|f| f.pixels).sum::<usize>(), W * H);
    assert_eq!(report.shrink_threshold, Some(uniform_report.threshold));
    assert!(report.note().contains("least SURE"), "{}", report.note());
}

#[test]
fn auto_falls_back_to_shrunk_where_a_pixel_is_empty() {
    let run = run();
    let (xs, ys, values) = with_a_sample_everywhere(&run);
    // no sample left in pixel (0, 0)
    let keep: Vec<usize> = (0..xs.len())
        .filter(|&i| xs[i] >= 1.0 || ys[i] >= 1.0)
        .collect();
    assert!(keep.len() < xs.len());
    let pick = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let (xs, ys) = (pick(&xs), pick(&ys));
    let values = vec![pick(&values[0])];
    let out = |estimate| {
        output_pixels(
            &run.tree,
            &run.fit,
            &xs,
            &ys,
            &values,
            estimate,
            run.report.pixels.sigma,
            RESIDUAL_Z,
        )
        .unwrap()
    };
    let (_, auto_image, auto_report) = out(PixelEstimate::Auto);
    let (_, shrunk_image, shrunk_report) = out(PixelEstimate::Shrunk);
    for (a, b) in auto_image.channels[0].iter().zip(&shrunk_image.channels[0]) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    let reason = auto_report.auto_fallback.as_deref().expect("the reason");
    assert!(reason.contains("no sample"), "{reason}");
    assert_eq!(auto_report.films, None);
    assert_eq!(auto_report.shrink_threshold, shrunk_report.shrink_threshold);
    assert_eq!(auto_report.corrected, shrunk_report.corrected);
    let note = auto_report.note();
    assert!(
        note.contains("fell back to shrunk") && note.contains(reason),
        "{note}"
    );
}

#[test]
fn auto_is_named_on_the_command_line() {
    assert_eq!("auto".parse::<PixelEstimate>(), Ok(PixelEstimate::Auto));
    assert_eq!(PixelEstimate::Auto.name(), "auto");
    let err = "autos".parse::<PixelEstimate>().unwrap_err();
    assert!(err.contains("box_shrunk or auto"), "{err}");
}
