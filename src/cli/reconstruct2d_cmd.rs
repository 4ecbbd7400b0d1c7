//! `rkwave reconstruct --dim 2`: a renderer's image-plane samples (CSV `x,y,c1[,c2,c3,c4]` or
//! `.npy` `m x (2 + channels)`, positions in pixel units) onto pixels; with `--state`, on the
//! tree of an `rkwave plan` run.

use std::time::Instant;

use rkwave::image::estimate::{EstimateError, ShrinkParams};
use rkwave::image::report::FileReconstructionReport;
use rkwave::image::{reconstruct_estimated, Method, UniformEstimate, WaveletParams};
use rkwave::io::image_file::{write_image, ImageFormat};
use rkwave::io::output::check_output;
use rkwave::io::read_image_samples_with;

use super::image_args::{check_p, parse_resolution, spinner};
use super::reconstruct_args::ReconstructArgs;
use super::solve_args::MethodArg;
use super::CliError;

/// The wavelet parameters of `--p`, `--rho`, `--ridge` and `--smoothing` (each flag not
/// given keeps the image fit's default: rho 4, ridge 1e-9, smoothing 0).
fn wavelet_params(args: &ReconstructArgs) -> Result<WaveletParams, CliError> {
    let defaults = WaveletParams::default();
    let rho = args.solve.rho.unwrap_or(defaults.rho);
    if !(rho.is_finite() && rho > 0.0) {
        return Err(CliError::Invalid(format!(
            "--rho {rho} must be a positive number of samples per tensor function (the image \
             fit's default is 4)"
        )));
    }
    let ridge = args.solve.ridge.unwrap_or(defaults.ridge);
    if !(ridge.is_finite() && (0.0..1.0).contains(&ridge)) {
        return Err(CliError::Invalid(format!(
            "--ridge {ridge} must be in [0, 1) (the image fit's default is 1e-9)"
        )));
    }
    let smoothing = args.smoothing.unwrap_or(defaults.smoothing);
    if !(smoothing.is_finite() && smoothing >= 0.0) {
        return Err(CliError::Invalid(format!(
            "--smoothing {smoothing} must be a finite weight >= 0 (0: the least-squares fit)"
        )));
    }
    Ok(WaveletParams {
        p: check_p(args.filter().p)?,
        pixel_filter: None,
        rho,
        ridge,
        smoothing,
    })
}

