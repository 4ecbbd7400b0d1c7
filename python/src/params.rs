//! Keyword arguments to the library's parameter structs: every place this module builds a
//! `FitParams`, `ReportSetting`, `WaveletParams`, `AdaptiveParams` or `RefineParams` is here,
//! so a change of those structs touches this file alone. Each check refuses what the command
//! line refuses for the same parameter, naming the keyword.

use pyo3::prelude::*;
use rkwave::basis::FilterFamily;
use rkwave::image::job::{PlanBudget, PlanOptions};
use rkwave::kernel::LevelParams;
use rkwave::reconstruct::{FitParams, Levels, Method, SingleScaleSolver};
use rkwave::refine::{
    BaseSampling, Indicator, IntervalTreeParams, MarkingParams, RefineParams,
    StopParams as RefineStop, TreeParams as RefineTree,
};
use rkwave::report::ReportSetting;
use rkwave::sampling::{Domain, Layout, Signal};
use rkwave::solve::{GlobalLsParams, LocalInversionParams, Solver, MAX_RINGS};

use crate::errors::{invalid, to_py};

/// The filter family by name: `None` (CDV's choice for `p`), `"db"` or `"sym"`.
pub fn family(name: Option<&str>) -> PyResult<Option<FilterFamily>> {
    match name.map(|s| s.trim().to_ascii_lowercase()) {
        None => Ok(None),
        Some(s) if s == "db" => Ok(Some(FilterFamily::Extremal)),
        Some(s) if s == "sym" => Ok(Some(FilterFamily::LeastAsymmetric)),
        Some(s) => Err(invalid(format!(
            "family={s:?}: expected \"db\" (extremal phase) or \"sym\" (least asymmetric), or \
             None for CDV's choice"
        ))),
    }
}

/// The domain `(a, b)`.
pub fn domain(ab: (f64, f64)) -> PyResult<Domain> {
    Domain::new(ab.0, ab.1).map_err(|e| invalid(format!("domain={ab:?}: {e}")))
}

/// A relative singular value cut-off in `[0, 1)`.
fn check_cutoff(cutoff: f64) -> PyResult<()> {
    if cutoff.is_finite() && (0.0..1.0).contains(&cutoff) {
        Ok(())
    } else {
        Err(invalid(format!(
            "cutoff={cutoff} must be a relative cut-off in [0, 1), e.g. 1e-12"
        )))
    }
}

/// Neighbourhood rings of local inversion, at most [`MAX_RINGS`].
fn check_rings(rings: usize) -> PyResult<()> {
    if rings > MAX_RINGS {
        return Err(invalid(format!(
            "rings={rings} is outside 0..={MAX_RINGS}: local inversion takes at most \
             {MAX_RINGS} rings"
        )));
    }
    Ok(())
}

/// The local solver by name.
fn solver(name: &str) -> PyResult<Solver> {
    match name {
        "svd" => Ok(Solver::Svd),
        "qr" => Ok(Solver::Qr),
        "cholesky" => Ok(Solver::Cholesky),
        other => Err(invalid(format!(
            "solver={other:?}: expected \"svd\", \"qr\" or \"cholesky\""
        ))),
    }
}

/// The knobs of a 1D fit, as given to `rkwave.fit`.
pub struct FitArgs<'a> {
    /// Vanishing moments.
    pub p: usize,
    /// Filter family name.
    pub family: Option<&'a str>,
    /// `None` or `"auto"`, or `(n, N)`.
    pub levels: Option<(u32, u32)>,
    /// `single`, `local`, `global` or `dense`.
    pub method: &'a str,
    /// Oversampling target of automatic levels.
    pub rho: f64,
    /// Samples a coarse function may cover (automatic levels).
    pub coarse_samples: f64,
    /// Rings of local inversion.
    pub rings: usize,
    /// Local solver name.
    pub solver: &'a str,
    /// Relative cut-off of the local SVD / QR and the dense pseudo-inverse.
    pub cutoff: f64,
    /// Relative ridge of the single-scale normal equations.
    pub ridge: f64,
    /// `qr` or `normal` (single-scale factorization).
    pub factorization: &'a str,
}

