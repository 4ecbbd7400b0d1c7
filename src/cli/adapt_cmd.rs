//! `rkwave adapt`: the adaptive refiner (DESIGN §6) on a built-in signal or an expression in
//! `x`, its error against the truth and against uniform sampling with as many samples, and
//! the supplement's figure 4 (reconstruction, samples, local depth, `K^T` aligned below).

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{Args, ValueEnum};
use rkwave::plot::{Figure, Panel, PanelContent, Scale, Series, SeriesStyle, SparsityPanel};
use rkwave::reconstruct::{fit, Fit, FitParams};
use rkwave::refine::{
    grid_error, quadrature_error, refine, ErrorFigures, ExpressionOracle, Indicator,
    Reconstruction, RefineError, RefineParams, Refinement, SampleOracle, SignalOracle,
};
use rkwave::sampling::{Domain, Layout, Signal};
use serde_json::{json, Value};

use super::{check_writable, figures, CliError, FamilyArg};

/// Refinement indicator on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum IndicatorArg {
    /// Predicted coefficients from their decay across levels (free).
    Coefficients,
    /// Residual at probe points per leaf (costs samples).
    Residual,
    /// Both.
    Both,
}

/// `rkwave adapt`.
#[derive(Args, Debug)]
pub struct AdaptArgs {
    /// The signal: a built-in name (smooth, polynomialN, jumps, kink, cusp, blocks, bumps,
    /// heavisine, doppler; stretched over the domain) or an expression in x such as
    /// "sin(8*x) + (x > 0.6)" (comparisons count as 1 or 0; unary minus binds tighter than ^).
    #[arg(long, allow_hyphen_values = true)]
    pub signal: String,
    /// Domain `a,b`.
    #[arg(long, default_value = "0,1", allow_hyphen_values = true)]
    pub domain: String,
    /// Vanishing moments p.
    #[arg(long, default_value_t = 3)]
    pub p: usize,
    /// Interior filter family (default CDV's choice).
    #[arg(long, value_enum)]
    pub family: Option<FamilyArg>,
    /// Coarse level n (default j_min(p)).
    #[arg(long)]
    pub coarse: Option<u32>,
    /// Target RMS error (as estimated by the indicator).
    #[arg(long, default_value_t = 1e-6)]
    pub tolerance: f64,
    /// Depth limit: finest wavelet level (at most 52; refinement stops earlier where f64 runs out of resolution).
    #[arg(long, default_value_t = 32)]
    pub max_depth: u32,
    /// Sample budget (base samples included).
    #[arg(long, default_value_t = 100_000, value_parser = super::limits::samples)]
    pub budget: usize,
    /// Seed of the base layout and the jitter.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Base samples.
    #[arg(long, default_value_t = 256, value_parser = super::limits::samples)]
    pub base_samples: usize,
    /// Base depth (default: the deepest the base samples fill with rho per leaf).
    #[arg(long)]
    pub base_depth: Option<u32>,
    /// Base layout: uniform, jittered, random, lowdiscrepancy, ...
    #[arg(long, default_value = "jittered")]
    pub layout: String,
    /// Local oversampling: samples per leaf (rounded up).
    #[arg(long, default_value_t = 2.0)]
    pub rho: f64,
    /// Dörfler marking fraction in (0, 1].
    #[arg(long, default_value_t = 0.5)]
    pub theta: f64,
    /// Refinement indicator.
    #[arg(long, value_enum, default_value_t = IndicatorArg::Coefficients)]
    pub indicator: IndicatorArg,
    /// Probe points per leaf and round (residual indicator).
    #[arg(long, default_value_t = 1, value_parser = super::limits::probes)]
    pub probes: usize,
    /// Points of the uniform grid on which errors are measured.
    #[arg(long, default_value_t = 65_536, value_parser = super::limits::grid)]
    pub grid: usize,
    /// Points of the grid on which every round's error is logged (0 = off; these oracle calls
    /// are not samples).
    #[arg(long, default_value_t = 4096, value_parser = super::limits::grid_or_zero)]
    pub round_grid: usize,
    /// Run adaptive and uniform over a range of sample counts and print both errors.
    #[arg(long)]
    pub compare_uniform: bool,
    /// Sample counts for --compare-uniform (default: 512, 1024, ... up to the budget).
    #[arg(long, value_delimiter = ',', value_parser = super::limits::samples)]
    pub counts: Vec<usize>,
    /// Figure (PNG, or SVG by extension): figure 4 of the supplement, or with
    /// --compare-uniform the error against samples.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Overwrite an existing figure.
    #[arg(long)]
    pub force: bool,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// The signal: a built-in one on the domain, or a parsed expression.
enum Source {
    Builtin(SignalOracle),
    Expression(ExpressionOracle),
}

impl Source {
    fn parse(text: &str, domain: Domain) -> Result<Self, CliError> {
        if let Ok(signal) = text.parse::<Signal>() {
            return Ok(Source::Builtin(SignalOracle::new(signal, domain)));
        }
        ExpressionOracle::parse(text)
            .map(Source::Expression)
            .map_err(|e| {
                CliError::Invalid(format!(
                    "--signal: {e} (built-in signals: smooth, polynomialN, jumps, kink, cusp, \
                     blocks, bumps, heavisine, doppler)"
                ))
            })
    }
    fn oracle(&self) -> &dyn SampleOracle {
        match self {
            Source::Builtin(s) => s,
            Source::Expression(e) => e,
        }
    }
    fn name(&self) -> String {
        match self {
            Source::Builtin(s) => s.signal.to_string(),
            Source::Expression(e) => e.text().to_string(),
        }
    }
    /// Singular points in unit coordinates (quadrature breaks), when known.
    fn singular_points(&self) -> Vec<f64> {
        match self {
            Source::Builtin(s) => s.signal.singular_points().to_vec(),
            Source::Expression(_) => Vec::new(),
        }
    }
}

impl AdaptArgs {
    /// The validated refiner parameters.
    pub fn params(&self, domain: Domain) -> Result<RefineParams, CliError> {
        let family = super::FilterSpec {
            p: self.p,
            family: self.family,
        }
        .family();
        let base_layout: Layout = self
            .layout
            .parse()
            .map_err(|e: rkwave::sampling::ParseLayoutError| CliError::Invalid(e.to_string()))?;
        if self.grid < 2 {
            return Err(CliError::Invalid(format!(
                "--grid {} is too small: give at least 2 points",
                self.grid
            )));
        }
        let indicator = match self.indicator {
            IndicatorArg::Coefficients => Indicator::Coefficients,
            IndicatorArg::Residual => Indicator::Residual {
                probes: self.probes,
            },
            IndicatorArg::Both => Indicator::Both {
                probes: self.probes,
            },
        };
        let params = RefineParams {
            domain,
            p: self.p,
            family: Some(family),
            coarse: self.coarse,
            base_samples: self.base_samples,
            base_layout,
            base_depth: self.base_depth,
            max_depth: self.max_depth,
            rho: self.rho,
            tolerance: self.tolerance,
            budget: self.budget,
            indicator,
            theta: self.theta,
            seed: self.seed,
            reference_grid: self.round_grid,
            ..RefineParams::default()
        };
        params.validate().map_err(refine_error)?;
        Ok(params)
    }
}

/// Refiner errors: bad input (exit 2), except failures of the machine.
fn refine_error(e: RefineError) -> CliError {
    match e {
        RefineError::Basis(b) => CliError::Basis(b),
        other => CliError::Invalid(other.to_string()),
    }
}

/// Errors of one reconstruction against the truth.
struct Errors {
    grid: ErrorFigures,
    quadrature: ErrorFigures,
}

fn errors<R: Reconstruction + ?Sized>(
    rec: &R,
    source: &Source,
    domain: Domain,
    grid: usize,
    cells: &[f64],
) -> Result<Errors, CliError> {
    let oracle = source.oracle();
    let mut breaks: Vec<f64> = cells.to_vec();
    breaks.extend(source.singular_points());
    breaks.extend((0..4096).map(|i| i as f64 / 4096.0));
    Ok(Errors {
        grid: grid_error(rec, oracle, domain, grid).map_err(refine_error)?,
        quadrature: quadrature_error(rec, oracle, domain, &breaks, 2).map_err(refine_error)?,
    })
}

fn adaptive_errors(
    r: &Refinement,
    source: &Source,
    domain: Domain,
    grid: usize,
) -> Result<Errors, CliError> {
    let cells: Vec<f64> = r.tree.leaves().iter().map(|l| l.unit_bounds().0).collect();
    errors(r, source, domain, grid, &cells)
}

/// The default fit on `m` uniform samples and its errors.
fn uniform(
    m: usize,
    params: &RefineParams,
    source: &Source,
    grid: usize,
) -> Result<(Fit, Errors), CliError> {
    let domain = params.domain;
    let xs = Layout::Uniform.generate(m, domain, params.seed);
    let oracle = source.oracle();
    let values: Vec<f64> = xs.iter().map(|&x| oracle.sample(x)).collect();
    if let Some((x, v)) = xs.iter().zip(&values).find(|(_, v)| !v.is_finite()) {
        return Err(refine_error(RefineError::NonFiniteValue {
            x: *x,
            value: *v,
        }));
    }
    let fp = FitParams {
        p: params.p,
        family: Some(params.family()),
        ..FitParams::default()
    };
    let fitted = fit(&xs, &[&values], domain, &fp)?;
    let cells_level = fitted.levels.fine + 1;
    let n = 1u64 << cells_level.min(20);
    let cells: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    let e = errors(&fitted, source, domain, grid, &cells)?;
    Ok((fitted, e))
}

/// Runs `rkwave adapt`.
pub fn run(args: &AdaptArgs) -> Result<(), CliError> {
    let domain: Domain = args.domain.parse()?;
    let params = args.params(domain)?;
    let source = Source::parse(&args.signal, domain)?;
    if let Some(plot) = &args.plot {
        check_writable(plot, args.force)?;
    }
    if args.compare_uniform {
        return compare(args, &params, &source);
    }
    let t0 = Instant::now();
    let r = refine(source.oracle(), &params).map_err(refine_error)?;
    let refine_s = t0.elapsed().as_secs_f64();
    let (_, rebuild) = r.rebuild().map_err(refine_error)?;
    let adaptive = adaptive_errors(&r, &source, domain, args.grid)?;
    let m = r.samples.len();
    let (ufit, uerr) = uniform(m, &params, &source, args.grid)?;
    let refined_rounds: Vec<f64> = r
        .rounds
        .iter()
        .skip(1)
        .filter(|l| l.new_samples > 0)
        .map(|l| l.times.total_s)
        .collect();
    let mean_round = refined_rounds.iter().sum::<f64>() / refined_rounds.len().max(1) as f64;
    // The last round that computed an estimate (the final fit after a stop has none).
    let rounds_estimate = r.rounds.iter().rev().find_map(|l| l.estimated_error);
    let report = json!({
        "signal": source.name(),
        "domain": [domain.a(), domain.b()],
        "p": params.p,
        "coarse": params.coarse(),
        "base_depth": r.base_depth,
        "depth_limit": params.max_depth,
        "samples": m,
        "base_samples": r.base_samples(),
        "refinement_samples": m - r.base_samples(),
        "basis_size": r.columns.len(),
        "max_depth": r.tree.depth(),
        "leaves": r.tree.leaves().len(),
        "error_l2": adaptive.grid.l2,
        "error_max": adaptive.grid.max,
        "error_grid_points": adaptive.grid.points,
        "error_l2_quadrature": adaptive.quadrature.l2,
        "estimated_error": rounds_estimate,
        "stop": r.stop,
        "rounds": r.rounds,
        "uniform": {
            "samples": m,
            "coarse": ufit.levels.coarse,
            "fine": ufit.levels.fine,
            "basis_size": ufit.active.len(),
            "error_l2": uerr.grid.l2,
            "error_max": uerr.grid.max,
            "error_l2_quadrature": uerr.quadrature.l2,
        },
        "ratio_l2": uerr.grid.l2 / adaptive.grid.l2,
        "ratio_l2_quadrature": uerr.quadrature.l2 / adaptive.quadrature.l2,
        "time_s": {
            "refine": refine_s,
            "round_mean": mean_round,
            "round_last": refined_rounds.last().copied().unwrap_or(0.0),
            "full_rebuild": rebuild.total_s,
            "full_rebuild_kernel": rebuild.sample_s + rebuild.kernel_s,
            "full_rebuild_solve": rebuild.solve_s,
        },
    });
    if let Some(plot) = &args.plot {
        figure4(&r, &source, plot)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&report).expect("plain data")
        );
    } else {
        print!("{}", table(&report));
        if let Some(plot) = &args.plot {
            println!("wrote {}", plot.display());
        }
    }
    Ok(())
}

