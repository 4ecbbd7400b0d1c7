//! The front door's decisions, checked against the stages it calls.

use super::*;
use crate::error::{ErrorKind, Param};
use crate::image::estimate::ShrinkParams;
use crate::image::{reconstruct_estimated, ImageMethod, ImagePlane, ImageSamples, UniformEstimate};

fn plane() -> ImagePlane {
    ImagePlane::new(16, 12).expect("a valid plane")
}

/// Four samples a pixel on a deterministic scatter (golden-ratio steps), one smooth channel.
fn samples() -> ImageSamples {
    let m = 4 * 16 * 12;
    let xs: Vec<f64> = (0..m)
        .map(|i| 16.0 * (i as f64 * 0.618_034).fract())
        .collect();
    let ys: Vec<f64> = (0..m)
        .map(|i| 12.0 * (i as f64 * 0.754_878).fract())
        .collect();
    let f: Vec<f64> = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (x / 5.0).sin() + y / 12.0)
        .collect();
    ImageSamples::new(plane(), xs, ys, vec![f]).expect("valid samples")
}

/// Each range names its parameter (as data) and the value given.
#[test]
fn out_of_range_parameters_are_named() {
    let cases: [(FitOptions, Param); 5] = [
        (
            FitOptions {
                p: Some(7),
                ..Default::default()
            },
            Param::P,
        ),
        (
            FitOptions {
                rho: Some(0.0),
                ..Default::default()
            },
            Param::Rho,
        ),
        (
            FitOptions {
                rho: Some(f64::NAN),
                ..Default::default()
            },
            Param::Rho,
        ),
        (
            FitOptions {
                ridge: Some(1.0),
                ..Default::default()
            },
            Param::Ridge,
        ),
        (
            FitOptions {
                smoothing: Some(-1.0),
                ..Default::default()
            },
            Param::Smoothing,
        ),
    ];
    for (fit, param) in cases {
        let params = ImageParams {
            fit,
            ..Default::default()
        };
        match UniformJob::new(plane(), &params) {
            Err(e @ JobError::OutOfRange { param: p, .. }) => {
                assert_eq!(p, param);
                assert_eq!(e.kind(), ErrorKind::InvalidInput);
                assert!(e.to_string().starts_with(param.in_library()), "{e}");
            }
            other => panic!("{param:?}: {other:?}"),
        }
    }
}

/// The default estimate is `auto`; a fit parameter asked for makes it the fit, with the
/// parameters named in the order of the messages; an estimate asked for is kept.
#[test]
fn the_default_estimate_follows_the_parameters_asked() {
    let auto = PixelChoice::of(&ImageParams::default()).expect("the fit's path");
    assert_eq!(auto.estimate, UniformEstimate::Auto);
    assert!(auto.note().is_none());
    let asked = ImageParams {
        method: ImageMethod::Local,
        fit: FitOptions {
            p: Some(3),
            smoothing: Some(0.1),
            ..Default::default()
        },
        also_asked: vec![Param::Levels],
        ..Default::default()
    };
    let fit = PixelChoice::of(&asked).expect("the fit's path");
    assert_eq!(fit.estimate, UniformEstimate::Fit);
    assert_eq!(
        fit.because,
        [Param::P, Param::Method, Param::Levels, Param::Smoothing]
    );
    assert!(fit
        .note()
        .expect("a note")
        .contains("UniformEstimate::Auto"));
    let kept = ImageParams {
        pixels: Some(UniformEstimate::Shrunk),
        ..asked
    };
    assert_eq!(
        PixelChoice::of(&kept).map(|c| c.estimate),
        Some(UniformEstimate::Shrunk)
    );
    let film = ImageParams {
        method: ImageMethod::Film(crate::image::filters::FilmFilterKind::Gaussian),
        ..Default::default()
    };
    assert!(PixelChoice::of(&film).is_none());
    let both = ImageParams {
        pixels: Some(UniformEstimate::Box),
        ..film
    };
    assert!(matches!(
        UniformJob::new(plane(), &both),
        Err(JobError::Conflict { .. })
    ));
}

/// The job's pixels are the stage's own, bit for bit: the front door decides, it does not
/// compute differently.
#[test]
fn the_job_computes_what_the_stage_computes() {
    let s = samples();
    for pixels in [
        UniformEstimate::Auto,
        UniformEstimate::Fit,
        UniformEstimate::Shrunk,
    ] {
        let params = ImageParams {
            pixels: Some(pixels),
            ..Default::default()
        };
        let job = UniformJob::new(plane(), &params).expect("valid");
        let out = job.run(&s).expect("reconstructs");
        let (direct, _) = reconstruct_estimated(
            pixels,
            ImageMethod::Wavelet,
            &s,
            &crate::image::WaveletParams::default(),
            &ShrinkParams::default(),
        )
        .expect("reconstructs");
        assert_eq!(
            out.reconstruction.image.channels, direct.image.channels,
            "{pixels}"
        );
    }
}
