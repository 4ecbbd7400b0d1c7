//! The adaptive-against-uniform experiment of `rkwave adapt` (docs/design.md §6, supplement figure 4)
//! as library code: a refinement, its errors against the truth (RMS on a grid and the `L2`
//! norm by quadrature on the leaves), the default uniform fit on as many uniform samples and
//! the same errors, times, and the data of figure 4. The command line only prints these
//! typed reports.

use std::time::Instant;

use serde::Serialize;

use super::measure::{grid_error, quadrature_error, ErrorFigures, Reconstruction};
use super::{
    refine, RefineError, RefineParams, Refinement, RoundLog, SampleOracle, StopParams, StopReason,
};
use crate::reconstruct::{fit, FitParams};
use crate::sampling::Layout;

/// The signal of an experiment: an oracle, its name, and its singular points in unit
/// coordinates (quadrature breaks; empty when unknown).
#[derive(Clone, Copy)]
pub struct Truth<'a> {
    /// The oracle.
    pub oracle: &'a dyn SampleOracle,
    /// Its name, as printed.
    pub name: &'a str,
    /// Singular points in unit coordinates.
    pub singular_points: &'a [f64],
}

/// Errors of one reconstruction against the truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Errors {
    /// On the uniform grid.
    pub grid: ErrorFigures,
    /// By 6-point Gauss–Legendre on the leaves (or cells), the singular points and a
    /// 4096-cell partition, each cell halved.
    pub quadrature: ErrorFigures,
}

/// The uniform fit set against the refinement.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct UniformSummary {
    /// Uniform samples.
    pub samples: usize,
    /// Coarse level `n` of the automatic levels.
    pub coarse: u32,
    /// Finest level `N`.
    pub fine: u32,
    /// Functions `P`.
    pub basis_size: usize,
    /// RMS error on the grid.
    pub error_l2: f64,
    /// Largest error on the grid.
    pub error_max: f64,
    /// `L2` error by quadrature.
    pub error_l2_quadrature: f64,
}

/// Seconds of the experiment.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AdaptTimes {
    /// The whole refinement.
    pub refine: f64,
    /// Mean of the refinement rounds that added samples.
    pub round_mean: f64,
    /// The last such round.
    pub round_last: f64,
    /// Recomputing everything a round reuses, from scratch on the final tree.
    pub full_rebuild: f64,
    /// Of which evaluation and `K`.
    pub full_rebuild_kernel: f64,
    /// Of which the solve.
    pub full_rebuild_solve: f64,
}

/// The report of `rkwave adapt`: one refinement against the uniform fit on as many samples.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptReport {
    /// The signal.
    pub signal: String,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// Vanishing moments.
    pub p: usize,
    /// Coarse level `n`.
    pub coarse: u32,
    /// Depth of the base tree.
    pub base_depth: u32,
    /// The depth limit.
    pub depth_limit: u32,
    /// Samples in the end.
    pub samples: usize,
    /// Of which base samples.
    pub base_samples: usize,
    /// Of which refinement samples.
    pub refinement_samples: usize,
    /// Active functions `P`.
    pub basis_size: usize,
    /// Finest active level reached.
    pub max_depth: i32,
    /// Leaves of the final tree.
    pub leaves: usize,
    /// RMS error on the grid.
    pub error_l2: f64,
    /// Largest error on the grid.
    pub error_max: f64,
    /// Grid points.
    pub error_grid_points: usize,
    /// `L2` error by quadrature.
    pub error_l2_quadrature: f64,
    /// The last estimate of the indicator.
    pub estimated_error: Option<f64>,
    /// Why the refinement stopped.
    pub stop: StopReason,
    /// Every round.
    pub rounds: Vec<RoundLog>,
    /// The uniform fit on as many samples.
    pub uniform: UniformSummary,
    /// Uniform over adaptive, RMS on the grid.
    pub ratio_l2: f64,
    /// Uniform over adaptive, `L2` by quadrature.
    pub ratio_l2_quadrature: f64,
    /// Seconds.
    pub time_s: AdaptTimes,
}

/// One row of the comparison over sample counts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ComparisonRow {
    /// The budget.
    pub budget: usize,
    /// Samples the refinement took (and the uniform fit got).
    pub samples: usize,
    /// Finest level reached.
    pub max_depth: i32,
    /// Why the refinement stopped.
    pub stop: StopReason,
    /// Adaptive RMS on the grid.
    pub adaptive_l2: f64,
    /// Adaptive `L2` by quadrature.
    pub adaptive_l2_quadrature: f64,
    /// Uniform RMS on the grid.
    pub uniform_l2: f64,
    /// Uniform `L2` by quadrature.
    pub uniform_l2_quadrature: f64,
    /// Uniform over adaptive, RMS.
    pub ratio_l2: f64,
    /// Uniform over adaptive, quadrature.
    pub ratio_l2_quadrature: f64,
}