/// The report for people.
fn table(r: &Value) -> String {
    let f = |v: &Value| v.as_f64().unwrap_or(f64::NAN);
    let rounds = r["rounds"].as_array().map_or(0, |a| a.len());
    format!(
        "adaptive {}: {} samples ({} base, {} refinement), P = {}, depth {}..{} (limit {}), \
         {} rounds, stop: {}\n\
         \x20 error      RMS {:.3e} (grid of {}), max {:.3e}; L2/quadrature {:.3e}; estimated {:.3e}\n\
         \x20 uniform    {} samples, P = {}: RMS {:.3e}, max {:.3e}; L2/quadrature {:.3e}\n\
         \x20 ratio      {:.1}x (grid RMS), {:.1}x (L2 by quadrature)\n\
         \x20 time       refine {:.3} s, one round {:.2e} s (mean; last {:.2e} s), full rebuild {:.2e} s\n",
        r["signal"].as_str().unwrap_or(""),
        r["samples"],
        r["base_samples"],
        r["refinement_samples"],
        r["basis_size"],
        r["base_depth"],
        r["max_depth"],
        r["depth_limit"],
        rounds,
        r["stop"].as_str().unwrap_or(""),
        f(&r["error_l2"]),
        r["error_grid_points"],
        f(&r["error_max"]),
        f(&r["error_l2_quadrature"]),
        f(&r["estimated_error"]),
        r["uniform"]["samples"],
        r["uniform"]["basis_size"],
        f(&r["uniform"]["error_l2"]),
        f(&r["uniform"]["error_max"]),
        f(&r["uniform"]["error_l2_quadrature"]),
        f(&r["ratio_l2"]),
        f(&r["ratio_l2_quadrature"]),
        f(&r["time_s"]["refine"]),
        f(&r["time_s"]["round_mean"]),
        f(&r["time_s"]["round_last"]),
        f(&r["time_s"]["full_rebuild"]),
    )
}

