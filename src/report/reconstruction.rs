//! The report of a reconstruction of a user's samples onto a uniform grid: the fit, the
//! residual at the samples `sqrt( sum_i (f~(x_i) - f_i)^2 / m )` per channel, the levels,
//! stage times and every fallback taken.

use std::path::PathBuf;

use serde::Serialize;

use super::rms;
use crate::io::SampleSet;
use crate::reconstruct::{Fallback, Fit, Method, ReconstructError, SingleScaleReport, SolveReport};
use crate::sampling::Domain;
use crate::solve::Summary;

/// The lower-case name of a solve method: `single`, `local`, `global` or `dense`.
pub fn method_name(method: &Method) -> &'static str {
    match method {
        Method::SingleScale { .. } => "single",
        Method::Local(_) => "local",
        Method::Global(_) => "global",
        Method::Dense { .. } => "dense",
    }
}

/// A fit evaluated on a uniform grid, with its residuals at the samples.
#[derive(Clone, Debug)]
pub struct GridReconstruction {
    /// The fit.
    pub fit: Fit,
    /// The grid `x_g = a + (b - a) g / (G - 1)` and the reconstruction of every channel
    /// there, with the input's channel names.
    pub grid: SampleSet,
    /// RMS residual at the samples, per channel.
    pub residual_rms: Vec<f64>,
    /// Seconds evaluating on the grid.
    pub evaluate_s: f64,
}

/// The uniform grid of `points >= 2` points over `domain`, both ends included.
pub fn uniform_grid(domain: Domain, points: usize) -> Vec<f64> {
    domain.uniform_grid(points)
}

/// Evaluates `fit` of `samples` on `points` uniform grid points over `domain` and measures
/// the residual at the samples.
pub fn onto_grid(
    fit: Fit,
    samples: &SampleSet,
    domain: Domain,
    points: usize,
) -> Result<GridReconstruction, ReconstructError> {
    let t = std::time::Instant::now();
    let grid = uniform_grid(domain, points);
    let values = fit.evaluate(&grid)?;
    let evaluate_s = t.elapsed().as_secs_f64();
    let at_samples = fit.evaluate(&samples.positions)?;
    let residual_rms = at_samples
        .iter()
        .zip(&samples.values)
        .map(|(r, f)| rms(r, f))
        .collect();
    let grid = SampleSet {
        positions: grid,
        values,
        names: samples.names_or_default(),
    };
    Ok(GridReconstruction {
        fit,
        grid,
        residual_rms,
        evaluate_s,
    })
}

/// One value for a single channel, a list for several (as printed).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum PerChannel {
    /// A single channel.
    One(f64),
    /// One value per channel.
    Many(Vec<f64>),
}

impl From<Vec<f64>> for PerChannel {
    fn from(v: Vec<f64>) -> Self {
        if v.len() == 1 {
            PerChannel::One(v[0])
        } else {
            PerChannel::Many(v)
        }
    }
}

/// Seconds per stage of a reconstruction.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ReconstructTimes {
    /// Reading the samples.
    pub read: f64,
    /// Building `K` (or the normal equations).
    pub kernel: f64,
    /// The solve.
    pub solve: f64,
    /// Evaluating on the grid.
    pub evaluate: f64,
    /// Writing the grid.
    pub write: f64,
    /// Everything.
    pub total: f64,
}

/// Local inversion statistics of a fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LocalSummary {
    /// Factorizations.
    pub groups: usize,
    /// Groups whose cut-off dropped directions.
    pub cut_groups: usize,
    /// Local condition numbers.
    pub condition: Summary,
}

/// The report of `rkwave reconstruct`.
#[derive(Clone, Debug, Serialize)]
pub struct ReconstructReport {
    /// Input file.
    pub input: PathBuf,
    /// Output file.
    pub output: PathBuf,
    /// Samples `m`.
    pub samples: usize,
    /// Channels.
    pub channels: usize,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// Vanishing moments.
    pub p: usize,
    /// The method requested (`single`, `local`, `global`, `dense`).
    pub method: &'static str,
    /// Basis functions `P`.
    pub functions: usize,
    /// Coarse level `n`.
    pub coarse: u32,
    /// Finest level `N`.
    pub fine: u32,
    /// `m / P`.
    pub oversampling: f64,
    /// Grid points.
    pub grid: usize,
    /// RMS residual at the samples (one number per channel).
    pub residual_rms: PerChannel,
    /// Seconds per stage.
    pub time_s: ReconstructTimes,
    /// Local inversion statistics (local method or fallback).
    pub local: Option<LocalSummary>,
    /// The single-scale solve's report (single method).
    pub single_scale: Option<SingleScaleReport>,
    /// Every departure from the requested levels or method, in the order taken.
    pub fallbacks: Vec<FallbackNote>,
    /// Every fallback and warning of the fit, one sentence each (see
    /// [`Fit::warnings`]).
    pub warnings: Vec<String>,
}

/// A fallback with its message, as printed.
#[derive(Clone, Debug, Serialize)]
pub struct FallbackNote {
    /// The fallback.
    pub fallback: Fallback,
    /// What it means, for people.
    pub message: String,
}

impl ReconstructReport {
    /// The report of `rec`, reconstructed from `samples` (read from `input`, written to
    /// `output`) with `method`; `time_s.kernel`, `solve` and `evaluate` are taken from the fit,
    /// the others are the caller's.
    pub fn new(
        input: PathBuf,
        output: PathBuf,
        samples: &SampleSet,
        method: &Method,
        rec: &GridReconstruction,
        time_s: ReconstructTimes,
    ) -> Self {
        let fit = &rec.fit;
        let basis = fit.active.basis();
        Self {
            input,
            output,
            samples: samples.len(),
            channels: samples.channels(),
            domain: [basis.domain().a(), basis.domain().b()],
            p: basis.p(),
            method: method_name(method),
            functions: fit.active.len(),
            coarse: fit.levels.coarse,
            fine: fit.levels.fine,
            oversampling: fit.levels.oversampling,
            grid: rec.grid.len(),
            residual_rms: rec.residual_rms.clone().into(),
            time_s: ReconstructTimes {
                kernel: fit.timings.kernel_s,
                solve: fit.timings.solve_s,
                evaluate: rec.evaluate_s,
                ..time_s
            },
            local: match &fit.solve {
                SolveReport::Local(s) => Some(LocalSummary {
                    groups: s.n_groups,
                    cut_groups: s.cut_groups,
                    condition: s.condition_summary(),
                }),
                _ => None,
            },
            single_scale: match &fit.solve {
                SolveReport::SingleScale(rep) => Some(rep.clone()),
                _ => None,
            },
            fallbacks: fit
                .fallbacks
                .iter()
                .map(|f| FallbackNote {
                    fallback: f.clone(),
                    message: f.to_string(),
                })
                .collect(),
            warnings: fit.warnings(),
        }
    }
}
