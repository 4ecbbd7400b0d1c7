//! `rkwave report`: the local-vs-global report of docs/design.md §5.

use clap::Args;
use rkwave::report::{local_vs_global, LocalGlobalReport, ReportSetting};
use rkwave::sampling::{Domain, Layout, Signal};

use super::solve_args::SolverArg;
use super::{build_basis, CliError, FilterSpec, LevelSpec};

/// `rkwave report`.
#[derive(Args, Debug, Clone)]
pub struct ReportArgs {
    /// Filter bank.
    #[command(flatten)]
    pub filter: FilterSpec,
    /// Levels.
    #[command(flatten)]
    pub levels: LevelSpec,
    /// Number of samples.
    #[arg(long, default_value_t = 1024, value_parser = super::limits::samples)]
    pub samples: usize,
    /// Sample layout: uniform, endpoints, jittered, random, lowdiscrepancy, clustered.
    #[arg(long, default_value = "uniform")]
    pub layout: Layout,
    /// Seed of random layouts.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Test signal: smooth, polynomialD, jumps, kink, cusp, blocks, bumps, heavisine, doppler.
    #[arg(long, default_value = "smooth")]
    pub signal: Signal,
    /// Neighbourhood rings.
    #[arg(long, default_value_t = 1, value_parser = super::limits::rings)]
    pub rings: usize,
    /// Local solver.
    #[arg(long, value_enum, default_value_t = SolverArg::Svd)]
    pub solver: SolverArg,
    /// Relative singular value cut-off.
    #[arg(long, default_value_t = 1e-12)]
    pub cutoff: f64,
    /// Grid points on which reconstructions are compared.
    #[arg(long, default_value_t = 8192, value_parser = super::limits::grid)]
    pub grid: usize,
    /// Print JSON.
    #[arg(long)]
    pub json: bool,
}

impl ReportArgs {
    /// The validated setting.
    pub fn setting(&self) -> Result<ReportSetting, CliError> {
        // Validates p and the levels (the report's domain is [0, 1]).
        build_basis(&self.filter, &self.levels, Domain::UNIT)?;
        if self.samples == 0 {
            return Err(CliError::Invalid(
                "--samples 0: give at least one sample".into(),
            ));
        }
        if self.grid < 2 {
            return Err(CliError::Invalid("--grid must be at least 2".into()));
        }
        super::solve_args::check_cutoff(self.cutoff)?;
        Ok(ReportSetting {
            p: self.filter.p,
            family: self.filter.family(),
            coarse: self.levels.coarse(self.filter.p),
            fine: self.levels.fine,
            samples: self.samples,
            layout: self.layout,
            seed: self.seed,
            signal: self.signal,
            local: rkwave::solve::LocalInversionParams {
                rings: self.rings,
                solver: self.solver.into(),
                cutoff: self.cutoff,
                ..Default::default()
            },
            grid: self.grid,
        })
    }
}

/// Runs `rkwave report`.
pub fn run(args: &ReportArgs) -> Result<(), CliError> {
    let setting = args.setting()?;
    let report = local_vs_global(&setting)?;
    if args.json {
        super::print_json(&report);
    } else {
        print!("{}", table(&report));
    }
    Ok(())
}

/// The report for people.
pub fn table(r: &LocalGlobalReport) -> String {
    let s = &r.setting;
    let err = r.error.as_ref().map_or_else(
        || "n/a (too large for the dense reference)".to_string(),
        |e| {
            format!(
                "max |K~ - K+| {:.2e}, RMS {:.2e}, relative Frobenius {:.2e}",
                e.max_abs, e.rms, e.rel_frobenius
            )
        },
    );
    format!(
        "local vs global: p = {} ({}), levels {}..{}, {} {} samples, P = {} (oversampling {:.2})\n\
         \x20 solver {:?}, rings {}, cut-off {:e}: {} groups, {} cut ({} directions)\n\
         \x20 submatrix rows   min {:.0} median {:.0} max {:.0}\n\
         \x20 submatrix cols   min {:.0} median {:.0} max {:.0}\n\
         \x20 element-wise     {}\n\
         \x20 reconstruction   local vs global {:.2e}, local vs truth {:.2e}, global vs truth {:.2e} (RMS, signal {})\n\
         \x20 local condition  median {:.3e}, max {:.3e}; global {}\n\
         \x20 time             kernel {:.4} s, local {:.4} s, global ({}) {:.4} s\n",
        s.p,
        s.family.short_name(),
        s.coarse,
        s.fine,
        s.samples,
        s.layout,
        r.functions,
        r.oversampling,
        s.local.solver,
        s.local.rings,
        s.local.cutoff,
        r.groups,
        r.cut.0,
        r.cut.1,
        r.submatrix.rows.min,
        r.submatrix.rows.median,
        r.submatrix.rows.max,
        r.submatrix.cols.min,
        r.submatrix.cols.median,
        r.submatrix.cols.max,
        err,
        r.reconstruction.local_vs_global,
        r.reconstruction.local_vs_truth,
        r.reconstruction.global_vs_truth,
        s.signal,
        r.condition.median,
        r.condition.max,
        r.global_condition
            .map_or("n/a".to_string(), |c| format!("{c:.3e}")),
        r.time_s.kernel,
        r.time_s.local,
        r.reference,
        r.time_s.global
    )
}
