//! Command-line knobs of the solve, shared by `reconstruct`, `report` and `sweep`.

use clap::{Args, ValueEnum};
use rkwave::kernel::LevelParams;
use rkwave::reconstruct::{Levels, Method, SingleScaleSolver};
use rkwave::solve::{GlobalLsParams, LocalInversionParams, Solver};

use super::CliError;

/// Which solve.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum MethodArg {
    /// Global least squares through the single-scale basis (banded normal equations + FWT).
    Single,
    /// Local inversion (the paper's method).
    Local,
    /// Global sparse least squares on the multilevel K (sparse Cholesky of K^T K).
    Global,
    /// Dense SVD pseudo-inverse (small problems).
    Dense,
}

/// Local solver on the command line.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum SolverArg {
    /// SVD pseudo-inverse with a relative cut-off.
    Svd,
    /// Column-pivoted QR.
    Qr,
    /// Cholesky of the normal matrix.
    Cholesky,
}

impl From<SolverArg> for Solver {
    fn from(s: SolverArg) -> Self {
        match s {
            SolverArg::Svd => Solver::Svd,
            SolverArg::Qr => Solver::Qr,
            SolverArg::Cholesky => Solver::Cholesky,
        }
    }
}

/// Factorization of the single-scale least squares on the command line.
#[derive(Clone, Copy, Debug, ValueEnum, PartialEq, Eq)]
pub enum FactorizationArg {
    /// Banded QR by Givens rotations: accuracy of cond(K).
    Qr,
    /// Banded normal equations and Cholesky: accuracy of cond(K)^2, less work per sample.
    Normal,
}

impl From<FactorizationArg> for SingleScaleSolver {
    fn from(f: FactorizationArg) -> Self {
        match f {
            FactorizationArg::Qr => SingleScaleSolver::Qr,
            FactorizationArg::Normal => SingleScaleSolver::NormalEquations,
        }
    }
}

/// Solve knobs.
#[derive(Args, Debug, Clone)]
pub struct SolveArgs {
    /// Levels: `auto` (from the samples and --rho) or `n..N`.
    #[arg(long, default_value = "auto")]
    pub levels: String,
    /// Oversampling target m / P for automatic levels [default: 2; with --dim 2, samples per
    /// tensor function, default 4].
    #[arg(long)]
    pub rho: Option<f64>,
    /// Samples a coarse scaling function may cover (automatic levels).
    #[arg(long, default_value_t = 256.0)]
    pub coarse_samples: f64,
    /// Neighbourhood rings of local inversion.
    #[arg(long, default_value_t = 1, value_parser = super::limits::rings)]
    pub rings: usize,
    /// Local solver.
    #[arg(long, value_enum, default_value_t = SolverArg::Svd)]
    pub solver: SolverArg,
    /// Relative singular value cut-off of the local SVD/QR.
    #[arg(long, default_value_t = 1e-12)]
    pub cutoff: f64,
    /// Relative ridge of the single-scale normal equations (it moves the solution by about
    /// ridge x cond(K)^2; undetermined directions are handled without it) [default: 0; with
    /// --dim 2, on the equilibrated image normal equations, default 1e-9].
    #[arg(long)]
    pub ridge: Option<f64>,
    /// Factorization of the single-scale least squares (`--method single`).
    #[arg(long, value_enum, default_value_t = FactorizationArg::Qr)]
    pub factorization: FactorizationArg,
}

/// A relative singular value cut-off must lie in `[0, 1)`.
pub fn check_cutoff(cutoff: f64) -> Result<(), CliError> {
    if cutoff.is_finite() && (0.0..1.0).contains(&cutoff) {
        Ok(())
    } else {
        Err(CliError::Invalid(format!(
            "--cutoff {cutoff} must be a relative cut-off in [0, 1), e.g. 1e-12"
        )))
    }
}

impl SolveArgs {
    /// The level choice.
    pub fn levels(&self) -> Result<Levels, CliError> {
        let rho = self.rho.unwrap_or(2.0);
        if !(rho.is_finite() && rho > 0.0) {
            return Err(CliError::Invalid(format!(
                "--rho {rho} must be a positive oversampling rate such as 2"
            )));
        }
        if !(self.coarse_samples.is_finite() && self.coarse_samples >= 1.0) {
            return Err(CliError::Invalid(format!(
                "--coarse-samples {} must be at least 1",
                self.coarse_samples
            )));
        }
        if self.levels == "auto" {
            return Ok(Levels::Auto(LevelParams {
                rho,
                coarse_samples: self.coarse_samples,
            }));
        }
        let bad = || {
            CliError::Invalid(format!(
                "--levels {:?} is neither `auto` nor `n..N` (e.g. 4..9)",
                self.levels
            ))
        };
        let (a, b) = self.levels.split_once("..").ok_or_else(bad)?;
        let coarse = a.trim().parse::<u32>().map_err(|_| bad())?;
        let fine = b.trim().parse::<u32>().map_err(|_| bad())?;
        Ok(Levels::Fixed { coarse, fine })
    }

    /// The method.
    pub fn method(&self, which: MethodArg) -> Result<Method, CliError> {
        check_cutoff(self.cutoff)?;
        let ridge = self.ridge.unwrap_or(0.0);
        if !(ridge.is_finite() && (0.0..1.0).contains(&ridge)) {
            return Err(CliError::Invalid(format!(
                "--ridge {ridge} must be in [0, 1), e.g. 1e-16"
            )));
        }
        Ok(match which {
            MethodArg::Single => Method::SingleScale {
                ridge,
                solver: self.factorization.into(),
            },
            MethodArg::Local => Method::Local(self.local()),
            MethodArg::Global => Method::Global(GlobalLsParams::default()),
            MethodArg::Dense => Method::Dense {
                cutoff: self.cutoff,
            },
        })
    }

    /// The local inversion parameters.
    pub fn local(&self) -> LocalInversionParams {
        LocalInversionParams {
            rings: self.rings,
            solver: self.solver.into(),
            cutoff: self.cutoff,
            ..LocalInversionParams::default()
        }
    }
}
