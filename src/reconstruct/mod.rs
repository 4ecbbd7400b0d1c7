//! From samples to a reconstruction: levels, kernel matrix, solve, coefficients, evaluation.
//!
//! `c = K^+ f` (docs/design.md §3): the coefficients of `f(x) = sum_a c_a Psi_a(x)` over the active set,
//! by local inversion (the default), a global sparse least-squares solve, or a dense
//! pseudo-inverse. Evaluation of a uniform `Psi(n, N)` goes through the interval FWT to the
//! single-scale `V_{N+1}` coefficients and then evaluates only `2p - 1` (plus edge) scaling
//! functions per position.

pub(crate) mod density;
mod error;
mod evaluate;
mod fit_result;
mod kernel_functions;
mod outcome;
mod params;
mod single_scale;
pub mod stream;
mod undersampled;

use error::undersampled;
pub use error::ReconstructError;
pub use evaluate::FitEvaluator;
pub use fit_result::{Fit, Timings};
pub use kernel_functions::{dual_kernel, reproducing_kernel};
pub use outcome::{Fallback, SolveReport};
pub use params::{FitParams, Levels, Method};
pub use single_scale::{
    single_scale_ls, single_scale_qr, NormalEquations, SingleScaleProblem, SingleScaleReport,
    SingleScaleSolver, PIVOT_TOLERANCE,
};
pub use undersampled::UndersampledFix;

use std::time::Instant;

use crate::basis::CdvBasis;
use crate::kernel::{check_positions, kernel_matrix, ActiveSet, LevelChoice};
use crate::sampling::Domain;
use crate::solve::{apply_local, dense_pinv, global_ls, GlobalLsParams, LocalInversionParams};

fn check_values(m: usize, values: &[&[f64]]) -> Result<(), ReconstructError> {
    for (c, ch) in values.iter().enumerate() {
        if ch.len() != m {
            return Err(ReconstructError::LengthMismatch {
                channel: c,
                expected: m,
                found: ch.len(),
            });
        }
        if let Some((i, &v)) = ch.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(ReconstructError::NonFiniteValue {
                row: i + 1,
                channel: c,
                value: v,
            });
        }
    }
    Ok(())
}

/// Chooses the levels for `m` samples.
pub fn choose_levels(m: usize, params: &FitParams) -> LevelChoice {
    match params.levels {
        Levels::Auto(lp) => LevelChoice::auto(m, params.p, lp),
        Levels::Fixed { coarse, fine } => LevelChoice {
            coarse,
            fine,
            oversampling: m as f64 / 2f64.powi(fine as i32 + 1),
        },
    }
}

/// Fits `values` (one slice per channel) at `positions` on `domain`.
///
/// Errors: a value that is not finite ([`ReconstructError::NonFiniteValue`]), channels of the
/// wrong length, positions outside `domain`, invalid basis parameters, fewer samples than
/// functions at fixed levels, or a failed solve. With automatic levels and the single-scale
/// solve, levels the samples do not determine are lowered (recorded in [`Fit::fallbacks`]).
///
/// ```
/// use rkwave::reconstruct::{fit, FitParams, ReconstructError};
/// use rkwave::sampling::Domain;
///
/// let xs = [0.1, 0.5, 0.9];
/// let bad = [1.0, f64::NAN, 2.0];
/// let err = fit(&xs, &[&bad], Domain::UNIT, &FitParams::default()).unwrap_err();
/// assert!(matches!(err, ReconstructError::NonFiniteValue { row: 2, .. }));
/// ```
pub fn fit(
    positions: &[f64],
    values: &[&[f64]],
    domain: Domain,
    params: &FitParams,
) -> Result<Fit, ReconstructError> {
    let m = positions.len();
    check_values(m, values)?;
    let mut levels = choose_levels(m, params);
    guard_uniform(m, values.len(), params, &levels)?;
    if let (Levels::Auto(lp), Method::SingleScale { .. } | Method::Global(_)) =
        (params.levels, params.method)
    {
        // Strongly non-uniform samples: a tree whose local depth follows the sample count.
        if density::strongly_non_uniform(positions, domain, &levels, params.p) {
            return density::fit_density_tree(positions, values, domain, params, lp);
        }
    }
    let mut dropped = 0u32;
    if let (Levels::Auto(_), Method::SingleScale { ridge, solver }) = (params.levels, params.method)
    {
        // Automatic levels: while the samples leave single-scale directions undetermined,
        // drop the finest level (doubling the oversampling) rather than solve an ill-posed
        // problem; the normal equations are coarsened, not accumulated again. At most three
        // times, then the general path (local inversion) decides.
        let domain_ok = check_positions(domain, positions).is_ok();
        // Predict from sample counts what the pivots would show: a single-scale support with
        // fewer than two samples leaves its function undetermined. Drop those levels before
        // accumulating anything (the pivot check below stays the arbiter).
        while domain_ok
            && dropped < 3
            && levels.fine > levels.coarse
            && min_support_samples(positions, domain, levels.fine + 1, params.p) < 2
        {
            levels.lower_finest();
            dropped += 1;
        }
        let first = params.basis(levels.coarse, levels.fine, domain)?;
        if domain_ok && m >= first.dimension() {
            let t0 = Instant::now();
            let mut ne = SingleScaleProblem::new(&first, positions, values, solver)?;
            while dropped <= 3 && levels.fine >= levels.coarse {
                let basis = params.basis(levels.coarse, levels.fine, domain)?;
                let (c, rep) = ne.solve(&basis, ridge)?;
                if rep.deficient == 0 {
                    return Ok(single_scale_fit(basis, c, levels, t0, rep, dropped));
                }
                if levels.fine == levels.coarse {
                    break;
                }
                ne = ne.coarsen(basis.bank());
                levels.lower_finest();
                dropped += 1;
            }
        }
    }
    let basis = params.basis(levels.coarse, levels.fine, domain)?;
    let active = ActiveSet::uniform(basis);
    if m < active.len() {
        return Err(undersampled(
            m,
            active.len(),
            params.p,
            levels.fine,
            Some(&params.levels),
        ));
    }
    let mut fitted = fit_active(active, positions, values, params.method, levels)?;
    fitted.fallbacks.splice(0..0, lowered(dropped));
    Ok(fitted)
}