/// Adaptive against uniform over sample counts.
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// The signal.
    pub signal: String,
    /// One row per budget.
    pub comparison: Vec<ComparisonRow>,
}

/// Errors of `rec` against the truth: on `grid` uniform points, and by quadrature with the
/// breaks `cells` (unit coordinates), the singular points and 4096 equal cells.
pub fn errors<R: Reconstruction + ?Sized>(
    rec: &R,
    truth: Truth<'_>,
    params: &RefineParams,
    grid: usize,
    cells: &[f64],
) -> Result<Errors, RefineError> {
    let mut breaks: Vec<f64> = cells.to_vec();
    breaks.extend_from_slice(truth.singular_points);
    breaks.extend((0..4096).map(|i| i as f64 / 4096.0));
    Ok(Errors {
        grid: grid_error(rec, truth.oracle, params.domain, grid)?,
        quadrature: quadrature_error(rec, truth.oracle, params.domain, &breaks, 2)?,
    })
}

/// Errors of a refinement (breaks at its leaves).
pub fn adaptive_errors(
    r: &Refinement,
    truth: Truth<'_>,
    grid: usize,
) -> Result<Errors, RefineError> {
    let cells: Vec<f64> = r.tree.leaves().iter().map(|l| l.unit_bounds().0).collect();
    errors(r, truth, &r.params, grid, &cells)
}

/// The default fit (automatic levels, `p` and family of `params`) on `m` uniform samples of
/// the truth, and its errors (breaks at the cells of `V_{N+1}`, at most `2^20`).
pub fn uniform_fit(
    m: usize,
    params: &RefineParams,
    truth: Truth<'_>,
    grid: usize,
) -> Result<(UniformSummary, Errors), RefineError> {
    let domain = params.domain;
    let xs = Layout::Uniform.generate(m, domain, params.sampling.seed);
    let values: Vec<f64> = xs.iter().map(|&x| truth.oracle.sample(x)).collect();
    if let Some((x, v)) = xs.iter().zip(&values).find(|(_, v)| !v.is_finite()) {
        return Err(RefineError::NonFiniteValue { x: *x, value: *v });
    }
    let fp = FitParams {
        p: params.tree.p,
        family: Some(params.family()),
        ..FitParams::default()
    };
    let fitted = fit(&xs, &[&values], domain, &fp)?;
    let n = 1u64 << (fitted.levels.fine + 1).min(20);
    let cells: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    let e = errors(&fitted, truth, params, grid, &cells)?;
    Ok((
        UniformSummary {
            samples: m,
            coarse: fitted.levels.coarse,
            fine: fitted.levels.fine,
            basis_size: fitted.active.len(),
            error_l2: e.grid.l2,
            error_max: e.grid.max,
            error_l2_quadrature: e.quadrature.l2,
        },
        e,
    ))
}

/// Refines the truth with `params`, measures it and the uniform fit on as many samples on
/// `grid` points, and times a full rebuild. Returns the report and the refinement.
pub fn adaptive_vs_uniform(
    truth: Truth<'_>,
    params: &RefineParams,
    grid: usize,
) -> Result<(AdaptReport, Refinement), RefineError> {
    let t0 = Instant::now();
    let r = refine(truth.oracle, params)?;
    let refine_s = t0.elapsed().as_secs_f64();
    let (_, rebuild) = r.rebuild()?;
    let adaptive = adaptive_errors(&r, truth, grid)?;
    let m = r.samples.len();
    let (uniform, uerr) = uniform_fit(m, params, truth, grid)?;
    let refined: Vec<f64> = r
        .rounds
        .iter()
        .skip(1)
        .filter(|l| l.new_samples > 0)
        .map(|l| l.times.total_s)
        .collect();
    let domain = params.domain;
    let report = AdaptReport {
        signal: truth.name.to_string(),
        domain: [domain.a(), domain.b()],
        p: params.tree.p,
        coarse: params.coarse(),
        base_depth: r.base_depth,
        depth_limit: params.interval.max_depth,
        samples: m,
        base_samples: r.base_samples(),
        refinement_samples: m - r.base_samples(),
        basis_size: r.columns().len(),
        max_depth: r.tree.depth(),
        leaves: r.tree.leaves().len(),
        error_l2: adaptive.grid.l2,
        error_max: adaptive.grid.max,
        error_grid_points: adaptive.grid.points,
        error_l2_quadrature: adaptive.quadrature.l2,
        // The last round that computed an estimate (the final fit after a stop has none).
        estimated_error: r.rounds.iter().rev().find_map(|l| l.estimated_error),
        stop: r.stop,
        rounds: r.rounds.clone(),
        uniform,
        ratio_l2: uerr.grid.l2 / adaptive.grid.l2,
        ratio_l2_quadrature: uerr.quadrature.l2 / adaptive.quadrature.l2,
        time_s: AdaptTimes {
            refine: refine_s,
            round_mean: refined.iter().sum::<f64>() / refined.len().max(1) as f64,
            round_last: refined.last().copied().unwrap_or(0.0),
            full_rebuild: rebuild.total_s,
            full_rebuild_kernel: rebuild.sample_s + rebuild.kernel_s,
            full_rebuild_solve: rebuild.solve_s,
        },
    };
    Ok((report, r))
}

