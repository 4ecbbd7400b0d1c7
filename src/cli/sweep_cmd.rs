//! `rkwave sweep`: the local-vs-global report over a grid of knobs, one knob at a time around
//! a base setting ([`rkwave::report::sweep`]), written as a CSV and a figure of error against
//! time (one curve per knob).

use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rkwave::plot::figures::sweep_figure;
use rkwave::report::sweep::{sweep, SweepKnobs};

use super::report_args::ReportArgs;
use super::{check_writable, figures, CliError};

/// `rkwave sweep`.
#[derive(Args, Debug)]
pub struct SweepArgs {
    /// The base setting (every knob not being swept keeps this value).
    #[command(flatten)]
    pub base: ReportArgs,
    /// Rings to sweep.
    #[arg(long, value_delimiter = ',', default_value = "0,1,2", value_parser = super::limits::rings)]
    pub sweep_rings: Vec<usize>,
    /// Vanishing moments to sweep (coarse level follows j_min(p) when it would be too small).
    #[arg(long, value_delimiter = ',', default_value = "2,3,4,5")]
    pub sweep_p: Vec<usize>,
    /// Coarse levels to sweep (relative: n = N - depth).
    #[arg(long, value_delimiter = ',', default_value = "1,2,3,4")]
    pub sweep_depth: Vec<u32>,
    /// Sample counts to sweep (oversampling m / P).
    #[arg(long, value_delimiter = ',', default_value = "640,1024,2048,4096", value_parser = super::limits::samples)]
    pub sweep_samples: Vec<usize>,
    /// Output folder for sweep.csv and sweep.png.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
    /// Overwrite existing outputs.
    #[arg(long)]
    pub force: bool,
}

/// Runs `rkwave sweep`.
pub fn run(args: &SweepArgs) -> Result<(), CliError> {
    let base = args.base.setting()?;
    let csv_path = args.out.join("sweep.csv");
    let png = args.out.join("sweep.png");
    check_writable(&csv_path, args.force)?;
    check_writable(&png, args.force)?;
    let knobs = SweepKnobs {
        rings: args.sweep_rings.clone(),
        p: args.sweep_p.clone(),
        depth: args.sweep_depth.clone(),
        samples: args.sweep_samples.clone(),
    };
    let bar = ProgressBar::new(0);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} {msg} {elapsed}").expect("template"),
    );
    let report = sweep(&base, &knobs, |i, total, point| {
        bar.set_length(total as u64);
        bar.set_position(i as u64);
        bar.set_message(format!("{} = {}", point.knob.name(), point.value()));
    })?;
    bar.finish_and_clear();
    std::fs::create_dir_all(&args.out).map_err(|source| CliError::Write {
        path: args.out.clone(),
        source,
    })?;
    let mut table = csv::Writer::from_writer(Vec::new());
    for row in report.csv_rows() {
        table
            .serialize(row)
            .map_err(|e| CliError::Internal(format!("the sweep table: {e}")))?;
    }
    let text = table
        .into_inner()
        .map_err(|e| CliError::Internal(format!("the sweep table: {e}")))?;
    rkwave::io::output::write_new(&csv_path, &text, args.force)?;
    figures::save_new(&sweep_figure(&report), &png, args.force)?;
    print!("{}", String::from_utf8_lossy(&text));
    eprintln!("wrote {} and {}", csv_path.display(), png.display());
    Ok(())
}