/// `--compare-uniform`: both methods over a range of sample counts.
fn compare(args: &AdaptArgs, params: &RefineParams, source: &Source) -> Result<(), CliError> {
    let counts: Vec<usize> = if args.counts.is_empty() {
        (9..=24)
            .map(|k| 1usize << k)
            .filter(|&c| c <= params.budget)
            .collect()
    } else {
        args.counts.clone()
    };
    if counts.is_empty() {
        return Err(CliError::Invalid(format!(
            "--compare-uniform: no sample count up to the budget {}: give --counts or a budget \
             of at least 512",
            params.budget
        )));
    }
    let mut rows = Vec::new();
    for &c in &counts {
        let p = RefineParams {
            budget: c,
            reference_grid: 0,
            ..*params
        };
        p.validate().map_err(refine_error)?;
        let r = refine(source.oracle(), &p).map_err(refine_error)?;
        let a = adaptive_errors(&r, source, params.domain, args.grid)?;
        let m = r.samples.len();
        let (_, u) = uniform(m, params, source, args.grid)?;
        rows.push(json!({
            "budget": c,
            "samples": m,
            "max_depth": r.tree.depth(),
            "stop": r.stop,
            "adaptive_l2": a.grid.l2,
            "adaptive_l2_quadrature": a.quadrature.l2,
            "uniform_l2": u.grid.l2,
            "uniform_l2_quadrature": u.quadrature.l2,
            "ratio_l2": u.grid.l2 / a.grid.l2,
            "ratio_l2_quadrature": u.quadrature.l2 / a.quadrature.l2,
        }));
    }
    if let Some(plot) = &args.plot {
        comparison_figure(&rows, &source.name(), plot)?;
    }
    if args.json {
        let out = json!({ "signal": source.name(), "comparison": rows });
        println!(
            "{}",
            serde_json::to_string_pretty(&out).expect("plain data")
        );
    } else {
        println!(
            "{}: adaptive vs uniform (RMS on a grid of {}; L2 by quadrature)",
            source.name(),
            args.grid
        );
        println!(
            "{:>8} {:>8} {:>5} {:>11} {:>11} {:>10} {:>11} {:>11} {:>10}",
            "budget",
            "samples",
            "depth",
            "adapt RMS",
            "unif RMS",
            "ratio",
            "adapt L2",
            "unif L2",
            "ratio"
        );
        for row in &rows {
            let f = |k: &str| row[k].as_f64().unwrap_or(f64::NAN);
            println!(
                "{:>8} {:>8} {:>5} {:>11.3e} {:>11.3e} {:>10.1} {:>11.3e} {:>11.3e} {:>10.1}",
                row["budget"].as_u64().unwrap_or(0),
                row["samples"].as_u64().unwrap_or(0),
                row["max_depth"].as_i64().unwrap_or(0),
                f("adaptive_l2"),
                f("uniform_l2"),
                f("ratio_l2"),
                f("adaptive_l2_quadrature"),
                f("uniform_l2_quadrature"),
                f("ratio_l2_quadrature")
            );
        }
        if let Some(plot) = &args.plot {
            println!("wrote {}", plot.display());
        }
    }
    Ok(())
}