/// The flags given that only the least-squares fit reads (`--p`, `--family`, `--method` other
/// than the default, `--levels` other than auto, `--rho`, `--ridge`, `--smoothing`).
fn fit_flags(args: &ReconstructArgs) -> Vec<&'static str> {
    [
        ("--p", args.p.is_some()),
        ("--family", args.family.is_some()),
        ("--method", args.method != MethodArg::Single),
        ("--levels", args.solve.levels != "auto"),
        ("--rho", args.solve.rho.is_some()),
        ("--ridge", args.solve.ridge.is_some()),
        ("--smoothing", args.smoothing.is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect()
}

/// The pixel estimate: `--pixels`, or `auto` unless fit-only flags ask for the fit (then
/// `fit`, with a note saying so).
fn choose_estimate(args: &ReconstructArgs) -> (UniformEstimate, Option<String>) {
    if let Some(e) = args.pixels {
        return (e, None);
    }
    let given = fit_flags(args);
    if given.is_empty() {
        return (UniformEstimate::Auto, None);
    }
    (
        UniformEstimate::Fit,
        Some(format!(
            "pixels: the least-squares fit, because {} (read by the fit only) was given without \
             --pixels; the default without them is --pixels auto (films chosen per pixel by \
             SURE), which uses no fit",
            given.join(", ")
        )),
    )
}

/// The memory request of `estimate` and what it is called: the fit's for `fit` and
/// `fit-clamped`, and for `auto` where its fallback to the fit applies (a pixel without
/// samples, or fewer than half with two: the rule of [`rkwave::image::estimate::auto`]);
/// otherwise the estimate's own, without a basis.
fn estimate_request(
    estimate: UniformEstimate,
    plane: rkwave::image::ImagePlane,
    samples: &rkwave::image::ImageSamples,
    wavelet: &WaveletParams,
    method: Method,
) -> (rkwave::resources::ImageRequest, String) {
    let fits = estimate.uses_fit()
        || (estimate == UniformEstimate::Auto && {
            let stats = rkwave::image::estimate::PixelStatistics::new(samples);
            stats.empty_pixels() > 0 || 2 * stats.pixels_with_spread() < plane.pixels()
        });
    let (channels, m) = (samples.channels(), samples.len() as f64);
    if fits {
        let request = super::image_memory::uniform_request(
            plane,
            channels,
            m,
            wavelet.p,
            wavelet.rho,
            method == Method::Local,
            1,
        );
        (request, method.to_string())
    } else {
        let request = super::image_memory::estimate_request(plane, channels, m, estimate);
        (request, format!("--pixels {estimate}"))
    }
}

/// Runs the 2D path of `rkwave reconstruct`.
pub fn run(args: &ReconstructArgs) -> Result<(), CliError> {
    let started = Instant::now();
    ImageFormat::from_path(&args.output).map_err(|e| CliError::flag("--output", e))?;
    if let (Some(_), Some(pixels)) = (&args.state, args.pixels) {
        return Err(CliError::Invalid(format!(
            "--pixels {pixels} is for the uniform path: with --state the plan's own output is \
             written (see --no-residual); drop --pixels or --state"
        )));
    }
    if args.state.is_some() {
        let given = [
            ("--rho", args.solve.rho.is_some()),
            ("--ridge", args.solve.ridge.is_some()),
            ("--smoothing", args.smoothing.is_some()),
            ("--tile", args.tile.is_some()),
            ("--halo", args.halo.is_some()),
            ("--workers", args.workers.is_some()),
        ];
        if let Some((flag, _)) = given.iter().find(|(_, g)| *g) {
            return Err(CliError::Invalid(format!(
                "{flag} is for the uniform fit: with --state the plan's tree and its own \
                 parameters are used; drop {flag} or --state"
            )));
        }
    }
    if args.tile.is_none() && (args.halo.is_some() || args.workers.is_some()) {
        return Err(CliError::Invalid(
            "--halo and --workers are for the tiled fit: give --tile T too, or drop them".into(),
        ));
    }
    // Before any work: the output is new (or --force), its folder exists and takes a file,
    // and it is none of the inputs (the samples, the plan's state), after links and spellings.
    let state_file = args
        .state
        .as_deref()
        .map(rkwave::image::adaptive::protocol::PlanState::path);
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(state_file.as_deref());
    check_output(&args.output, args.force, &inputs)?;
    if let Some(dir) = &args.state {
        return super::plan_cmd::reconstruct(args, dir, started);
    }
    let resolution = args.resolution.as_deref().ok_or_else(|| {
        CliError::Invalid("--dim 2 needs --resolution WxH (the image size in pixels)".into())
    })?;
    let plane = parse_resolution(resolution)?;
    let method = match args.method {
        MethodArg::Local => Method::Local,
        MethodArg::Single | MethodArg::Global => Method::Wavelet,
        MethodArg::Dense => {
            return Err(CliError::Invalid(
                "--method dense is 1D only; on the image plane use single, global or local".into(),
            ))
        }
    };
    let wavelet = wavelet_params(args)?;
    if let Some(tile) = args.tile {
        return super::reconstruct_tiles_cmd::run(args, plane, method, tile, &wavelet, started);
    }
    super::image_memory::check_reading(&args.input)?;
    let bar = spinner("reading samples");
    let (samples, dropped) = read_image_samples_with(
        &args.input,
        plane,
        super::plan_cmd::nonfinite(args.drop_nonfinite),
    )?;
    let read_s = started.elapsed().as_secs_f64();
    let (estimate, kept_fit) = choose_estimate(args);
    // Before the work: the fit (or the estimate without one) and the output image, from the
    // sizes read.
    let (request, by) = estimate_request(estimate, plane, &samples, &wavelet, method);
    if let Err(e) = super::image_memory::check(
        &request,
        format!(
            "reconstructing {} samples onto {plane} pixels by {by}",
            samples.len()
        ),
        "a smaller --resolution, fewer samples, or --method local / a lower --p",
    ) {
        bar.finish_and_clear();
        return Err(e);
    }
    bar.set_message("reconstructing");
    let (done, estimated) = reconstruct_estimated(
        estimate,
        method,
        &samples,
        &wavelet,
        &ShrinkParams::default(),
    )
    .map_err(|e| match e {
        EstimateError::Wavelet(e) => CliError::Wavelet(e),
        other => CliError::Estimate(other),
    })?;
    let used = estimated.estimate;
    let method = if used.uses_fit() {
        method
    } else {
        Method::Film(rkwave::image::filters::FilmFilterKind::Box)
    };
    bar.set_message("writing");
    let t_write = Instant::now();
    write_image(&args.output, &done.image, args.force)?;
    let write_s = t_write.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let mut report = FileReconstructionReport::new(
        &args.input,
        &args.output,
        plane,
        &samples,
        method,
        wavelet.p,
        &done,
        read_s,
        write_s,
        started.elapsed().as_secs_f64(),
    )
    .with_pixels(estimated);

    report.notes.extend(kept_fit);
    report.notes.extend(dropped.note());
    report.nonfinite = dropped;
    if args.json {
        super::print_json(&report);
    } else {
        let by = if used == UniformEstimate::Auto {
            "auto (a film per pixel by SURE)".to_string()
        } else {
            method.to_string()
        };
        println!(
            "{} samples x {} channels -> {plane} pixels by {by}{}, {:.3} s; wrote {}",
            report.samples,
            report.channels,
            report
                .functions
                .map_or(String::new(), |f| format!(" ({f} functions)")),
            report.time_s.total,
            args.output.display()
        );
        for note in &report.notes {
            println!("note: {note}");
        }
    }
    Ok(())
}
