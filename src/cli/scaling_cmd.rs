//! `rkwave scaling`: end-to-end time and peak memory against the number of samples
//! ([`rkwave::report::scaling`]). Each configuration runs in its own process (this binary
//! with the hidden `--one` flag) so that peak memory (the kernel's `VmHWM`) belongs to it
//! alone; this file is that process management and the table.

use std::process::Command as Process;

use clap::Args;
use rkwave::report::scaling::{scaling_run, ScalingMethod, ScalingRow, ScalingSetting};

use super::CliError;

/// `rkwave scaling`.
#[derive(Args, Debug)]
pub struct ScalingArgs {
    /// Sample counts (e.g. 1e4,1e5,1e6,1e7).
    #[arg(long, value_delimiter = ',', default_value = "1e4,1e5,1e6", value_parser = super::limits::size)]
    pub sizes: Vec<f64>,
    /// Channel counts.
    #[arg(long, value_delimiter = ',', default_value = "1,3", value_parser = super::limits::channels)]
    pub channels: Vec<usize>,
    /// Methods: single, global, local0 (rings 0, SVD), local1 (rings 1, SVD).
    #[arg(long, value_enum, value_delimiter = ',', default_value = "single")]
    pub methods: Vec<ScalingMethod>,
    /// Evaluation grid (points); 0 means as many points as samples.
    #[arg(long, default_value_t = 1_000_000, value_parser = super::limits::grid_or_zero)]
    pub grid: usize,
    /// Print JSON rows.
    #[arg(long)]
    pub json: bool,
    /// Internal: run one configuration in this process.
    #[arg(long, hide = true)]
    pub one: bool,
}

/// The table's row for people.
fn table_row(row: &ScalingRow) -> String {
    format!(
        "| {} | {} | {} | {} | {}..{} | {:.3} | {:.3} | {:.3} | {:.0} | {:.0} | {:.1e} |{}",
        row.samples,
        row.channels,
        row.method,
        row.functions,
        row.levels.0,
        row.levels.1,
        row.time_s,
        row.solve_s,
        row.evaluate_s,
        row.ns_per_sample,
        row.peak_mb,
        row.rms_error,
        row.fallback
            .as_deref()
            .map_or(String::new(), |f| format!(" {f}"))
    )
}

/// Runs `rkwave scaling`.
pub fn run(args: &ScalingArgs) -> Result<(), CliError> {
    if args.grid == 1 {
        return Err(CliError::Invalid(
            "--grid must be at least 2 (or 0: as many points as samples)".into(),
        ));
    }
    let sizes: Vec<usize> = args
        .sizes
        .iter()
        .map(|&s| {
            if s.is_finite() && s >= 1.0 {
                Ok(s.round() as usize)
            } else {
                Err(CliError::Invalid(format!(
                    "--sizes: {s} is not a sample count"
                )))
            }
        })
        .collect::<Result<_, _>>()?;
    let grid_for = |m: usize| if args.grid == 0 { m.max(2) } else { args.grid };
    if args.one {
        let (Some(&m), Some(&channels), Some(&method)) =
            (sizes.first(), args.channels.first(), args.methods.first())
        else {
            return Err(CliError::Invalid(
                "--one needs one size, one channel count and one method".into(),
            ));
        };
        let row = scaling_run(&ScalingSetting {
            samples: m,
            channels,
            method,
            grid: grid_for(m),
        })?;
        println!("{}", serde_json::to_string(&row).expect("plain data"));
        return Ok(());
    }
    let exe = std::env::current_exe().map_err(|source| CliError::Write {
        path: "current executable".into(),
        source,
    })?;
    let mut rows = Vec::new();
    if !args.json {
        println!("| samples | channels | method | P | levels | total (s) | solve (s) | evaluate (s) | ns/sample | peak MB | RMS error |");
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
    }
    for &m in &sizes {
        for &c in &args.channels {
            for &method in &args.methods {
                let out = Process::new(&exe)
                    .args(["scaling", "--one", "--sizes", &m.to_string()])
                    .args(["--channels", &c.to_string(), "--methods", method.name()])
                    .args(["--grid", &args.grid.to_string()])
                    .output()
                    .map_err(|source| CliError::Write {
                        path: exe.clone(),
                        source,
                    })?;
                if !out.status.success() {
                    return Err(CliError::Invalid(format!(
                        "scaling run m = {m}, channels = {c}, {method} failed: {}",
                        String::from_utf8_lossy(&out.stderr)
                    )));
                }
                let row: ScalingRow = serde_json::from_slice(&out.stdout).map_err(|e| {
                    CliError::Internal(format!("a scaling row from the child process: {e}"))
                })?;
                if !args.json {
                    println!("{}", table_row(&row));
                }
                rows.push(row);
            }
        }
    }
    if args.json {
        super::print_json(&rows);
    }
    Ok(())
}