/// Log-log error against samples, adaptive and uniform.
fn comparison_figure(rows: &[Value], name: &str, path: &Path) -> Result<(), CliError> {
    let curve = |key: &str| -> Vec<(f64, f64)> {
        rows.iter()
            .map(|r| {
                (
                    r["samples"].as_f64().unwrap_or(f64::NAN),
                    r[key].as_f64().unwrap_or(f64::NAN),
                )
            })
            .collect()
    };
    let panel = Panel {
        title: format!("{name}: error against samples"),
        x_label: "samples".into(),
        y_label: "error".into(),
        x_scale: Scale::Log10,
        y_scale: Scale::Log10,
        series: vec![
            Series::new(
                "adaptive, RMS on grid",
                curve("adaptive_l2"),
                SeriesStyle::LineMarkers,
            )
            .with_color(3),
            Series::new(
                "uniform, RMS on grid",
                curve("uniform_l2"),
                SeriesStyle::LineMarkers,
            )
            .with_color(0),
            Series::new(
                "adaptive, L2 (quadrature)",
                curve("adaptive_l2_quadrature"),
                SeriesStyle::Dashed,
            )
            .with_color(3),
            Series::new(
                "uniform, L2 (quadrature)",
                curve("uniform_l2_quadrature"),
                SeriesStyle::Dashed,
            )
            .with_color(0),
        ],
        ..Panel::default()
    };
    figures::save(&Figure::new(900, 650, vec![panel.into()]), path)
}

