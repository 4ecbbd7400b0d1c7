//! `rkwave reconstruct --dim 2`: a renderer's image-plane samples (CSV `x,y,c1[,c2,c3,c4]` or
//! `.npy` `m x (2 + channels)`, positions in pixel units) onto pixels. One library call per
//! job ([`rkwave::image::job`]): the uniform fit ([`UniformJob`]), the same tile by tile
//! with `--tile` ([`TiledJob`]), the final image of a plan with `--state` ([`PlanFinal`],
//! the call `rkwave plan --final-image` makes). This file parses the flags and prints.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use rkwave::error::Param;
use rkwave::image::estimate::ShrinkParams;
use rkwave::image::job::{FitOptions, ImageParams, PlanFinal, TileOptions, TiledJob, UniformJob};
use rkwave::image::report::{FileReconstructionReport, PlanReconstructionReport};
use rkwave::image::tiles::{TileReport, TiledInput, TiledReport};
use rkwave::image::{ImageMethod, ImagePlane, UniformEstimate};
use rkwave::io::image_file::{write_image, ImageFormat};
use rkwave::io::output::check_output;
use rkwave::io::read_image_samples_with;
use serde::Serialize;

use super::image_args::{load_plan, parse_resolution, spinner};
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
        .map(rkwave::image::plan::PlanState::path);
    let mut inputs = vec![args.input.as_path()];
    inputs.extend(state_file.as_deref());
    check_output(&args.output, args.force, &inputs)?;
    if let Some(dir) = &args.state {
        return plan_image(args, dir, started);
    }
    let resolution = args.resolution.as_deref().ok_or_else(|| {
        CliError::Invalid("--dim 2 needs --resolution WxH (the image size in pixels)".into())
    })?;
    let plane = parse_resolution(resolution)?;
    let params = image_params(args)?;
    if let Some(tile) = args.tile {
        return tiled(args, plane, &params, tile, started);
    }
    let job = UniformJob::new(plane, &params)?;
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

/// `rkwave reconstruct --dim 2 --state DIR`: the plan's final image from its state and the
/// samples ([`PlanFinal`]: the fit on the tree the samples were planned for, then the plan's
/// output pixels, or with `--no-residual` the fit's box pixels alone), written to `--output`.
fn plan_image(args: &ReconstructArgs, dir: &Path, started: Instant) -> Result<(), CliError> {
    // What this call asks for beyond the plan: refused (before the state is read), or said
    // not to be used.
    let asked = ImageParams {
        fit: FitOptions {
            p: args.p,
            rho: args.solve.rho,
            ridge: args.solve.ridge,
            smoothing: args.smoothing,
        },
        pixels: args.pixels,
        also_asked: [
            (Param::Family, args.family.is_some()),
            (Param::Method, args.method != MethodArg::Single),
            (Param::Tile, args.tile.is_some()),
            (Param::Halo, args.halo.is_some()),
            (Param::Workers, args.workers.is_some()),
        ]
        .into_iter()
        .filter_map(|(param, given)| given.then_some(param))
        .collect(),
        ..ImageParams::default()
    };
    PlanFinal::check_request(&asked)?;
    let state = load_plan(dir)?;
    let plane = args
        .resolution
        .as_deref()
        .map(parse_resolution)
        .transpose()?;
    let job = PlanFinal::new(&state, plane, &asked, args.no_residual)?;
    super::check_reading(&args.input)?;
    let (samples, dropped) = read_image_samples_with(
        &args.input,
        state.plane,
        rkwave::image::NonFinitePolicy::dropping(args.drop_nonfinite),
    )?;
    let done = job.run(&samples, dropped, None)?;
    write_image(&args.output, &done.image, args.force)?;
    let mut overridden: Vec<String> = done.solver_note.iter().cloned().collect();
    overridden.extend(super::hints::in_flags(|| job.notes()));
    let report = PlanReconstructionReport::new(
        &state,
        dir,
        &args.input,
        &args.output,
        &samples,
        &done,
        overridden,
        started.elapsed().as_secs_f64(),
    );
    if args.json {
        super::print_json(&report);
    } else {
        println!(
            "{} samples x {} channels (rounds 0..={}) -> {} pixels on the plan's tree ({} \
             functions, p = {}), {:.3} s; wrote {}",
            report.samples,
            report.channels,
            report.round,
            state.plane,
            report.fit.functions,
            report.p,
            report.time_s,
            args.output.display()
        );
        for note in &report.notes {
            super::print_note(note);
        }
    }
    Ok(())
}

/// The `--json` report of a tiled reconstruction.
#[derive(Serialize)]
struct TiledFileReport<'a> {
    input: String,
    output: String,
    resolution: String,
    p: usize,
    rho: f64,
    ridge: f64,
    /// What the tiled fit did, with every tile's report.
    tiled: &'a TiledReport,
    /// Seconds: reading (all passes), fitting, writing, total.
    time_s: Times,
    /// The job's decisions and what happened on the way, in words.
    notes: Vec<String>,
}

#[derive(Serialize)]
struct Times {
    read: f64,
    fit: f64,
    write: f64,
    total: f64,
}

/// `rkwave reconstruct --dim 2 --tile T [--halo H] [--workers N]`: the image fitted tile by
/// tile ([`TiledJob`]), the input read in chunks, the output written atomically once every
/// tile is solved. Band files go to `--scratch`, by default the output's folder.
fn tiled(
    args: &ReconstructArgs,
    plane: ImagePlane,
    params: &ImageParams,
    tile: usize,
    started: Instant,
) -> Result<(), CliError> {
    let scratch = args
        .scratch
        .clone()
        .unwrap_or_else(|| match args.output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        });
    let tiles = TileOptions {
        tile,
        halo: args.halo,
        workers: args.workers,
        scratch: Some(scratch),
    };
    let job = TiledJob::new(
        plane,
        params,
        &tiles,
        rkwave::image::NonFinitePolicy::dropping(args.drop_nonfinite),
    )?;
    let bar = if std::io::stderr().is_terminal() {
        ProgressBar::new(job.geometry().count() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} tiles {msg} [{elapsed}]")
            .expect("a valid template"),
    );
    let progress = |r: &TileReport| {
        bar.set_message(format!("tile {} {:.2} s", r.tile, r.seconds));
        bar.inc(1);
    };
    let done = job.run(TiledInput::File(&args.input), &progress);
    bar.finish_and_clear();
    let done = done?;
    let t_write = Instant::now();
    write_image(&args.output, &done.output.image, args.force)?;
    let write_s = t_write.elapsed().as_secs_f64();
    let r = &done.output.report;
    let wavelet = job.wavelet();
    let report = TiledFileReport {
        input: args.input.display().to_string(),
        output: args.output.display().to_string(),
        resolution: plane.to_string(),
        p: wavelet.p,
        rho: wavelet.rho,
        ridge: wavelet.ridge,
        tiled: r,
        time_s: Times {
            read: r.read_s,
            fit: r.fit_s,
            write: write_s,
            total: started.elapsed().as_secs_f64(),
        },
        notes: done.notes.clone(),
    };
    if args.json {
        super::print_json(&report);
    } else {
        println!(
            "{} samples x {} channels -> {plane} pixels by tiles of {} (halo {}, {} x {} tiles, \
             {} workers, {} passes over the input), {:.3} s; wrote {}",
            r.samples,
            r.channels,
            r.tile,
            r.halo,
            r.grid.0,
            r.grid.1,
            r.workers,
            r.passes,
            report.time_s.total,
            args.output.display()
        );
        for note in &report.notes {
            super::print_note(note);
        }
    }
    Ok(())
}
