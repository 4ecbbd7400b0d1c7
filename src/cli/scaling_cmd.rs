//! `rkwave scaling`: end-to-end time and peak memory against the number of samples (uniform
//! random samples, automatic levels, `rho = 2`), for the single-scale global solve, the sparse
//! global solve on the multilevel `K`, and local inversion. Each configuration runs in its own
//! process so that peak memory (the kernel's `VmHWM`) belongs to it alone.

use std::process::Command as Process;
use std::time::Instant;

use clap::Args;
use rkwave::reconstruct::{fit, FitParams, Method};
use rkwave::sampling::{Domain, Layout, Signal};
use rkwave::solve::{GlobalLsParams, LocalInversionParams, Solver};
use serde::{Deserialize, Serialize};

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
    #[arg(long, value_delimiter = ',', default_value = "single")]
    pub methods: Vec<String>,
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

/// One measured configuration.
#[derive(Debug, Serialize, Deserialize)]
pub struct ScalingRow {
    /// Samples.
    pub samples: usize,
    /// Channels.
    pub channels: usize,
    /// Method.
    pub method: String,
    /// Basis functions.
    pub functions: usize,
    /// Levels.
    pub levels: (u32, u32),
    /// Seconds: generating samples is excluded; kernel + solve + evaluation on the grid.
    pub time_s: f64,
    /// Seconds of the solve alone.
    pub solve_s: f64,
    /// Seconds of the grid evaluation.
    pub evaluate_s: f64,
    /// Nanoseconds per sample, end to end.
    pub ns_per_sample: f64,
    /// Peak resident memory of the process (MB).
    pub peak_mb: f64,
    /// RMS error against the true signals on the grid (max over channels).
    pub rms_error: f64,
    /// The fallback taken, if any.
    pub fallback: Option<String>,
}

fn method(name: &str) -> Result<Method, CliError> {
    Ok(match name {
        "single" => Method::SingleScale {
            ridge: 0.0,
            solver: Default::default(),
        },
        "global" => Method::Global(GlobalLsParams::default()),
        // SVD: the Cholesky solver squares the blocks' condition numbers (up to 3e7 for
        // random samples), which ruins accuracy.
        "local0" | "local1" => Method::Local(LocalInversionParams {
            rings: if name == "local0" { 0 } else { 1 },
            solver: Solver::Svd,
            ..LocalInversionParams::default()
        }),
        other => {
            return Err(CliError::Invalid(format!(
                "unknown method {other:?}: use single, global, local0 or local1"
            )))
        }
    })
}

fn peak_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmHWM:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|kb| kb.parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn run_one(m: usize, channels: usize, name: &str, grid_n: usize) -> Result<ScalingRow, CliError> {
    let domain = Domain::UNIT;
    let signals = [Signal::Smooth, Signal::HeaviSine, Signal::Doppler];
    let xs = Layout::Random.generate(m, domain, 7);
    let values: Vec<Vec<f64>> = (0..channels)
        .map(|c| signals[c % 3].sample(domain, &xs))
        .collect();
    let refs: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
    let params = FitParams {
        method: method(name)?,
        ..FitParams::default()
    };
    let grid_n = if grid_n == 0 { m } else { grid_n };
    let grid: Vec<f64> = (0..grid_n)
        .map(|i| domain.from_unit(i as f64 / (grid_n - 1) as f64))
        .collect();
    let t = Instant::now();
    let fitted = fit(&xs, &refs, domain, &params)?;
    let t_eval = Instant::now();
    let out = fitted.evaluate(&grid)?;
    let evaluate_s = t_eval.elapsed().as_secs_f64();
    let time_s = t.elapsed().as_secs_f64();
    let rms_error = out
        .iter()
        .enumerate()
        .map(|(c, r)| {
            let truth = signals[c % 3].sample(domain, &grid);
            (r.iter()
                .zip(&truth)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                / grid_n as f64)
                .sqrt()
        })
        .fold(0.0, f64::max);
    Ok(ScalingRow {
        samples: m,
        channels,
        method: name.to_string(),
        functions: fitted.active.len(),
        levels: (fitted.levels.coarse, fitted.levels.fine),
        time_s,
        solve_s: fitted.timings.solve_s,
        evaluate_s,
        ns_per_sample: time_s / m as f64 * 1e9,
        peak_mb: peak_mb(),
        rms_error,
        fallback: (!fitted.fallbacks.is_empty()).then(|| {
            let notes: Vec<String> = fitted.fallbacks.iter().map(ToString::to_string).collect();
            notes.join("; ")
        }),
    })
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
    if args.one {
        let row = run_one(sizes[0], args.channels[0], &args.methods[0], args.grid)?;
        println!("{}", serde_json::to_string(&row).expect("plain data"));
        return Ok(());
    }
    for m in &args.methods {
        method(m)?;
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
            for name in &args.methods {
                let out = Process::new(&exe)
                    .args(["scaling", "--one", "--sizes", &m.to_string()])
                    .args(["--channels", &c.to_string(), "--methods", name])
                    .args(["--grid", &args.grid.to_string()])
                    .output()
                    .map_err(|source| CliError::Write {
                        path: exe.clone(),
                        source,
                    })?;
                if !out.status.success() {
                    return Err(CliError::Invalid(format!(
                        "scaling run m = {m}, channels = {c}, {name} failed: {}",
                        String::from_utf8_lossy(&out.stderr)
                    )));
                }
                let row: ScalingRow = serde_json::from_slice(&out.stdout)
                    .map_err(|e| CliError::Invalid(format!("bad scaling row: {e}")))?;
                if !args.json {
                    println!(
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
                        row.fallback.as_deref().map_or(String::new(), |f| format!(" {f}"))
                    );
                }
                rows.push(row);
            }
        }
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).expect("plain data")
        );
    }
    Ok(())
}