/// The fit of a single-scale solve on `basis` that determined every direction, begun at
/// `t0`, after `dropped` lowered finest levels: shared by [`fit`] and the streamed fit
/// ([`stream::fit_streamed`]).
fn single_scale_fit(
    basis: CdvBasis,
    coefficients: Vec<Vec<f64>>,
    levels: LevelChoice,
    t0: Instant,
    rep: SingleScaleReport,
    dropped: u32,
) -> Fit {
    Fit {
        active: ActiveSet::uniform(basis),
        coefficients,
        levels,
        timings: Timings {
            kernel_s: 0.0,
            solve_s: t0.elapsed().as_secs_f64(),
        },
        solve: SolveReport::SingleScale(rep),
        fallbacks: lowered(dropped),
    }
}

/// The fallback record of `dropped` lowered levels (none if zero).
fn lowered(dropped: u32) -> Vec<Fallback> {
    if dropped > 0 {
        vec![Fallback::FinestLevelLowered { by: dropped }]
    } else {
        Vec::new()
    }
}

/// Refuses, before anything of size `P` is allocated, a uniform fit that cannot work: basis
/// parameters out of range, fewer samples than functions (with automatic levels, fewer than
/// `P / 8`: at most three levels are dropped), or more memory than
/// [`crate::resources::memory_limit`] (basis, normal equations, and `K` unless single-scale).
fn guard_uniform(
    m: usize,
    channels: usize,
    params: &FitParams,
    levels: &LevelChoice,
) -> Result<(), ReconstructError> {
    use crate::resources;
    // Parameter errors first: their messages are more precise than a size.
    params.basis(levels.coarse, levels.fine, Domain::UNIT)?;
    let functions = resources::dimension(levels.fine);
    let reach = match params.levels {
        Levels::Auto(_) => 8.0,
        Levels::Fixed { .. } => 1.0,
    };
    if (m as f64) * reach < functions {
        return Err(undersampled(
            m,
            functions.min(usize::MAX as f64) as usize,
            params.p,
            levels.fine,
            Some(&params.levels),
        ));
    }
    let mut needed = resources::uniform_basis_bytes(params.p, levels.fine, channels);
    if !matches!(params.method, Method::SingleScale { .. }) {
        needed += resources::kernel_bytes(m, params.p, levels.coarse, levels.fine);
    }
    resources::check(
        || {
            format!(
                "a fit of {m} samples on levels {}..{} (P = {functions:e} functions, p = {})",
                levels.coarse, levels.fine, params.p
            )
        },
        needed,
        || "lower the fine level N (automatic levels: raise rho)".to_string(),
    )?;
    Ok(())
}