/// The library's fit parameters, checked as `rkwave reconstruct` checks its flags.
pub fn fit_params(a: &FitArgs<'_>) -> PyResult<FitParams> {
    if !(a.rho.is_finite() && a.rho > 0.0) {
        return Err(invalid(format!(
            "rho={} must be a positive oversampling rate such as 2",
            a.rho
        )));
    }
    if !(a.coarse_samples.is_finite() && a.coarse_samples >= 1.0) {
        return Err(invalid(format!(
            "coarse_samples={} must be at least 1",
            a.coarse_samples
        )));
    }
    check_cutoff(a.cutoff)?;
    check_rings(a.rings)?;
    if !(a.ridge.is_finite() && (0.0..1.0).contains(&a.ridge)) {
        return Err(invalid(format!(
            "ridge={} must be in [0, 1), e.g. 1e-16",
            a.ridge
        )));
    }
    let levels = match a.levels {
        None => Levels::Auto(LevelParams {
            rho: a.rho,
            coarse_samples: a.coarse_samples,
        }),
        Some((coarse, fine)) => Levels::Fixed { coarse, fine },
    };
    let single = match a.factorization {
        "qr" => SingleScaleSolver::Qr,
        "normal" => SingleScaleSolver::NormalEquations,
        other => {
            return Err(invalid(format!(
                "factorization={other:?}: expected \"qr\" or \"normal\""
            )))
        }
    };
    let method = match a.method {
        "single" => Method::SingleScale {
            ridge: a.ridge,
            solver: single,
        },
        "local" => Method::Local(LocalInversionParams {
            rings: a.rings,
            solver: solver(a.solver)?,
            cutoff: a.cutoff,
            ..LocalInversionParams::default()
        }),
        "global" => Method::Global(GlobalLsParams::default()),
        "dense" => Method::Dense { cutoff: a.cutoff },
        other => {
            return Err(invalid(format!(
                "method={other:?}: expected \"single\", \"local\", \"global\" or \"dense\""
            )))
        }
    };
    Ok(FitParams {
        p: a.p,
        family: family(a.family)?,
        levels,
        method,
    })
}

/// The setting of the local-vs-global report, checked as `rkwave report` checks its flags.
#[allow(clippy::too_many_arguments)]
pub fn report_setting(
    p: usize,
    family_name: Option<&str>,
    coarse: Option<u32>,
    fine: u32,
    samples: usize,
    layout: &str,
    seed: u64,
    signal: &str,
    rings: usize,
    solver_name: &str,
    cutoff: f64,
    grid: usize,
) -> PyResult<ReportSetting> {
    let family = family(family_name)?.unwrap_or_else(|| FilterFamily::cdv_default(p.max(1)));
    let coarse = coarse.unwrap_or_else(|| rkwave::basis::minimum_level(p.max(1)));
    rkwave::basis::CdvBasis::new(p, family, coarse, fine, Domain::UNIT).map_err(to_py)?;
    if samples == 0 {
        return Err(invalid("samples=0: give at least one sample"));
    }
    if grid < 2 {
        return Err(invalid("grid must be at least 2"));
    }
    check_cutoff(cutoff)?;
    check_rings(rings)?;
    Ok(ReportSetting {
        p,
        family,
        coarse,
        fine,
        samples,
        layout: layout
            .parse::<Layout>()
            .map_err(|e| invalid(format!("layout: {e}")))?,
        seed,
        signal: signal
            .parse::<Signal>()
            .map_err(|e| invalid(format!("signal: {e}")))?,
        local: LocalInversionParams {
            rings,
            solver: solver(solver_name)?,
            cutoff,
            ..LocalInversionParams::default()
        },
        grid,
    })
}

/// Vanishing moments on the image plane: 1 to 4 (the library's range,
/// [`rkwave::image::job::check_p`]).
pub fn image_p(p: usize) -> PyResult<usize> {
    rkwave::image::job::check_p(p).map_err(crate::errors::to_py)
}

/// The keyword arguments of `rkwave.Plan`, as the flags of `rkwave plan`.
pub struct PlanArgs<'a> {
    /// Total sample budget.
    pub budget: Option<usize>,
    /// Average samples per pixel.
    pub spp: Option<usize>,
    /// Vanishing moments.
    pub p: Option<usize>,
    /// Samples per slot.
    pub rho: Option<f64>,
    /// Depth limit below the pixel.
    pub below_pixel: Option<u32>,
    /// Seed of the positions.
    pub seed: Option<u64>,
    /// False-alarm rate of the noise test.
    pub false_alarm: Option<f64>,
    /// Least growth per round, as a share of the samples so far.
    pub min_growth: Option<f64>,
    /// Share of each round's new samples given to the pixels by their spread.
    pub pixel_share: Option<f64>,
    /// Where a slot's positions go: `"sobol"` or `"stratified"`.
    pub pattern: Option<&'a str>,
    /// Where a round's spare samples go: `"indicator"`, `"uncertainty"` or `"uniform"`.
    pub spread: Option<&'a str>,
    /// The rounds' solver: `"pcg"`, `"direct"` or `"schwarz"`.
    pub solver: Option<&'a str>,
    /// The final image's pixels, by [`PixelEstimate`]'s name.
    pub output_pixels: Option<&'a str>,
}

