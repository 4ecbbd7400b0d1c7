//! End-to-end time, peak memory and accuracy of one fit against the number of samples: `m`
//! uniform random samples of `channels` test signals (smooth, HeaviSine, Doppler in turn) on
//! `[0, 1]`, automatic levels (`rho = 2`), the fit and its evaluation on a uniform grid, and
//! the RMS error against the true signals there,
//! `max_c sqrt( sum_g (f~_c(x_g) - f_c(x_g))^2 / G )`.
//!
//! [`scaling_run`] measures one configuration in the calling process; running each
//! configuration in its own process (so that the peak memory belongs to it alone) is the
//! caller's business.

use std::fmt;
use std::str::FromStr;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::rms;
use crate::reconstruct::{fit, FitParams, Method, ReconstructError};
use crate::sampling::{Domain, Layout, Signal};
use crate::solve::{GlobalLsParams, LocalInversionParams, Solver};

/// The methods the scaling harness compares.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum ScalingMethod {
    /// Global least squares through the single-scale basis (banded normal equations + FWT).
    Single,
    /// Global sparse least squares on the multilevel `K`.
    Global,
    /// Local inversion, rings 0, SVD.
    Local0,
    /// Local inversion, rings 1, SVD.
    Local1,
}

impl ScalingMethod {
    /// The method's name (`single`, `global`, `local0`, `local1`).
    pub fn name(self) -> &'static str {
        match self {
            ScalingMethod::Single => "single",
            ScalingMethod::Global => "global",
            ScalingMethod::Local0 => "local0",
            ScalingMethod::Local1 => "local1",
        }
    }

    /// The solve it stands for. Local inversion uses SVD: the Cholesky solver squares the
    /// blocks' condition numbers (up to 3e7 for random samples), which ruins accuracy.
    pub fn method(self) -> Method {
        match self {
            ScalingMethod::Single => Method::SingleScale {
                ridge: 0.0,
                solver: crate::reconstruct::SingleScaleSolver::default(),
            },
            ScalingMethod::Global => Method::Global(GlobalLsParams::default()),
            ScalingMethod::Local0 | ScalingMethod::Local1 => Method::Local(LocalInversionParams {
                rings: usize::from(self == ScalingMethod::Local1),
                solver: Solver::Svd,
                ..LocalInversionParams::default()
            }),
        }
    }
}

impl fmt::Display for ScalingMethod {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown scaling method name.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown method {name:?}: use single, global, local0 or local1")]
pub struct ParseScalingMethodError {
    /// The name given.
    pub name: String,
}

impl FromStr for ScalingMethod {
    type Err = ParseScalingMethodError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "single" => Ok(ScalingMethod::Single),
            "global" => Ok(ScalingMethod::Global),
            "local0" => Ok(ScalingMethod::Local0),
            "local1" => Ok(ScalingMethod::Local1),
            _ => Err(ParseScalingMethodError {
                name: s.to_string(),
            }),
        }
    }
}

/// Why a scaling configuration could not be measured.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ScalingError {
    /// The evaluation grid has fewer than two points.
    #[error("an evaluation grid of {grid} points cannot span the domain: give at least 2")]
    GridTooSmall {
        /// The grid size given.
        grid: usize,
    },
    /// The fit or its evaluation failed.
    #[error(transparent)]
    Reconstruct(#[from] ReconstructError),
}

/// One configuration of the scaling harness.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScalingSetting {
    /// Samples `m`.
    pub samples: usize,
    /// Channels (signals smooth, HeaviSine, Doppler, smooth, ... in turn).
    pub channels: usize,
    /// The solve.
    pub method: ScalingMethod,
    /// Points of the evaluation grid (at least 2).
    pub grid: usize,
}

/// Seed of the random sample positions.
pub const SCALING_SEED: u64 = 7;

/// The test signals of the channels, in turn.
pub const SCALING_SIGNALS: [Signal; 3] = [Signal::Smooth, Signal::HeaviSine, Signal::Doppler];

/// One measured configuration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScalingRow {
    /// Samples.
    pub samples: usize,
    /// Channels.
    pub channels: usize,
    /// Method.
    pub method: ScalingMethod,
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
    /// Peak resident memory of the process (MB; NaN where `/proc/self/status` is missing).
    pub peak_mb: f64,
    /// RMS error against the true signals on the grid (max over channels).
    pub rms_error: f64,
    /// The fallback taken, if any.
    pub fallback: Option<String>,
}

/// The samples of a scaling configuration: positions and one value vector per channel.
pub fn scaling_samples(setting: &ScalingSetting) -> (Vec<f64>, Vec<Vec<f64>>) {
    let domain = Domain::UNIT;
    let xs = Layout::Random.generate(setting.samples, domain, SCALING_SEED);
    let values = (0..setting.channels)
        .map(|c| SCALING_SIGNALS[c % SCALING_SIGNALS.len()].sample(domain, &xs))
        .collect();
    (xs, values)
}

/// Peak resident memory of this process in MB (`VmHWM` of `/proc/self/status`; NaN where
/// that file is missing, e.g. off Linux).
pub fn peak_resident_mb() -> f64 {
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

/// Measures one configuration in this process: fit, evaluation on the grid, errors, peak
/// memory.
pub fn scaling_run(setting: &ScalingSetting) -> Result<ScalingRow, ScalingError> {
    if setting.grid < 2 {
        return Err(ScalingError::GridTooSmall { grid: setting.grid });
    }
    let domain = Domain::UNIT;
    let (xs, values) = scaling_samples(setting);
    let refs: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
    let params = FitParams {
        method: setting.method.method(),
        ..FitParams::default()
    };
    let grid = domain.uniform_grid(setting.grid);
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
            rms(
                r,
                &SCALING_SIGNALS[c % SCALING_SIGNALS.len()].sample(domain, &grid),
            )
        })
        .fold(0.0, f64::max);
    Ok(ScalingRow {
        samples: setting.samples,
        channels: setting.channels,
        method: setting.method,
        functions: fitted.active.len(),
        levels: (fitted.levels.coarse, fitted.levels.fine),
        time_s,
        solve_s: fitted.timings.solve_s,
        evaluate_s,
        ns_per_sample: time_s / setting.samples as f64 * 1e9,
        peak_mb: peak_resident_mb(),
        rms_error,
        fallback: (!fitted.fallbacks.is_empty()).then(|| {
            let notes: Vec<String> = fitted.fallbacks.iter().map(ToString::to_string).collect();
            notes.join("; ")
        }),
    })
}

impl ScalingError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ScalingError::GridTooSmall { .. } => crate::error::ErrorKind::InvalidInput,
            ScalingError::Reconstruct(e) => e.kind(),
        }
    }
}

crate::error::classified!(ScalingError);
