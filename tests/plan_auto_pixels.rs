//! The adaptive engine's `auto` output pixels (`src/image/adaptive/correction.rs`): the
//! uniform path's SURE film choice and shrinkage on the plan's own samples, one
//! implementation. Where every pixel holds a sample the output is the uniform `auto` of the
//! same samples bit for bit; where one does not, it is the `shrunk` output bit for bit, with
//! the reason in the report and the note. `blend` (the inverse-risk combination of `shrunk`
//! and `auto`) lies between the two in every pixel and channel, and is `shrunk` bit for bit
//! where `auto` falls back.

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
    assert_eq!(report.auto_description, Some(uniform_report.describe()));
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
    assert!(
        err.contains("box_shrunk, auto, blend, blend_gated or blend_sure"),
        "{err}"
    );
    assert_eq!(
        "blend-gated".parse::<PixelEstimate>(),
        Ok(PixelEstimate::BlendGated)
    );
}

/// `output_pixels` of the run's tree and fit on the given samples.
fn pixels_of(run: &AdaptiveImage, samples: &Samples, estimate: PixelEstimate) -> Outputs {
    let (xs, ys, values) = samples;
    output_pixels(
        &run.tree,
        &run.fit,
        xs,
        ys,
        values,
        estimate,
        run.report.pixels.sigma,
        RESIDUAL_Z,
    )
    .unwrap()
}

type Outputs = (
    rkwave::image::PixelImage,
    rkwave::image::PixelImage,
    rkwave::image::adaptive::correction::ResidualCorrection,
);

/// Weights in `[0, 1]` summing to 1 (`w S + (1 - w) A`): each blended pixel lies between the
/// `shrunk` and the `auto` pixel, and so its squared error against the scene's pixel is at
/// most the larger of theirs.
#[test]
fn blend_lies_between_shrunk_and_auto_in_every_pixel() {
    let run = run();
    let samples = with_a_sample_everywhere(&run);
    let (_, blend, report) = pixels_of(&run, &samples, PixelEstimate::Blend);
    let (_, shrunk, _) = pixels_of(&run, &samples, PixelEstimate::Shrunk);
    let (_, auto_image, _) = pixels_of(&run, &samples, PixelEstimate::Auto);
    assert_eq!(report.estimate, PixelEstimate::Blend);
    assert_eq!(report.auto_fallback, None);
    let w = report.blend_weight.expect("the mean weight");
    assert!((0.0..=1.0).contains(&w), "{w}");
    let unknown = report
        .blend_unknown_risk
        .expect("the count of unknown risks");
    assert!(unknown <= blend.channels[0].len());
    assert_eq!(unknown > 0, report.note().contains("risk unknown"));
    let (mut moved_off_shrunk, mut moved_off_auto) = (0, 0);
    for ((&b, &s), &a) in blend.channels[0]
        .iter()
        .zip(&shrunk.channels[0])
        .zip(&auto_image.channels[0])
    {
        let slack = 1e-15 * (1.0 + s.abs().max(a.abs()));
        assert!(
            s.min(a) - slack <= b && b <= s.max(a) + slack,
            "{s} {a} {b}"
        );
        moved_off_shrunk += usize::from(b != s);
        moved_off_auto += usize::from(b != a);
    }
    // both inputs take part (neither risk is zero or infinite everywhere)
    assert!(moved_off_shrunk > 0 && moved_off_auto > 0);
    assert!(report.note().contains("inverse-risk"), "{}", report.note());
}

#[test]
fn blend_is_shrunk_where_auto_falls_back() {
    let run = run();
    let (xs, ys, values) = with_a_sample_everywhere(&run);
    let keep: Vec<usize> = (0..xs.len())
        .filter(|&i| xs[i] >= 1.0 || ys[i] >= 1.0)
        .collect();
    let pick = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<_>>();
    let samples = (pick(&xs), pick(&ys), vec![pick(&values[0])]);
    let (_, blend, report) = pixels_of(&run, &samples, PixelEstimate::Blend);
    let (_, shrunk, shrunk_report) = pixels_of(&run, &samples, PixelEstimate::Shrunk);
    for (a, b) in blend.channels[0].iter().zip(&shrunk.channels[0]) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    let reason = report.auto_fallback.as_deref().expect("the reason");
    assert!(reason.contains("no sample"), "{reason}");
    assert_eq!(report.blend_weight, None);
    assert_eq!(report.blend_unknown_risk, None);
    assert_eq!(report.shrink_threshold, shrunk_report.shrink_threshold);
    assert!(
        report.note().contains("blend fell back to shrunk"),
        "{}",
        report.note()
    );
    assert_eq!("blend".parse::<PixelEstimate>(), Ok(PixelEstimate::Blend));
}