/// The plan's options from `rkwave.Plan`'s keywords, as `rkwave plan` takes its flags:
/// parsing only (one of `budget=` and `spp=`; the names of `pattern=`, `spread=`, `solver=`
/// and `output_pixels=`); the library's plan jobs ([`rkwave::image::job::PlanStart`])
/// validate them and decide the defaults for both front ends. Every field of
/// [`PlanOptions`] is set here by name (no `..Default`), so an option the library adds does
/// not compile until it has its keyword.
pub fn plan_options(a: &PlanArgs<'_>) -> PyResult<PlanOptions> {
    let budget = match (a.budget, a.spp) {
        (Some(_), Some(_)) => {
            return Err(invalid(
                "give budget= (total samples) or spp= (samples per pixel), not both",
            ))
        }
        (budget, spp) => budget
            .map(PlanBudget::Samples)
            .or(spp.map(PlanBudget::PerPixel)),
    };
    Ok(PlanOptions {
        budget,
        p: a.p,
        rho: a.rho,
        below_pixel: a.below_pixel,
        seed: a.seed,
        false_alarm: a.false_alarm,
        min_growth: a.min_growth,
        pixel_share: a.pixel_share,
        pattern: parse_named("pattern", a.pattern)?,
        spread: parse_named("spread", a.spread)?,
        output_pixels: parse_named("output_pixels", a.output_pixels)?,
        solver: parse_named("solver", a.solver)?,
    })
}

/// A keyword's name parsed as its library type (`None` when not given); a name it does not
/// know is refused as `keyword="name": <the library's words>`.
fn parse_named<T>(keyword: &str, name: Option<&str>) -> PyResult<Option<T>>
where
    T: std::str::FromStr,
    T::Err: std::fmt::Display,
{
    name.map(|name| {
        name.parse::<T>()
            .map_err(|e| invalid(format!("{keyword}={name:?}: {e}")))
    })
    .transpose()
}

/// The keyword arguments of `rkwave.adapt`, as the flags of `rkwave adapt` (same defaults).
pub struct AdaptArgs<'a> {
    /// The domain.
    pub domain: Domain,
    /// Vanishing moments.
    pub p: usize,
    /// Filter family name.
    pub family: Option<&'a str>,
    /// Coarse level.
    pub coarse: Option<u32>,
    /// Target RMS error.
    pub tolerance: f64,
    /// Depth limit.
    pub max_depth: u32,
    /// Sample budget.
    pub budget: usize,
    /// Seed.
    pub seed: u64,
    /// Base samples.
    pub base_samples: usize,
    /// Base depth.
    pub base_depth: Option<u32>,
    /// Base layout name.
    pub layout: &'a str,
    /// Samples per leaf.
    pub rho: f64,
    /// Dörfler fraction.
    pub theta: f64,
    /// `coefficients`, `residual` or `both`.
    pub indicator: &'a str,
    /// Probe points per leaf (residual indicator).
    pub probes: usize,
}

/// The refiner's parameters, checked by the library ([`RefineParams::validate`]).
pub fn refine_params(a: &AdaptArgs<'_>) -> PyResult<RefineParams> {
    let indicator = match a.indicator {
        "coefficients" => Indicator::Coefficients,
        "residual" => Indicator::Residual { probes: a.probes },
        "both" => Indicator::Both { probes: a.probes },
        other => {
            return Err(invalid(format!(
                "indicator={other:?}: expected \"coefficients\", \"residual\" or \"both\""
            )))
        }
    };
    let params = RefineParams {
        domain: a.domain,
        indicator,
        reference_grid: 0,
        tree: RefineTree { p: a.p, rho: a.rho },
        interval: IntervalTreeParams {
            family: Some(
                family(a.family)?.unwrap_or_else(|| FilterFamily::cdv_default(a.p.max(1))),
            ),
            coarse: a.coarse,
            base_depth: a.base_depth,
            max_depth: a.max_depth,
        },
        sampling: BaseSampling {
            base_samples: a.base_samples,
            base_layout: a
                .layout
                .parse::<Layout>()
                .map_err(|e| invalid(format!("layout: {e}")))?,
            seed: a.seed,
        },
        stop: RefineStop {
            tolerance: a.tolerance,
            budget: a.budget,
            ..RefineParams::default().stop
        },
        marking: MarkingParams { theta: a.theta },
        ..RefineParams::default()
    };
    params.validate().map_err(to_py)?;
    Ok(params)
}
