//! `rkwave reconstruct`: a user's samples onto a grid ([`rkwave::report::reconstruction`]).

use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use rkwave::io::output::check_output;
use rkwave::io::{read_samples, validate_positions, GridWriter};
use rkwave::reconstruct::{fit, FitParams};
use rkwave::report::reconstruction::{onto_grid, ReconstructReport, ReconstructTimes};

use super::reconstruct_args::ReconstructArgs;
use super::CliError;

/// Runs `rkwave reconstruct --dim 1` (the flags checked and the dimension dispatched by
/// [`ReconstructArgs::checked_dim`]).
pub fn run(args: &ReconstructArgs) -> Result<(), CliError> {
    let started = Instant::now();
    check_output(&args.output, args.force, &[&args.input])?;
    if args.grid < 2 {
        return Err(CliError::Invalid(format!(
            "--grid {} is too small: give at least 2 points",
            args.grid
        )));
    }
    let params = FitParams {
        p: args.filter().p,
        family: args.filter().family_given(),
        levels: args.solve.levels()?,
        method: args.solve.method(args.method)?,
    };
    if super::reconstruct_stream::chooses_streaming(args, &params)? {
        return super::reconstruct_stream::run(args, &params, started);
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("template"));
    bar.set_message("reading samples");
    let set = read_samples(&args.input)?;
    let read_s = started.elapsed().as_secs_f64();
    let domain = match args.domain {
        Some(d) => d,
        None => {
            let (a, b) = set.bounds().ok_or(CliError::Invalid("no samples".into()))?;
            super::reconstruct_stream::domain_of_bounds(a, b)?
        }
    };
    validate_positions(&set, domain)?;
    bar.set_message("fitting");
    let channels: Vec<&[f64]> = set.values.iter().map(|v| v.as_slice()).collect();
    let fitted = fit(&set.positions, &channels, domain, &params)?;
    bar.set_message("evaluating and writing");
    // The grid is evaluated and written block by block, never held whole: `.npy` (NumPy
    // float64, G x (1 + channels)) for readers with numpy, CSV otherwise, into a temporary
    // file moved into place at the end.
    let mut writer = GridWriter::create(&args.output, &set.names_or_default(), args.grid)?;
    let rec = onto_grid(fitted, &set, domain, args.grid, |xs, values| {
        writer.write_block(xs, values).map_err(CliError::from)
    })?;
    let t_finish = Instant::now();
    writer.finish(args.force)?;
    let finish_s = t_finish.elapsed().as_secs_f64();
    bar.finish_and_clear();
    let report = ReconstructReport::new(
        args.input.clone(),
        args.output.clone(),
        &set,
        &params.method,
        &rec,
        ReconstructTimes::of_command(read_s, finish_s, started),
    );
    if args.json {
        super::print_json(&report);
    } else {
        for w in &report.warnings {
            eprintln!("warning: {w}");
        }
        println!(
            "{} samples x {} channels -> {}; wrote {}",
            report.samples,
            report.channels,
            super::reconstruct_stream::fit_summary(&report, &rec.residual_rms),
            args.output.display()
        );
    }
    Ok(())
}
