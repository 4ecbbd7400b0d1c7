//! `rkwave adapt`: the adaptive refiner (docs/design.md §6) on a built-in signal or an expression in
//! `x`, its error against the truth and against uniform sampling with as many samples, and
//! the supplement's figure 4 (reconstruction, samples, local depth, `K^T` aligned below).
//! The experiment and the figure's data are library code (`rkwave::lab::refine`), the
//! figures' layout the lab's (`rkwave::lab::refine_figures`): this parses, calls and prints.

use std::path::PathBuf;

use clap::{Args, ValueEnum};
use rkwave::lab::refine::{adaptive_vs_uniform, compare_uniform, comparison_budgets, Truth};
use rkwave::lab::refine_figures::{error_against_samples, figure4_layout};
use rkwave::refine::{ExpressionOracle, Indicator, RefineParams, SampleOracle, SignalOracle};
use rkwave::sampling::{Domain, Layout, Signal};

use super::adapt_text::{adapt_table, comparison_table, refine_error};
use super::{check_writable, figures, CliError, FamilyArg};
use rkwave::refine::{BaseSampling, IntervalTreeParams, MarkingParams, StopParams, TreeParams};

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
            .map_err(|e: rkwave::sampling::ParseLayoutError| CliError::parse("--layout", e))?;
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
            indicator,
            reference_grid: self.round_grid,
            tree: TreeParams {
                p: self.p,
                rho: self.rho,
            },
            interval: IntervalTreeParams {
                family: Some(family),
                coarse: self.coarse,
                base_depth: self.base_depth,
                max_depth: self.max_depth,
            },
            sampling: BaseSampling {
                base_samples: self.base_samples,
                base_layout,
                seed: self.seed,
            },
            stop: StopParams {
                tolerance: self.tolerance,
                budget: self.budget,
                ..RefineParams::default().stop
            },
            marking: MarkingParams { theta: self.theta },
            ..RefineParams::default()
        };
        params.validate().map_err(refine_error)?;
        Ok(params)
    }
}

/// Runs `rkwave adapt`.
pub fn run(args: &AdaptArgs) -> Result<(), CliError> {
    let domain: Domain = args
        .domain
        .parse()
        .map_err(|e| CliError::reworded(&e, format!("invalid --domain: {e}")))?;
    let params = args.params(domain)?;
    let source = Source::parse(&args.signal, domain)?;
    if let Some(plot) = &args.plot {
        check_writable(plot, args.force)?;
    }
    let name = source.name();
    let singular = source.singular_points();
    let truth = Truth {
        oracle: source.oracle(),
        name: &name,
        singular_points: &singular,
    };
    if args.compare_uniform {
        return compare(args, &params, truth);
    }
    let (report, r) = adaptive_vs_uniform(truth, &params, args.grid).map_err(refine_error)?;
    if let Some(plot) = &args.plot {
        figures::save(&figure4_layout(&r, truth).map_err(refine_error)?, plot)?;
    }
    if args.json {
        super::print_json(&report);
    } else {
        print!("{}", adapt_table(&report));
        if let Some(plot) = &args.plot {
            println!("wrote {}", plot.display());
        }
    }
    Ok(())
}

/// `--compare-uniform`: both methods over a range of sample counts.
fn compare(args: &AdaptArgs, params: &RefineParams, truth: Truth<'_>) -> Result<(), CliError> {
    let budgets = comparison_budgets(&args.counts, params);
    if budgets.is_empty() {
        return Err(CliError::Invalid(format!(
            "--compare-uniform: no sample count up to the budget {}: give --counts or a budget \
             of at least 512",
            params.stop.budget
        )));
    }
    let out = compare_uniform(truth, params, &budgets, args.grid).map_err(refine_error)?;
    if let Some(plot) = &args.plot {
        figures::save(&error_against_samples(&out.comparison, &out.signal), plot)?;
    }
    if args.json {
        super::print_json(&out);
    } else {
        print!("{}", comparison_table(&out, args.grid));
        if let Some(plot) = &args.plot {
            println!("wrote {}", plot.display());
        }
    }
    Ok(())
}
