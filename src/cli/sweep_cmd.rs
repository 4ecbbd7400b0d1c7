//! `rkwave sweep`: the local-vs-global report over a grid of knobs, one knob at a time around
//! a base setting, written as a CSV and a figure of error against time (one curve per knob).

use std::fmt::Write as _;
use std::path::PathBuf;

use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use rkwave::basis::minimum_level;
use rkwave::plot::{Figure, Panel, Scale, Series, SeriesStyle};
use rkwave::report::{local_vs_global, LocalGlobalReport, ReportSetting};
use rkwave::solve::Solver;

use super::report_cmd::ReportArgs;
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

/// One row of the sweep.
struct Row {
    knob: &'static str,
    value: String,
    report: LocalGlobalReport,
}

/// Runs `rkwave sweep`.
pub fn run(args: &SweepArgs) -> Result<(), CliError> {
    let base = args.base.setting()?;
    let csv = args.out.join("sweep.csv");
    let png = args.out.join("sweep.png");
    check_writable(&csv, args.force)?;
    check_writable(&png, args.force)?;
    let mut settings: Vec<(&'static str, String, ReportSetting)> = Vec::new();
    for &r in &args.sweep_rings {
        let mut s = base;
        s.local.rings = r;
        settings.push(("rings", r.to_string(), s));
    }
    for solver in [Solver::Svd, Solver::Qr, Solver::Cholesky] {
        let mut s = base;
        s.local.solver = solver;
        settings.push(("solver", format!("{solver:?}").to_lowercase(), s));
    }
    for &p in &args.sweep_p {
        let mut s = base;
        s.p = p;
        s.family = rkwave::basis::FilterFamily::cdv_default(p);
        s.coarse = s.coarse.max(minimum_level(p)).min(s.fine);
        settings.push(("p", p.to_string(), s));
    }
    for &d in &args.sweep_depth {
        let mut s = base;
        s.coarse = s.fine.saturating_sub(d).max(minimum_level(s.p));
        settings.push(("coarse level", s.coarse.to_string(), s));
    }
    for &m in &args.sweep_samples {
        let mut s = base;
        s.samples = m;
        settings.push(("samples", m.to_string(), s));
    }
    let bar = ProgressBar::new(settings.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} {msg} {elapsed}").expect("template"),
    );
    let mut rows = Vec::new();
    for (knob, value, s) in settings {
        bar.set_message(format!("{knob} = {value}"));
        let report = local_vs_global(&s)?;
        rows.push(Row {
            knob,
            value,
            report,
        });
        bar.inc(1);
    }
    bar.finish_and_clear();
    std::fs::create_dir_all(&args.out).map_err(|source| CliError::Write {
        path: args.out.clone(),
        source,
    })?;
    let mut text = String::from(
        "knob,value,p,coarse,fine,samples,rings,solver,rows_median,cols_median,max_abs,rms,\
         rel_frobenius,local_vs_global,local_vs_truth,global_vs_truth,condition_max,\
         time_kernel,time_local,time_global\n",
    );
    for r in &rows {
        let s = &r.report.setting;
        let e = r.report.error.as_ref();
        let _ = writeln!(
            text,
            "{},{},{},{},{},{},{},{:?},{},{},{:e},{:e},{:e},{:e},{:e},{:e},{:e},{},{},{}",
            r.knob,
            r.value,
            s.p,
            s.coarse,
            s.fine,
            s.samples,
            s.local.rings,
            s.local.solver,
            r.report.submatrix.rows.median,
            r.report.submatrix.cols.median,
            e.map_or(f64::NAN, |e| e.max_abs),
            e.map_or(f64::NAN, |e| e.rms),
            e.map_or(f64::NAN, |e| e.rel_frobenius),
            r.report.reconstruction.local_vs_global,
            r.report.reconstruction.local_vs_truth,
            r.report.reconstruction.global_vs_truth,
            r.report.condition.max,
            r.report.time_s.kernel,
            r.report.time_s.local,
            r.report.time_s.global
        );
    }
    std::fs::write(&csv, &text).map_err(|source| CliError::Write {
        path: csv.clone(),
        source,
    })?;
    let knobs = ["rings", "solver", "p", "coarse level", "samples"];
    let series: Vec<Series> = knobs
        .iter()
        .enumerate()
        .map(|(c, k)| {
            let pts = rows
                .iter()
                .filter(|r| r.knob == *k)
                .filter_map(|r| {
                    r.report
                        .error
                        .as_ref()
                        .map(|e| (r.report.time_s.local, e.max_abs.max(1e-17)))
                })
                .collect();
            Series::new(k.to_string(), pts, SeriesStyle::LineMarkers).with_color(c)
        })
        .collect();
    let fig = Figure {
        width: 1000,
        height: 700,
        columns: 1,
        panels: vec![Panel {
            title: format!(
                "max |K~ - K+| vs time (base: p = {}, levels {}..{}, {} {})",
                base.p, base.coarse, base.fine, base.samples, base.layout
            ),
            x_label: "local inversion time (s)".into(),
            y_label: "max |K~ - K+|".into(),
            x_scale: Scale::Log10,
            y_scale: Scale::Log10,
            series,
            ..Panel::default()
        }
        .into()],
    };
    figures::save(&fig, &png)?;
    print!("{text}");
    eprintln!("wrote {} and {}", csv.display(), png.display());
    Ok(())
}
