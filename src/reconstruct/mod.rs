//! From samples to a reconstruction: levels, kernel matrix, solve, coefficients, evaluation.
//!
//! `c = K^+ f` (docs/design.md §3): the coefficients of `f(x) = sum_a c_a Psi_a(x)` over the active set,
//! by local inversion (the default), a global sparse least-squares solve, or a dense
//! pseudo-inverse. Evaluation of a uniform `Psi(n, N)` goes through the interval FWT to the
//! single-scale `V_{N+1}` coefficients and then evaluates only `2p - 1` (plus edge) scaling
//! functions per position.

mod banded_qr;
pub(crate) mod density;
mod evaluate;
mod kernel_functions;
mod outcome;
mod single_scale;
pub mod stream;
mod undersampled;

pub use evaluate::FitEvaluator;
pub use kernel_functions::{dual_kernel, reproducing_kernel};
pub use outcome::{Fallback, SolveReport};
pub use single_scale::{
    single_scale_ls, single_scale_qr, NormalEquations, SingleScaleProblem, SingleScaleReport,
    SingleScaleSolver, PIVOT_TOLERANCE,
};
use undersampled::undersampled;
pub use undersampled::UndersampledFix;

use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

use crate::basis::{BasisError, CdvBasis, FilterFamily};
use crate::kernel::{
    check_positions, kernel_matrix, ActiveSet, KernelError, LevelChoice, LevelParams,
};
use crate::sampling::Domain;
use crate::solve::{
    apply_local, dense_pinv, global_ls, GlobalLsParams, LocalInversionParams, SolveError,
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
    /// Local inversion (docs/design.md §4): fast, local, approximate.
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
///
/// The default is `p = 3`, CDV's filter family, automatic levels and the single-scale
/// solve. Change one field and keep the rest:
///
/// ```
/// use rkwave::basis::FilterFamily;
/// use rkwave::reconstruct::{FitParams, Levels, Method};
/// use rkwave::solve::LocalInversionParams;
///
/// let params = FitParams { p: 6, ..FitParams::default() };
/// assert_eq!(params.family(), FilterFamily::LeastAsymmetric); // sym6, CDV's choice
///
/// let fixed = FitParams {
///     levels: Levels::Fixed { coarse: 4, fine: 7 },
///     method: Method::Local(LocalInversionParams::default()),
///     ..FitParams::default()
/// };
/// assert_eq!(fixed.family(), FilterFamily::Extremal); // db3
/// ```
#[derive(Clone, Copy, Debug)]
pub struct FitParams {
    /// Vanishing moments `p`: higher reproduces smoother signals with fewer samples, costs
    /// `O(p^2)` per sample.
    pub p: usize,
    /// Interior filter family; `None` is CDV's choice for `p`
    /// ([`FilterFamily::cdv_default`]: extremal phase for `p <= 3`, least asymmetric above).
    pub family: Option<FilterFamily>,
    /// Levels.
    pub levels: Levels,
    /// Solver.
    pub method: Method,
}

impl FitParams {
    /// The interior filter family: the given one, or CDV's choice for `p`.
    pub fn family(&self) -> FilterFamily {
        self.family
            .unwrap_or_else(|| FilterFamily::cdv_default(self.p))
    }

    /// The CDV basis of these parameters with scaling level `coarse` and wavelets on
    /// `coarse..=fine` on `domain` ([`CdvBasis::new`], with [`FitParams::family`]).
    pub fn basis(&self, coarse: u32, fine: u32, domain: Domain) -> Result<CdvBasis, BasisError> {
        CdvBasis::new(self.p, self.family(), coarse, fine, domain)
    }
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            p: 3,
            family: None,
            levels: Levels::Auto(LevelParams::default()),
            method: Method::SingleScale {
                ridge: 0.0,
                solver: SingleScaleSolver::default(),
            },
        }
    }
}

/// Errors of reconstruction.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
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
    #[error("{samples} samples cannot determine {functions} basis functions: {fix}")]
    Undersampled {
        /// Samples `m` (rows of `K`).
        samples: usize,
        /// Basis functions `P` (columns of `K`).
        functions: usize,
        /// What to change: only changes that can work here (more samples; a smaller fine
        /// level or a larger `rho` only where the basis is not already the smallest for `p`).
        fix: UndersampledFix,
    },
    /// The request would need more memory than the limit.
    #[error(transparent)]
    Resources(#[from] crate::resources::ResourceError),
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

/// A fitted reconstruction: `f~(x) = sum_a c_a Psi_a(x)` over the active set, per channel.
///
/// ```
/// use rkwave::reconstruct::{fit, FitParams};
/// use rkwave::sampling::{Domain, Layout};
///
/// let xs = Layout::Random.generate(1000, Domain::UNIT, 3);
/// let line: Vec<f64> = xs.iter().map(|x| 2.0 * x - 1.0).collect();
/// let square: Vec<f64> = xs.iter().map(|x| x * x).collect();
/// let f = fit(&xs, &[&line, &square], Domain::UNIT, &FitParams::default())?;
/// assert_eq!(f.coefficients.len(), 2); // two channels
/// assert_eq!(f.coefficients[0].len(), f.active.len());
/// // p = 3 reproduces polynomials of degree < 3 exactly (up to rounding).
/// let v = f.evaluate(&[0.25])?;
/// assert!((v[0][0] + 0.5).abs() < 1e-9 && (v[1][0] - 0.0625).abs() < 1e-9);
/// # Ok::<(), rkwave::reconstruct::ReconstructError>(())
/// ```
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
    /// The report of the solve that produced the coefficients.
    pub solve: SolveReport,
    /// Every departure from the requested levels or method, in the order taken (empty when
    /// the fit is exactly what was asked for).
    pub fallbacks: Vec<Fallback>,
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

impl Fit {
    /// Every fallback and warning of the fit, one sentence each, for text and JSON output:
    /// the replaced method or lowered level ([`Fit::fallbacks`]) and the local inversion's
    /// cut directions, solver fallbacks and weakly supported blocks
    /// ([`LocalStats::warnings`]).
    pub fn warnings(&self) -> Vec<String> {
        let mut w: Vec<String> = self.fallbacks.iter().map(|f| f.to_string()).collect();
        if let SolveReport::Local(local) = &self.solve {
            w.extend(local.warnings());
        }
        w
    }

    /// The reconstruction at `xs`, one vector per channel (see [`Fit::evaluator`] to evaluate
    /// many batches).
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<Vec<f64>>, ReconstructError> {
        self.evaluator()?.evaluate(xs)
    }
}

impl ReconstructError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ReconstructError::Basis(e) => e.kind(),
            ReconstructError::Kernel(e) => e.kind(),
            ReconstructError::Solve(e) => e.kind(),
            ReconstructError::Undersampled { .. } => crate::error::ErrorKind::Undetermined,
            ReconstructError::Resources(e) => e.kind(),
            ReconstructError::NonFiniteValue { .. } | ReconstructError::LengthMismatch { .. } => {
                crate::error::ErrorKind::InvalidInput
            }
        }
    }
}

crate::error::classified!(ReconstructError);