/// The budgets of a comparison: `counts`, or `512, 1024, ...` up to `params.budget`.
pub fn comparison_budgets(counts: &[usize], params: &RefineParams) -> Vec<usize> {
    if counts.is_empty() {
        (9..=24)
            .map(|k| 1usize << k)
            .filter(|&c| c <= params.stop.budget)
            .collect()
    } else {
        counts.to_vec()
    }
}

/// Adaptive against uniform for every budget of `budgets` (reference grid off).
pub fn compare_uniform(
    truth: Truth<'_>,
    params: &RefineParams,
    budgets: &[usize],
    grid: usize,
) -> Result<Comparison, RefineError> {
    let mut rows = Vec::with_capacity(budgets.len());
    for &budget in budgets {
        let p = RefineParams {
            reference_grid: 0,
            stop: StopParams {
                budget,
                ..params.stop
            },
            ..*params
        };
        p.validate()?;
        let r = refine(truth.oracle, &p)?;
        let a = adaptive_errors(&r, truth, grid)?;
        let m = r.samples.len();
        let (_, u) = uniform_fit(m, params, truth, grid)?;
        rows.push(ComparisonRow {
            budget,
            samples: m,
            max_depth: r.tree.depth(),
            stop: r.stop,
            adaptive_l2: a.grid.l2,
            adaptive_l2_quadrature: a.quadrature.l2,
            uniform_l2: u.grid.l2,
            uniform_l2_quadrature: u.quadrature.l2,
            ratio_l2: u.grid.l2 / a.grid.l2,
            ratio_l2_quadrature: u.quadrature.l2 / a.quadrature.l2,
        });
    }
    Ok(Comparison {
        signal: truth.name.to_string(),
        comparison: rows,
    })
}

/// The data of the supplement's figure 4 for a refinement: the reconstruction over the
/// truth on 4001 uniform points and the leaf ends of the refined zones, the samples by
/// origin, the local depth as a step function, and the pattern of `K^T`.
#[derive(Clone, Debug, Serialize)]
pub struct Figure4 {
    /// `(x, f(x))`.
    pub truth: Vec<(f64, f64)>,
    /// `(x, f~(x))` at the same positions.
    pub reconstruction: Vec<(f64, f64)>,
    /// Positions of the base samples.
    pub base_samples: Vec<f64>,
    /// Positions of the refinement samples.
    pub refinement_samples: Vec<f64>,
    /// `(x, d)` corners of the local depth `d(x)` (two per leaf, left to right).
    pub depth: Vec<(f64, f64)>,
    /// `(column, row)` of every entry of `K`.
    pub kernel_entries: Vec<(usize, usize)>,
    /// `K` is `samples x functions`.
    pub functions: usize,
}

/// [`Figure4`] of `r` against the truth.
pub fn figure4(r: &Refinement, truth: Truth<'_>) -> Result<Figure4, RefineError> {
    let domain = r.tree.domain();
    let points = 4000;
    let mut xs: Vec<f64> = domain.uniform_grid(points + 1);
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
    let recon = r.evaluate(&xs)?;
    let depth = r
        .tree
        .leaves()
        .iter()
        .flat_map(|leaf| {
            let (a, b) = leaf.unit_bounds();
            let d = leaf.depth() as f64;
            [(domain.from_unit(a), d), (domain.from_unit(b), d)]
        })
        .collect();
    let mut kernel_entries = Vec::with_capacity(r.kernel.nnz());
    for (i, row) in r.kernel.outer_iterator().enumerate() {
        for (c, _) in row.iter() {
            kernel_entries.push((c, i));
        }
    }
    Ok(Figure4 {
        truth: xs.iter().map(|&x| (x, truth.oracle.sample(x))).collect(),
        reconstruction: xs.iter().copied().zip(recon).collect(),
        base_samples: r
            .samples
            .iter()
            .filter(|s| s.round == 0)
            .map(|s| s.x)
            .collect(),
        refinement_samples: r
            .samples
            .iter()
            .filter(|s| s.round > 0)
            .map(|s| s.x)
            .collect(),
        depth,
        kernel_entries,
        functions: r.columns().len(),
    })
}
