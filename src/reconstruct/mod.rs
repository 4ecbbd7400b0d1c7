//! From samples to a reconstruction: levels, kernel matrix, solve, coefficients, evaluation.
//!
//! `c = K^+ f` (DESIGN §3): the coefficients of `f(x) = sum_a c_a Psi_a(x)` over the active set,
//! by local inversion (the default), a global sparse least-squares solve, or a dense
//! pseudo-inverse. Evaluation of a uniform `Psi(n, N)` goes through the interval FWT to the
//! single-scale `V_{N+1}` coefficients and then evaluates only `2p - 1` (plus edge) scaling
//! functions per position.

mod banded_qr;
mod evaluate;
mod kernels;
mod single_scale;

pub use evaluate::FitEvaluator;
pub use kernels::{dual_kernel, reproducing_kernel};
pub use single_scale::{
    single_scale_ls, single_scale_qr, NormalEquations, SingleScaleProblem, SingleScaleReport,
    SingleScaleSolver, PIVOT_TOLERANCE,
};

use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

use crate::basis::{BasisError, CdvBasis, FilterFamily};
use crate::kernel::{
    check_positions, kernel_matrix, ActiveSet, KernelError, LevelChoice, LevelParams,
};
use crate::sampling::Domain;
use crate::solve::{
    apply_local, dense_pinv, global_ls, GlobalLsParams, GlobalReport, LocalInversionParams,
    LocalStats, SolveError,
};

/// How the levels are chosen.
#[derive(Clone, Copy, Debug, Serialize)]
pub enum Levels {
    /// From the number of samples ([`LevelChoice::auto`]).
    Auto(LevelParams),
    /// Given explicitly.
    Fixed {
        /// Coarse scaling level `n`.
        coarse: u32,
        /// Finest wavelet level `N`.
        fine: u32,
    },
}

/// How `c = K^+ f` is computed.
#[derive(Clone, Copy, Debug, Serialize)]
pub enum Method {
    /// Global least squares through the single-scale basis `V_{N+1}` (banded QR or banded
    /// normal equations, then the FWT): exact, `O(m p^2 + P p^2)`, the fastest path for
    /// uniform levels; `ridge` is the relative diagonal shift of the equilibrated normal matrix.
    SingleScale {
        /// Relative ridge (e.g. 1e-13).
        ridge: f64,
        /// Factorization: QR (accuracy of `cond(K)`, default) or normal equations
        /// (`cond(K)^2`, cheaper per sample).
        solver: SingleScaleSolver,
    },
    /// Local inversion (DESIGN §4): fast, local, approximate.
    Local(LocalInversionParams),
    /// Global sparse least squares: exact up to the solver tolerance, one large factorization.
    Global(GlobalLsParams),
    /// Dense SVD pseudo-inverse with a relative cut-off: the truth, small problems only.
    Dense {
        /// Relative singular value cut-off.
        cutoff: f64,
    },
}

/// Parameters of a fit.
#[derive(Clone, Copy, Debug)]
pub struct FitParams {
    /// Vanishing moments `p`: higher reproduces smoother signals with fewer samples, costs
    /// `O(p^2)` per sample.
    pub p: usize,
    /// Interior filter family.
    pub family: FilterFamily,
    /// Levels.
    pub levels: Levels,
    /// Solver.
    pub method: Method,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            p: 3,
            family: FilterFamily::cdv_default(3),
            levels: Levels::Auto(LevelParams::default()),
            method: Method::SingleScale {
                ridge: 0.0,
                solver: SingleScaleSolver::default(),
            },
        }
    }
}

/// Errors of reconstruction.
#[derive(Debug, Error)]
pub enum ReconstructError {
    /// Basis parameters.
    #[error(transparent)]
    Basis(#[from] BasisError),
    /// Sample positions.
    #[error(transparent)]
    Kernel(#[from] KernelError),
    /// The solve.
    #[error(transparent)]
    Solve(#[from] SolveError),
    /// Fewer samples than basis functions.
    #[error(
        "{samples} samples cannot determine {functions} basis functions: give more samples, \
         a smaller fine level N, or automatic levels"
    )]
    Undersampled {
        /// Samples `m`.
        samples: usize,
        /// Basis functions `P`.
        functions: usize,
    },
    /// A sample value is NaN or infinite.
    #[error(
        "sample {row} (1-based), channel {channel}: value {value} is not finite: fix or remove it"
    )]
    NonFiniteValue {
        /// 1-based sample.
        row: usize,
        /// 0-based channel.
        channel: usize,
        /// The value.
        value: f64,
    },
    /// Values and positions disagree in length.
    #[error("channel {channel} has {found} values for {expected} positions")]
    LengthMismatch {
        /// Channel.
        channel: usize,
        /// Positions.
        expected: usize,
        /// Values.
        found: usize,
    },
}

/// Seconds spent in each stage.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Timings {
    /// Building `K`.
    pub kernel_s: f64,
    /// Solving for the coefficients.
    pub solve_s: f64,
}

