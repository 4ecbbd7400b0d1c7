//! `rkwave reconstruct`: a user's samples onto a grid.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rkwave::io::output::check_output;
use rkwave::io::{read_samples, validate_positions, GridWriter};
use rkwave::reconstruct::{fit, FitParams, SolveReport};
use rkwave::sampling::Domain;
use serde_json::json;

use super::solve_args::{MethodArg, SolveArgs};
use super::{CliError, FamilyArg};

/// Grid points evaluated and written per block.
const GRID_BLOCK: usize = 1 << 16;

/// `rkwave reconstruct`.
#[derive(Args, Debug)]
pub struct ReconstructArgs {
    /// Samples: CSV with header `x,value[,value...]` or NumPy `.npy` (m x (1 + channels)).
    #[arg(long)]
    pub input: PathBuf,
    /// Domain `a,b` (default: the smallest and largest sample position).
    #[arg(long, allow_hyphen_values = true)]
    pub domain: Option<String>,
    /// Vanishing moments p.
    #[arg(long, default_value_t = 3)]
    pub p: usize,
    /// Interior filter family (default CDV's choice).
    #[arg(long, value_enum)]
    pub family: Option<FamilyArg>,
    /// Solve method.
    #[arg(long, value_enum, default_value_t = MethodArg::Single)]
    pub method: MethodArg,
    /// Solve knobs.
    #[command(flatten)]
    pub solve: SolveArgs,
    /// Grid points of the output (uniform, both ends included).
    #[arg(long, default_value_t = 1000, value_parser = super::limits::grid)]
    pub grid: usize,
    /// Output: `.npy` (NumPy float64, G x (1 + channels)) or CSV (`x,<channels>`) otherwise;
    /// written while the grid is evaluated.
    #[arg(long)]
    pub output: PathBuf,
    /// Overwrite an existing output.
    #[arg(long)]
    pub force: bool,
    /// Print a JSON report.
    #[arg(long)]
    pub json: bool,
    /// Dimension of the sample positions: 1 (`x,value...`) or 2 (image plane, `x,y,c1...`,
    /// see `reconstruct2d_cmd`).
    #[arg(long, default_value_t = 1)]
    pub dim: usize,
    /// Image resolution `WxH` (with `--dim 2`).
    #[arg(long)]
    pub resolution: Option<String>,
}

/// Runs `rkwave reconstruct`.
pub fn run(args: &ReconstructArgs) -> Result<(), CliError> {
    match args.dim {
        1 => {}
        2 => return super::reconstruct2d_cmd::run(args),
        d => return Err(CliError::Invalid(format!("--dim {d}: expected 1 or 2"))),
    }
    let started = Instant::now();
    check_output(&args.output, args.force, &[&args.input])?;
    if args.grid < 2 {
        return Err(CliError::Invalid(format!(
            "--grid {} is too small: give at least 2 points",
            args.grid
        )));
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("template"));
    bar.set_message("reading samples");
    let set = read_samples(&args.input)?;
    let read_s = started.elapsed().as_secs_f64();
    let domain = match &args.domain {
        Some(d) => d.parse::<Domain>()?,
        None => {
            let (a, b) = set.bounds().ok_or(CliError::Invalid("no samples".into()))?;
            Domain::new(a, b).map_err(|e| match e {
                rkwave::sampling::DomainError::NotIncreasing { .. } => CliError::Invalid(format!(
                    "all samples sit at x = {}: give --domain a,b explicitly",
                    rkwave::norms::show(a)
                )),
                other => CliError::Invalid(format!(
                    "the samples span [{}, {}], which is no usable domain: {other}",
                    rkwave::norms::show(a),
                    rkwave::norms::show(b)
                )),
            })?
        }
    };
    validate_positions(&set, domain)?;
    let family = super::BasisSpec {
        p: args.p,
        family: args.family,
        coarse: None,
        fine: 0,
        domain: String::new(),
    }
    .family();
    let params = FitParams {
        p: args.p,
        family: Some(family),
        levels: args.solve.levels()?,
        method: args.solve.method(args.method)?,
    };
    bar.set_message("fitting");
    let channels: Vec<&[f64]> = set.values.iter().map(|v| v.as_slice()).collect();
    let fitted = fit(&set.positions, &channels, domain, &params)?;
    bar.set_message("evaluating and writing");
    // The grid is evaluated and written block by block (never held whole).
    let evaluator = fitted.evaluator()?;
    let names = set.names_or_default();
    let mut writer = GridWriter::create(&args.output, &names, args.grid)?;
    let (mut evaluate_s, mut write_s) = (0.0, 0.0);
    let last = (args.grid - 1) as f64;
    for start in (0..args.grid).step_by(GRID_BLOCK) {
        let t = Instant::now();
        let xs: Vec<f64> = (start..(start + GRID_BLOCK).min(args.grid))
            .map(|i| domain.from_unit(i as f64 / last))
            .collect();
        let values = evaluator.evaluate(&xs)?;
        evaluate_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        writer.write_block(&xs, &values)?;
        write_s += t.elapsed().as_secs_f64();
    }
    let t = Instant::now();
    writer.finish(args.force)?;
    write_s += t.elapsed().as_secs_f64();
    let at_samples = evaluator.evaluate(&set.positions)?;
    let residual_rms: Vec<f64> = at_samples
        .iter()
        .zip(&set.values)
        .map(|(r, f)| rkwave::norms::rms_difference(r, f))
        .collect();
    bar.finish_and_clear();
    let total = started.elapsed().as_secs_f64();
    let report = json!({
        "input": args.input,
        "output": args.output,
        "samples": set.len(),
        "channels": set.channels(),
        "domain": [domain.a(), domain.b()],
        "p": args.p,
        "method": format!("{:?}", args.method).to_lowercase(),
        "functions": fitted.active.len(),
        "coarse": fitted.levels.coarse,
        "fine": fitted.levels.fine,
        "oversampling": fitted.levels.oversampling,
        "grid": args.grid,
        "residual_rms": if residual_rms.len() == 1 { json!(residual_rms[0]) } else { json!(residual_rms) },
        "time_s": {
            "read": read_s,
            "kernel": fitted.timings.kernel_s,
            "solve": fitted.timings.solve_s,
            "evaluate": evaluate_s,
            "write": write_s,
            "total": total,
        },
        "local": match &fitted.solve {
            SolveReport::Local(s) => json!({
                "groups": s.n_groups,
                "cut_groups": s.cut_groups,
                "condition": s.condition_summary(),
            }),
            _ => json!(null),
        },
        "single_scale": match &fitted.solve {
            SolveReport::SingleScale(rep) => json!(rep),
            _ => json!(null),
        },
        "fallbacks": fitted
            .fallbacks
            .iter()
            .map(|f| json!({ "fallback": f, "message": f.to_string() }))
            .collect::<Vec<_>>(),
        "warnings": fitted.warnings(),
    });
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("plain data")
        );
    } else {
        for w in fitted.warnings() {
            eprintln!("warning: {w}");
        }
        println!(
            "{} samples x {} channels -> P = {} functions (levels {}..{}, oversampling {:.2}), \
             residual RMS [{}], {:.3} s; wrote {}",
            set.len(),
            set.channels(),
            fitted.active.len(),
            fitted.levels.coarse,
            fitted.levels.fine,
            fitted.levels.oversampling,
            residual_rms
                .iter()
                .map(|r| format!("{r:.3e}"))
                .collect::<Vec<_>>()
                .join(", "),
            total,
            args.output.display()
        );
        for f in &fitted.fallbacks {
            println!("note: {f}");
        }
    }
    Ok(())
}
