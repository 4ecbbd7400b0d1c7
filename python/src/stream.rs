//! 1D fits out of core and across processes: partial fits of chunks of samples
//! ([`rkwave::reconstruct::stream::SingleScaleAccumulator`]: the banded QR triangle of a chunk,
//! as `bytes` so that Dask or pickle can move it), merged in any tree and finished into the
//! same [`PyFit`] as `rkwave.fit`. `rkwave.dask.fit_chunks` drives them.
//!
//! Every call names the whole problem (`samples` in total, `domain`, `p`, `levels`, `rho`):
//! the basis follows from it as in `rkwave.fit` ([`rkwave::reconstruct::choose_levels`]), so
//! partials built on different machines agree on their columns.

use pyo3::prelude::*;
use pyo3::types::{PyAny, PyBytes};
use rkwave::basis::CdvBasis;
use rkwave::kernel::ActiveSet;
use rkwave::reconstruct::stream::SingleScaleAccumulator;
use rkwave::reconstruct::{choose_levels, Fit, FitParams, Method, SolveReport, Timings};

use crate::arrays::{check_finite, columns, floats, vector};
use crate::errors::{invalid, to_py};
use crate::fit::{levels_arg, FitReport, FitSeconds, PyFit};
use crate::params::{domain as domain_of, fit_params, FitArgs};

/// The problem every partial of one fit shares.
struct Problem {
    params: FitParams,
    basis: CdvBasis,
    levels: rkwave::kernel::LevelChoice,
    ridge: f64,
}

#[allow(clippy::too_many_arguments)]
fn problem(
    samples: usize,
    domain: (f64, f64),
    p: usize,
    levels: Option<&Bound<'_, PyAny>>,
    family: Option<&str>,
    rho: f64,
    coarse_samples: f64,
    ridge: f64,
) -> PyResult<Problem> {
    let params = fit_params(&FitArgs {
        p,
        family,
        levels: levels_arg(levels)?,
        method: "single",
        rho,
        coarse_samples,
        rings: 1,
        solver: "svd",
        cutoff: 1e-12,
        ridge,
        factorization: "qr",
    })?;
    if samples == 0 {
        return Err(invalid(
            "samples=0: give the total number of samples of all chunks",
        ));
    }
    let domain = domain_of(domain)?;
    let levels = choose_levels(samples, &params);
    let basis = params
        .basis(levels.coarse, levels.fine, domain)
        .map_err(to_py)?;
    Ok(Problem {
        params,
        basis,
        levels,
        ridge,
    })
}

/// The partial fit of one chunk of samples (sorted by `x`, inside `domain`, after the samples
/// of every earlier chunk) as bytes: the banded QR triangle of its rows. `samples` is the
/// number of samples of all chunks together (it sets the levels), `start` the index of this
/// chunk's first sample (errors name samples by it). `y` is `(m,)` or `(m, channels)`.
///
/// >>> import numpy as np, rkwave
/// >>> x = np.linspace(0, 1, 4000); y = np.sin(3 * x)
/// >>> kw = dict(samples=4000, domain=(0, 1))
/// >>> a = rkwave.partial_fit(x[:2500], y[:2500], **kw)
/// >>> b = rkwave.partial_fit(x[2500:], y[2500:], start=2500, **kw)
/// >>> f = rkwave.finish_partial(rkwave.merge_partials(a, b, **kw), **kw)
/// >>> bool(abs(f(np.array([0.5]))[0] - np.sin(1.5)) < 1e-6)
/// True
#[pyfunction]
#[pyo3(signature = (x, y, *, samples, domain, start=0, p=3, levels=None, family=None,
    rho=2.0, coarse_samples=256.0))]
#[allow(clippy::too_many_arguments)]
pub fn partial_fit<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    samples: usize,
    domain: (f64, f64),
    start: usize,
    p: usize,
    levels: Option<&Bound<'py, PyAny>>,
    family: Option<&str>,
    rho: f64,
    coarse_samples: f64,
) -> PyResult<Bound<'py, PyBytes>> {
    let pr = problem(samples, domain, p, levels, family, rho, coarse_samples, 0.0)?;
    let xd = floats(x, "x")?;
    let xv = xd.view();
    let xs = vector(&xv, "x")?;
    check_finite(&xs, "x")?;
    if xs.is_empty() {
        return Err(invalid(
            "the chunk is empty: give every chunk at least one sample",
        ));
    }
    let yd = floats(y, "y")?;
    let yv = yd.view();
    let ys = columns(&yv, "y")?;
    if ys.is_empty() || ys.iter().any(|c| c.len() != xs.len()) {
        return Err(invalid(format!(
            "y has shape {} but x has {} samples: give y as (m,) or (m, channels) with m = {}",
            crate::arrays::shape(yv.shape()),
            xs.len(),
            xs.len()
        )));
    }
    let channels: Vec<&[f64]> = ys.iter().map(|c| c.as_ref()).collect();
    let bytes = py
        .detach(|| {
            let mut acc = SingleScaleAccumulator::new(&pr.basis, channels.len()).starting_at(start);
            acc.add_chunk(&xs, &channels).map(|()| acc.to_bytes())
        })
        .map_err(to_py)?;
    Ok(PyBytes::new(py, &bytes))
}

