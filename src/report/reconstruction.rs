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

/// The point `x_g = a + (b - a) g / (G - 1)` of the uniform grid of `points` points over
/// `domain` (both ends included; a single point sits at `a`).
pub fn grid_point(domain: Domain, points: usize, g: usize) -> f64 {
    let last = points.saturating_sub(1).max(1) as f64;
    domain.from_unit(g as f64 / last)
}

/// The uniform grid of `points >= 2` points over `domain`, both ends included
/// (see [`grid_point`]).
pub fn uniform_grid(domain: Domain, points: usize) -> Vec<f64> {
    (0..points).map(|g| grid_point(domain, points, g)).collect()
}

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
            .map(|g| grid_point(domain, points, g))
            .collect();
        let values = evaluator.evaluate(&xs)?;
        evaluate_s += t.elapsed().as_secs_f64();
        let t = std::time::Instant::now();
        sink(&xs, &values)?;
        sink_s += t.elapsed().as_secs_f64();
    }
    // The QR found the residual on the way; otherwise evaluate the fit at the samples.
    let residual_rms = match &fit.solve {
        SolveReport::SingleScale(SingleScaleReport {
            residual_rms: Some(r),
            ..
        }) => r.clone(),
        _ => evaluator
            .evaluate(&samples.positions)?
            .iter()
            .zip(&samples.values)
            .map(|(r, f)| rms(r, f))
            .collect(),
    };
    Ok(GridReconstruction {
        fit,
        points,
        residual_rms,
        evaluate_s,
        sink_s,
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
