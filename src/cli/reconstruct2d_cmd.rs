//! `rkwave reconstruct --dim 2`: a renderer's image-plane samples (CSV `x,y,c1[,c2,c3,c4]` or
//! `.npy` `m x (2 + channels)`, positions in pixel units) onto pixels; with `--state`, on the
//! tree of an `rkwave plan` run.

use std::time::Instant;

use rkwave::error::Param;
use rkwave::image::estimate::ShrinkParams;
use rkwave::image::job::{FitOptions, ImageParams, UniformJob};
use rkwave::image::report::FileReconstructionReport;
use rkwave::image::{ImageMethod, UniformEstimate};
use rkwave::io::image_file::{write_image, ImageFormat};
use rkwave::io::output::check_output;
use rkwave::io::read_image_samples_with;

use super::image_args::{parse_resolution, spinner};
use super::reconstruct_args::ReconstructArgs;
use super::solve_args::MethodArg;
use super::CliError;

/// The image job's parameters from the flags (each flag not given stays `None`: the
/// library's default, not asked for), and the method the flags ask for.
fn image_params(args: &ReconstructArgs) -> Result<ImageParams, CliError> {
    let method = match args.method {
        MethodArg::Local => ImageMethod::Local,
        MethodArg::Single | MethodArg::Global => ImageMethod::Wavelet,
        MethodArg::Dense => {
            return Err(CliError::Invalid(
                "--method dense is 1D only; on the image plane use single, global or local".into(),
            ))
        }
    };
    // Settings of this command line that only the fit reads and the job does not hold.
    let also_asked = [
        (Param::Family, args.family.is_some()),
        (Param::Method, args.method == MethodArg::Global),
        (Param::Levels, args.solve.levels != "auto"),
    ]
    .into_iter()
    .filter_map(|(param, given)| given.then_some(param))
    .collect();
    Ok(ImageParams {
        method,
        fit: FitOptions {
            p: args.p,
            rho: args.solve.rho,
            ridge: args.solve.ridge,
            smoothing: args.smoothing,
        },
        pixels: args.pixels,
        shrink: ShrinkParams::default(),
        also_asked,
    })
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
    let params = image_params(args)?;
    let job = UniformJob::new(plane, &params)?;
    if let Some(tile) = args.tile {
        return super::reconstruct_tiles_cmd::run(
            args,
            plane,
            params.method,
            tile,
            job.wavelet(),
            started,
        );
    }
    super::check_reading(&args.input)?;
    let bar = spinner("reading samples");
    let (samples, dropped) = read_image_samples_with(
        &args.input,
        plane,
        rkwave::image::NonFinitePolicy::dropping(args.drop_nonfinite),
    )?;
    let read_s = started.elapsed().as_secs_f64();
    bar.set_message("reconstructing");
    // The job checks the memory (the fit, or the estimate without one) before its work.
    let out = job.run(&samples);
    let out = match out {
        Ok(out) => out,
        Err(e) => {
            bar.finish_and_clear();
            return Err(e.into());
        }
    };
    let (done, estimated, method) = (out.reconstruction, out.estimate, out.method);
    let estimated = estimated.expect("the fit's path makes a pixel estimate");
    let used = estimated.estimate;
    let kept_fit = out.pixels.and_then(|c| super::hints::in_flags(|| c.note()));
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
        job.wavelet().p,
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
            super::print_note(note);
        }
    }
    Ok(())
}