/// The fewest samples in the support of any function of `V_level` (windows of `2p - 1`
/// cells of width `2^-level`, and the `p` cells at each end).
pub(crate) fn min_support_samples(
    positions: &[f64],
    domain: Domain,
    level: u32,
    p: usize,
) -> usize {
    let cells = 1usize << level;
    let mut counts = vec![0usize; cells];
    for &x in positions {
        counts[cell_of(domain.to_unit(x), cells)] += 1;
    }
    min_support_of_counts(&counts, p)
}

/// The cell `floor(t cells)` of `t` in `[0, 1]` (`t = 1` in the last).
pub(crate) fn cell_of(t: f64, cells: usize) -> usize {
    ((t * cells as f64) as usize).min(cells - 1)
}

/// [`min_support_samples`] from the sample count of each cell of the level.
pub(crate) fn min_support_of_counts(counts: &[usize], p: usize) -> usize {
    let cells = counts.len();
    let w = (2 * p - 1).min(cells);
    let mut window: usize = counts[..w].iter().sum();
    let mut least = window;
    for c in w..cells {
        window = window + counts[c] - counts[c - w];
        least = least.min(window);
    }
    let edge = p.min(cells);
    let left: usize = counts[..edge].iter().sum();
    let right: usize = counts[cells - edge..].iter().sum();
    least.min(left).min(right)
}

/// Fits on a given active set (uniform or adaptive).
pub fn fit_active(
    active: ActiveSet,
    positions: &[f64],
    values: &[&[f64]],
    method: Method,
    levels: LevelChoice,
) -> Result<Fit, ReconstructError> {
    let m = positions.len();
    check_values(m, values)?;
    if m < active.len() {
        let basis = active.basis();
        return Err(undersampled(m, active.len(), basis.p(), basis.fine(), None));
    }
    check_positions(active.basis().domain(), positions)?;
    let uniform = active.len() == active.basis().dimension();
    let single = matches!(method, Method::SingleScale { .. }) && uniform;
    if !single {
        let basis = active.basis();
        crate::resources::check(
            || {
                format!(
                    "the kernel matrix of {m} samples x {} functions",
                    active.len()
                )
            },
            crate::resources::kernel_bytes(m, basis.p(), basis.coarse(), basis.fine()),
            || "use fewer samples or a smaller fine level N".into(),
        )?;
    }
    let t0 = Instant::now();
    // The single-scale path never forms K.
    let k = if single {
        None
    } else {
        Some(kernel_matrix(&active, positions)?)
    };
    let kernel_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut fallbacks = Vec::new();
    let (coefficients, solve) = match (method, k) {
        (Method::SingleScale { ridge, solver }, None) => {
            let (c, rep) = match solver {
                SingleScaleSolver::Qr => single_scale_qr(active.basis(), positions, values, ridge)?,
                SingleScaleSolver::NormalEquations => {
                    single_scale_ls(active.basis(), positions, values, ridge)?
                }
            };
            if rep.deficient > 0 {
                // Undetermined directions: truncated local pseudo-inverses instead.
                fallbacks.push(Fallback::LocalInversion {
                    deficient: rep.deficient,
                    unsampled: rep.unsampled,
                });
                let k = kernel_matrix(&active, positions)?;
                let out = apply_local(&k, values, &LocalInversionParams::default())?;
                (out.coefficients, SolveReport::Local(out.stats))
            } else {
                (c, SolveReport::SingleScale(rep))
            }
        }
        (Method::Local(lp), Some(k)) => {
            let out = apply_local(&k, values, &lp)?;
            (out.coefficients, SolveReport::Local(out.stats))
        }
        (Method::Dense { cutoff }, Some(k)) => {
            let pinv = dense_pinv(&k, cutoff)?;
            let c = values
                .iter()
                .map(|f| pinv.apply(f))
                .collect::<Result<Vec<_>, _>>()?;
            (c, SolveReport::Dense { cutoff })
        }
        // Global, or single scale on an adaptive set (no single-scale equivalent).
        (m, Some(k)) => {
            let gp = match m {
                Method::Global(gp) => gp,
                _ => GlobalLsParams::default(),
            };
            let out = global_ls(&k, values, &gp)?;
            (out.coefficients, SolveReport::Global(out.report))
        }
        (_, None) => unreachable!("K is formed for every method but the uniform single scale"),
    };
    Ok(Fit {
        active,
        coefficients,
        levels,
        timings: Timings {
            kernel_s,
            solve_s: t1.elapsed().as_secs_f64(),
        },
        solve,
        fallbacks,
    })
}
