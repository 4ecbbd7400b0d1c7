//! The arguments of `rkwave report`, shared with `rkwave sweep` (its base setting).

use clap::Args;
use rkwave::report::ReportSetting;
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
