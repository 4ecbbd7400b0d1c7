//! The report of a reconstruction of a user's samples onto a uniform grid: the fit, the
//! residual at the samples `sqrt( sum_i (f~(x_i) - f_i)^2 / m )` per channel, the levels,
//! stage times and every fallback taken.

use std::path::PathBuf;

use serde::Serialize;

use super::rms;
use crate::io::SampleSet;
use crate::reconstruct::{
    Fallback, Fit, FitEvaluator, Method, ReconstructError, SingleScaleReport, SolveReport,
};
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

/// A fit evaluated on a uniform grid (the values went to a sink, block by block), with its
/// residuals at the samples.
#[derive(Clone, Debug)]
pub struct GridReconstruction {
    /// The fit.
    pub fit: Fit,
    /// Grid points `G`.
    pub points: usize,
    /// RMS residual at the samples, per channel.
    pub residual_rms: Vec<f64>,
    /// Seconds evaluating on the grid.
    pub evaluate_s: f64,
    /// Seconds in the sink (writing the grid).
    pub sink_s: f64,
}

/// Grid points evaluated and handed to the sink per block: large enough to amortise the
/// evaluator's parallel dispatch, small enough (a few MB) never to hold the grid.
pub const GRID_BLOCK: usize = 1 << 16;

/// Evaluates `fit` (made from `samples`: their residual may come from the fit's own solve)
/// on `points` uniform grid points over `domain`, handing the
/// positions and values (one vector per channel) to `sink` block by block of
/// [`GRID_BLOCK`] points in grid order, so the grid is never held whole; then the residual at
/// the samples (from the solve's report when the QR found it, else by evaluating there). The first error of the evaluation or of the sink stops it.
pub fn onto_grid<E, S>(
    fit: Fit,
    samples: &SampleSet,
    domain: Domain,
    points: usize,
    mut sink: S,
) -> Result<GridReconstruction, E>
where
    E: From<ReconstructError>,
    S: FnMut(&[f64], &[Vec<f64>]) -> Result<(), E>,
{
    let evaluator = fit.evaluator()?;
    let (mut evaluate_s, mut sink_s) = (0.0, 0.0);
    for start in (0..points).step_by(GRID_BLOCK) {
        let t = std::time::Instant::now();
        let xs: Vec<f64> = (start..(start + GRID_BLOCK).min(points))
            .map(|g| domain.grid_point(points, g))
            .collect();
        let values = evaluator.evaluate(&xs)?;
        evaluate_s += t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        sink(&xs, &values)?;
        sink_s += t.elapsed().as_secs_f64();
    }
    let residual_rms = sample_residual(&fit, &evaluator, &samples.positions, &samples.values)?;
    Ok(GridReconstruction {
        fit,
        points,
        residual_rms,
        evaluate_s,
        sink_s,
    })
}

/// The RMS residual `sqrt( sum_i (f~(x_i) - f_i)^2 / m )` of `fit` at the samples
/// (`values`: one slice per channel), per channel: from the solve's report when the QR found
/// it on the way, else by evaluating the fit (through `evaluator`, made from `fit`) at
/// `positions`.
pub fn sample_residual<V: AsRef<[f64]>>(
    fit: &Fit,
    evaluator: &FitEvaluator<'_>,
    positions: &[f64],
    values: &[V],
) -> Result<Vec<f64>, ReconstructError> {
    Ok(match &fit.solve {
        SolveReport::SingleScale(SingleScaleReport {
            residual_rms: Some(r),
            ..
        }) => r.clone(),
        _ => evaluator
            .evaluate(positions)?
            .iter()
            .zip(values)
            .map(|(r, f)| rms(r, f.as_ref()))
            .collect(),
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

impl ReconstructTimes {
    /// The times of a command that read for `read` seconds and wrote for `write`, begun at
    /// `started` (the fit's own stages are in its report).
    pub fn of_command(read: f64, write: f64, started: std::time::Instant) -> Self {
        Self {
            read,
            write,
            total: started.elapsed().as_secs_f64(),
            ..Self::default()
        }
    }
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

impl FallbackNote {
    /// Each of `fallbacks` with its message, in order.
    pub fn all(fallbacks: &[Fallback]) -> Vec<Self> {
        fallbacks
            .iter()
            .map(|f| FallbackNote {
                fallback: f.clone(),
                message: f.to_string(),
            })
            .collect()
    }
}

impl ReconstructReport {
    /// The report of `rec`, reconstructed from `samples` (read from `input`, written to
    /// `output`) with `method`; `time_s.kernel`, `solve` and `evaluate` are taken from the fit,
    /// `write` is the sink's time plus the caller's (closing the file), the others are the
    /// caller's.
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
            grid: rec.points,
            residual_rms: rec.residual_rms.clone().into(),
            time_s: ReconstructTimes {
                kernel: fit.timings.kernel_s,
                solve: fit.timings.solve_s,
                evaluate: rec.evaluate_s,
                write: rec.sink_s + time_s.write,
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
            fallbacks: FallbackNote::all(&fit.fallbacks),
            warnings: fit.warnings(),
        }
    }
}