/// Figure 4 of the supplement for this run: reconstruction over the truth, base (grey) and
/// refinement (red) samples as crosses on the axis, the local depth (magenta, scaled into the
/// chart), and below it the pattern of `K^T` with each sample's column at its abscissa.
fn figure4(r: &Refinement, source: &Source, path: &Path) -> Result<(), CliError> {
    let domain = r.tree.domain();
    let points = 4000;
    let mut xs: Vec<f64> = (0..=points)
        .map(|i| domain.from_unit(i as f64 / points as f64))
        .collect();
    // Resolve the refined zones: the leaf ends too.
    xs.extend(
        r.tree
            .leaves()
            .iter()
            .filter(|l| l.level > r.base_depth + 1)
            .map(|l| domain.from_unit(l.unit_bounds().0)),
    );
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let recon = r.evaluate(&xs).map_err(refine_error)?;
    let oracle = source.oracle();
    let truth: Vec<(f64, f64)> = xs.iter().map(|&x| (x, oracle.sample(x))).collect();
    let (lo, hi) = truth
        .iter()
        .map(|p| p.1)
        .chain(recon.iter().copied())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
    let span = if hi > lo { hi - lo } else { 1.0 };
    let (y0, y1) = (lo - 0.18 * span, hi + 0.08 * span);
    let cross_y = lo - 0.11 * span;
    let base: Vec<(f64, f64)> = r
        .samples
        .iter()
        .filter(|s| s.round == 0)
        .map(|s| (s.x, cross_y))
        .collect();
    let refined: Vec<(f64, f64)> = r
        .samples
        .iter()
        .filter(|s| s.round > 0)
        .map(|s| (s.x, cross_y))
        .collect();
    let leaves = r.tree.leaves();
    let shallowest = leaves.iter().map(|l| l.depth()).min().unwrap_or(0);
    let d_lo = shallowest as f64 - 1.0;
    let d_hi = (r.tree.depth() as f64).max(d_lo + 1.0);
    let scale = |d: f64| lo + (d - d_lo) / (d_hi - d_lo) * (hi - lo);
    let mut depth = Vec::new();
    for leaf in &leaves {
        let (a, b) = leaf.unit_bounds();
        let y = scale(leaf.depth() as f64);
        depth.push((domain.from_unit(a), y));
        depth.push((domain.from_unit(b), y));
    }
    let chart = Panel {
        title: format!(
            "adaptive reconstruction of {}: {} samples ({} base), P = {}, depth {}..{}",
            source.name(),
            r.samples.len(),
            r.base_samples(),
            r.columns.len(),
            r.base_depth,
            r.tree.depth()
        ),
        x_label: "x".into(),
        y_label: "f(x)".into(),
        series: vec![
            Series::new("signal", truth, SeriesStyle::Line).with_color(7),
            Series::new(
                "reconstruction",
                xs.iter().copied().zip(recon).collect(),
                SeriesStyle::Dashed,
            )
            .with_color(0),
            Series::new(
                format!("local depth ({d_lo} at the bottom, {d_hi} at the top)"),
                depth,
                SeriesStyle::Line,
            )
            .with_color(6),
            Series::new("base samples", base, SeriesStyle::Crosses).with_color(7),
            Series::new("refinement samples", refined, SeriesStyle::Crosses).with_color(3),
        ],
        x_range: Some((domain.a(), domain.b())),
        y_range: Some((y0, y1)),
        ..Panel::default()
    };
    let mut entries = Vec::with_capacity(r.kernel.nnz());
    for (i, row) in r.kernel.outer_iterator().enumerate() {
        for (c, _) in row.iter() {
            entries.push((c, i));
        }
    }
    let pattern = SparsityPanel {
        title: "K^T: basis functions (coarse on top) x samples (at their abscissa)".into(),
        x_label: "x".into(),
        y_label: "basis function".into(),
        shape: (r.columns.len(), r.samples.len()),
        entries,
        x_positions: Some(r.samples.iter().map(|s| s.x).collect()),
        x_range: Some((domain.a(), domain.b())),
        ..SparsityPanel::default()
    };
    let fig = Figure::new(
        1100,
        1050,
        vec![PanelContent::Chart(chart), PanelContent::Sparsity(pattern)],
    );
    figures::save(&fig, path)
}