/// A fitted reconstruction.
#[derive(Clone, Debug)]
pub struct Fit {
    /// The active basis.
    pub active: ActiveSet,
    /// Coefficients per channel, one per active function.
    pub coefficients: Vec<Vec<f64>>,
    /// The levels used.
    pub levels: LevelChoice,
    /// Stage times.
    pub timings: Timings,
    /// Local inversion statistics (local method).
    pub local: Option<LocalStats>,
    /// Single-scale solve report.
    pub single_scale: Option<SingleScaleReport>,
    /// Why the requested method was replaced, if it was (e.g. the single-scale normal
    /// equations were rank deficient and local inversion took over).
    pub fallback: Option<String>,
    /// Global solve report (global method).
    pub global: Option<GlobalReport>,
}

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
pub fn fit(
    positions: &[f64],
    values: &[&[f64]],
    domain: Domain,
    params: &FitParams,
) -> Result<Fit, ReconstructError> {
    let m = positions.len();
    check_values(m, values)?;
    let mut levels = choose_levels(m, params);
    let mut dropped = 0;
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
            levels.fine -= 1;
            levels.oversampling *= 2.0;
            dropped += 1;
        }
        let first = CdvBasis::new(params.p, params.family, levels.coarse, levels.fine, domain)?;
        if domain_ok && m >= first.dimension() {
            let t0 = Instant::now();
            let mut ne = SingleScaleProblem::new(&first, positions, values, solver)?;
            while dropped <= 3 && levels.fine >= levels.coarse {
                let basis =
                    CdvBasis::new(params.p, params.family, levels.coarse, levels.fine, domain)?;
                let (c, rep) = ne.solve(&basis, ridge)?;
                if rep.deficient == 0 {
                    return Ok(Fit {
                        active: ActiveSet::uniform(basis),
                        coefficients: c,
                        levels,
                        timings: Timings {
                            kernel_s: 0.0,
                            solve_s: t0.elapsed().as_secs_f64(),
                        },
                        local: None,
                        global: None,
                        single_scale: Some(rep),
                        fallback: (dropped > 0).then(|| {
                            format!(
                                "finest level lowered by {dropped}: the samples left \
                                 single-scale directions undetermined at the automatic level"
                            )
                        }),
                    });
                }
                if levels.fine == levels.coarse {
                    break;
                }
                ne = ne.coarsen(basis.bank());
                levels.fine -= 1;
                levels.oversampling *= 2.0;
                dropped += 1;
            }
        }
    }
    let basis = CdvBasis::new(params.p, params.family, levels.coarse, levels.fine, domain)?;
    let active = ActiveSet::uniform(basis);
    fit_active(active, positions, values, params.method, levels)
}

/// The fewest samples in the support of any function of `V_level` (windows of `2p - 1`
/// cells of width `2^-level`, and the `p` cells at each end).
fn min_support_samples(positions: &[f64], domain: Domain, level: u32, p: usize) -> usize {
    let cells = 1usize << level;
    let mut counts = vec![0usize; cells];
    for &x in positions {
        let c = (domain.to_unit(x) * cells as f64) as usize;
        counts[c.min(cells - 1)] += 1;
    }
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
        return Err(ReconstructError::Undersampled {
            samples: m,
            functions: active.len(),
        });
    }
    check_positions(active.basis().domain(), positions)?;
    let uniform = active.len() == active.basis().dimension();
    let single = matches!(method, Method::SingleScale { .. }) && uniform;
    let t0 = Instant::now();
    // The single-scale path never forms K.
    let k = if single {
        None
    } else {
        Some(kernel_matrix(&active, positions)?)
    };
    let kernel_s = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let mut single_scale = None;
    let mut fallback = None;
    let (coefficients, local, global) = match (method, k) {
        (Method::SingleScale { ridge, solver }, None) => {
            let (c, rep) = match solver {
                SingleScaleSolver::Qr => single_scale_qr(active.basis(), positions, values, ridge)?,
                SingleScaleSolver::NormalEquations => {
                    single_scale_ls(active.basis(), positions, values, ridge)?
                }
            };
            if rep.deficient > 0 {
                // Undetermined directions: truncated local pseudo-inverses instead.
                fallback = Some(format!(
                    "single-scale normal equations have {} undetermined directions \
                     ({} functions without samples): local inversion used instead",
                    rep.deficient, rep.unsampled
                ));
                single_scale = Some(rep);
                let k = kernel_matrix(&active, positions)?;
                let out = apply_local(&k, values, &LocalInversionParams::default())?;
                (out.coefficients, Some(out.stats), None)
            } else {
                single_scale = Some(rep);
                (c, None, None)
            }
        }
        (Method::Local(lp), Some(k)) => {
            let out = apply_local(&k, values, &lp)?;
            (out.coefficients, Some(out.stats), None)
        }
        (Method::Dense { cutoff }, Some(k)) => {
            let pinv = dense_pinv(&k, cutoff)?;
            let c = values
                .iter()
                .map(|f| pinv.apply(f))
                .collect::<Result<Vec<_>, _>>()?;
            (c, None, None)
        }
        // Global, or single scale on an adaptive set (no single-scale equivalent).
        (m, Some(k)) => {
            let gp = match m {
                Method::Global(gp) => gp,
                _ => GlobalLsParams::default(),
            };
            let out = global_ls(&k, values, &gp)?;
            (out.coefficients, None, Some(out.report))
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
        local,
        global,
        single_scale,
        fallback,
    })
}

impl Fit {
    /// The reconstruction at `xs`, one vector per channel (see [`Fit::evaluator`] to evaluate
    /// many batches).
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<Vec<f64>>, ReconstructError> {
        self.evaluator()?.evaluate(xs)
    }
}