/// The partial fit of the samples of `earlier` followed by those of `later` (both from
/// [`partial_fit`] or this function, for the same problem).
#[pyfunction]
#[pyo3(signature = (earlier, later, *, samples, domain, p=3, levels=None, family=None,
    rho=2.0, coarse_samples=256.0))]
#[allow(clippy::too_many_arguments)]
pub fn merge_partials<'py>(
    py: Python<'py>,
    earlier: &[u8],
    later: &[u8],
    samples: usize,
    domain: (f64, f64),
    p: usize,
    levels: Option<&Bound<'py, PyAny>>,
    family: Option<&str>,
    rho: f64,
    coarse_samples: f64,
) -> PyResult<Bound<'py, PyBytes>> {
    let pr = problem(samples, domain, p, levels, family, rho, coarse_samples, 0.0)?;
    let bytes = py
        .detach(|| {
            let mut a = SingleScaleAccumulator::from_bytes(earlier, &pr.basis)?;
            a.merge(SingleScaleAccumulator::from_bytes(later, &pr.basis)?)?;
            Ok(a.to_bytes())
        })
        .map_err(to_py::<rkwave::reconstruct::stream::StreamError>)?;
    Ok(PyBytes::new(py, &bytes))
}

/// The fit of a partial that holds all `samples`: the same `Fit` as `rkwave.fit` on them (its
/// coefficients bit for bit when the partials were merged in `rkwave.fit`'s order, else
/// within the QR's rounding). Raises `RkwaveError` when the samples leave directions
/// undetermined (`rkwave.fit` would lower the levels or fall back to local inversion): give
/// lower `levels`.
#[pyfunction]
#[pyo3(signature = (partial, *, samples, domain, p=3, levels=None, family=None, rho=2.0,
    coarse_samples=256.0, ridge=0.0))]
#[allow(clippy::too_many_arguments)]
pub fn finish_partial<'py>(
    py: Python<'py>,
    partial: &[u8],
    samples: usize,
    domain: (f64, f64),
    p: usize,
    levels: Option<&Bound<'py, PyAny>>,
    family: Option<&str>,
    rho: f64,
    coarse_samples: f64,
    ridge: f64,
) -> PyResult<PyFit> {
    let pr = problem(
        samples,
        domain,
        p,
        levels,
        family,
        rho,
        coarse_samples,
        ridge,
    )?;
    let t0 = std::time::Instant::now();
    let acc = SingleScaleAccumulator::from_bytes(partial, &pr.basis).map_err(to_py)?;
    if acc.samples() != samples {
        return Err(invalid(format!(
            "the partial holds {} samples, not samples={samples}: merge the partials of every \
             chunk before finishing",
            acc.samples()
        )));
    }
    let (coefficients, rep) = py
        .detach(|| acc.finish(&pr.basis, pr.ridge))
        .map_err(to_py)?;
    if rep.deficient > 0 {
        return Err(invalid(format!(
            "{} single-scale directions are undetermined ({} functions without a sample): \
             give lower levels=(n, N) or fit the samples in memory with rkwave.fit",
            rep.deficient, rep.unsampled
        )));
    }
    let residual = rep.residual_rms.clone().unwrap_or_default();
    let fitted = Fit {
        active: ActiveSet::uniform(pr.basis),
        coefficients,
        levels: pr.levels,
        timings: Timings {
            kernel_s: 0.0,
            solve_s: t0.elapsed().as_secs_f64(),
        },
        solve: SolveReport::SingleScale(rep),
        fallbacks: Vec::new(),
    };
    let method: Method = pr.params.method;
    let time_s = FitSeconds {
        solve: fitted.timings.solve_s,
        total: t0.elapsed().as_secs_f64(),
        ..FitSeconds::default()
    };
    let report = FitReport::new(&fitted, samples, &method, residual, time_s);
    Ok(PyFit {
        fit: fitted,
        flat: coefficients_flat(&report),
        report: serde_json::to_string(&report).expect("plain data"),
        samples: None,
    })
}

/// Values come out as `(m,)` for one channel (the shape `rkwave.fit` gives a 1D `y`).
fn coefficients_flat(report: &FitReport) -> bool {
    report.channels == 1
}
