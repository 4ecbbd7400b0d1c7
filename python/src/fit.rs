//! 1D: `rkwave.fit` (scattered samples to `f(x) = sum_a c_a Psi_a(x)`, the library's
//! [`rkwave::reconstruct::fit`], the entry point `rkwave reconstruct` calls), the [`PyFit`]
//! it returns, and the local-vs-global report ([`rkwave::report::local_vs_global`], what
//! `rkwave report` prints).

use std::borrow::Cow;
use std::time::Instant;

use pyo3::prelude::*;
use pyo3::types::PyAny;
use rkwave::reconstruct::{fit as fit_samples, Fit, Method, SolveReport};
use rkwave::report::local_vs_global as report_local_vs_global;
use rkwave::report::reconstruction::{method_name, sample_residual, FallbackNote};
use serde::Serialize;

use crate::arrays::{channels_out, check_finite, columns, floats, vector};
use crate::errors::{invalid, to_py, warn_all};
use crate::params::{domain as domain_of, fit_params, report_setting, FitArgs};
use crate::report::to_dict;

/// Seconds per stage of `rkwave.fit`.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct FitSeconds {
    /// Building `K` (0 for the single-scale path, which accumulates the normal equations in
    /// its solve).
    pub kernel: f64,
    /// The solve.
    pub solve: f64,
    /// The residual at the samples (free when the QR found it).
    pub residual: f64,
    /// Everything inside the library call, conversion excluded.
    pub total: f64,
    /// When the library call started, in seconds since the Unix epoch (`time.time()`'s
    /// clock): with `finished`, shows whether calls from several threads overlapped.
    pub started: f64,
    /// When the library call finished (same clock).
    pub finished: f64,
}

/// Seconds since the Unix epoch.
pub fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// The report of a 1D fit: the fields of `rkwave reconstruct --json` that describe the fit.
#[derive(Clone, Debug, Serialize)]
pub struct FitReport {
    /// Samples `m`.
    pub samples: usize,
    /// Channels.
    pub channels: usize,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// Vanishing moments.
    pub p: usize,
    /// `db` or `sym`.
    pub family: &'static str,
    /// The method requested.
    pub method: &'static str,
    /// Basis functions `P`.
    pub functions: usize,
    /// Coarse level `n`.
    pub coarse: u32,
    /// Finest level `N`.
    pub fine: u32,
    /// `m / P`.
    pub oversampling: f64,
    /// RMS residual at the samples, per channel.
    pub residual_rms: Vec<f64>,
    /// Seconds per stage.
    pub time_s: FitSeconds,
    /// The solve's own report.
    pub solve: SolveReport,
    /// Every departure from the requested levels or method, in the order taken.
    pub fallbacks: Vec<FallbackNote>,
    /// Every fallback and warning, one sentence each (also issued as `RkwaveWarning`).
    pub warnings: Vec<String>,
}

impl FitReport {
    pub fn new(
        fit: &Fit,
        samples: usize,
        method: &Method,
        residual_rms: Vec<f64>,
        time_s: FitSeconds,
    ) -> Self {
        let basis = fit.active.basis();
        Self {
            samples,
            channels: fit.coefficients.len(),
            domain: [basis.domain().a(), basis.domain().b()],
            p: basis.p(),
            family: basis.bank().family().short_name(),
            method: method_name(method),
            functions: fit.active.len(),
            coarse: fit.levels.coarse,
            fine: fit.levels.fine,
            oversampling: fit.levels.oversampling,
            residual_rms,
            time_s,
            solve: fit.solve.clone(),
            fallbacks: FallbackNote::all(&fit.fallbacks),
            warnings: fit.warnings(),
        }
    }
}

/// A fitted reconstruction `f(x) = sum_a c_a Psi_a(x)`: call it (or `evaluate`) at any
/// positions in its domain.
#[pyclass(name = "Fit", module = "rkwave", frozen)]
pub struct PyFit {
    pub(crate) fit: Fit,
    /// Whether values come out as `(m,)` (a 1D `y`) rather than `(m, channels)`.
    pub(crate) flat: bool,
    /// The report, as JSON text (turned into a dict on each access).
    pub(crate) report: String,
    /// The samples of an adaptive run (`rkwave.adapt`): positions and values.
    pub(crate) samples: Option<(Vec<f64>, Vec<f64>)>,
}

#[pymethods]
impl PyFit {
    /// The reconstruction at `x` (any shape of positions inside the domain, float32 or
    /// float64): `(m,)` for a single-channel fit made from a 1D `y`, else `(m, channels)`.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 500); f = rkwave.fit(x, x**2)
    /// >>> bool(abs(f(np.array([0.5]))[0] - 0.25) < 1e-9)
    /// True
    fn __call__<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        self.evaluate(py, x)
    }

    /// Same as calling the fit: the reconstruction at the positions `x`.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 500); f = rkwave.fit(x, np.c_[x, 1 - x])
    /// >>> f.evaluate(np.array([0.25, 0.75])).shape
    /// (2, 2)
    fn evaluate<'py>(&self, py: Python<'py>, x: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let data = floats(x, "x")?;
        let view = data.view();
        let flat: Cow<'_, [f64]> = match view.as_slice_memory_order() {
            Some(s) if view.is_standard_layout() => Cow::Borrowed(s),
            _ => Cow::Owned(view.iter().copied().collect()),
        };
        check_finite(&flat, "x")?;
        let fit = &self.fit;
        let values = py.detach(|| fit.evaluate(&flat)).map_err(to_py)?;
        let out = channels_out(py, values, self.flat);
        if view.ndim() == 1 || !self.flat || fit.coefficients.len() != 1 {
            return Ok(out);
        }
        // A single channel keeps the shape of the positions.
        out.call_method1("reshape", (view.shape().to_vec(),))
    }

    /// The coefficients `c_a`, one per active basis function: `(P,)` for a 1D `y`, else
    /// `(P, channels)`.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 500); f = rkwave.fit(x, np.sin(x))
    /// >>> f.coefficients.shape == (f.report["functions"],)
    /// True
    #[getter]
    fn coefficients<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        channels_out(py, self.fit.coefficients.clone(), self.flat)
    }

    /// Global indices of the active basis functions, in the order of `coefficients`.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 500); f = rkwave.fit(x, x)
    /// >>> len(f.indices) == len(f.coefficients)
    /// True
    #[getter]
    fn indices(&self) -> Vec<usize> {
        self.fit.active.indices().to_vec()
    }

    /// The levels used, `(n, N)`: coarse scaling level and finest wavelet level.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> rkwave.fit(np.linspace(0, 1, 500), np.zeros(500), levels=(3, 6)).levels
    /// (3, 6)
    #[getter]
    fn levels(&self) -> (u32, u32) {
        (self.fit.levels.coarse, self.fit.levels.fine)
    }

    /// The domain `(a, b)`.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> rkwave.fit(np.linspace(-1, 1, 500), np.zeros(500)).domain
    /// (-1.0, 1.0)
    #[getter]
    fn domain(&self) -> (f64, f64) {
        let d = self.fit.active.basis().domain();
        (d.a(), d.b())
    }

    /// What the fit did, as a plain dict: levels, functions, residual RMS per channel, the
    /// solve's report, fallbacks, warnings and seconds per stage (the fields of
    /// `rkwave reconstruct --json`; for `rkwave.adapt` also its rounds and stop reason).
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 500); r = rkwave.fit(x, x**2).report
    /// >>> r["method"], r["warnings"]
    /// ('single', [])
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        to_dict(py, &self.report)
    }

    /// The samples of an adaptive run (`rkwave.adapt`) as `(m, 2)`: position, value; `None`
    /// for a fit of given samples.
    ///
    /// >>> import rkwave
    /// >>> rkwave.adapt(lambda x: x * x, budget=2000, tolerance=1e-6).samples.shape[1]
    /// 2
    #[getter]
    fn samples<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.samples
            .as_ref()
            .map(|(x, v)| crate::arrays::positions_out(py, x, v))
    }

    fn __repr__(&self) -> String {
        format!(
            "rkwave.Fit(p={}, levels={:?}, functions={}, channels={}, domain={:?})",
            self.fit.active.basis().p(),
            self.levels(),
            self.fit.active.len(),
            self.fit.coefficients.len(),
            self.domain()
        )
    }
}

/// Checks that the columns `ys` of `y` (shape `shape`) hold one value per position of the
/// `m` in `x`.
pub fn check_values_shape(ys: &[Cow<'_, [f64]>], shape: &[usize], m: usize) -> PyResult<()> {
    if ys.first().is_some_and(|c| c.len() != m) || ys.is_empty() {
        return Err(invalid(format!(
            "y has shape {} but x has {m} samples: give y as (m,) or (m, channels) with m = {m}",
            crate::arrays::shape(shape),
        )));
    }
    Ok(())
}

/// The domain of the samples when none is given: `[min x, max x]`, as `rkwave reconstruct`.
fn sample_domain(xs: &[f64]) -> PyResult<rkwave::sampling::Domain> {
    let (a, b) = xs
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if xs.is_empty() {
        return Err(invalid("x is empty: give at least one sample"));
    }
    if a == b {
        return Err(invalid(format!(
            "all samples sit at x = {}: give domain=(a, b) explicitly",
            rkwave::norms::show(a)
        )));
    }
    domain_of((a, b)).map_err(|e| {
        invalid(format!(
            "the samples span [{}, {}], which is no usable domain ({e}): give domain=(a, b)",
            rkwave::norms::show(a),
            rkwave::norms::show(b)
        ))
    })
}

/// Levels as given from Python: `None` / `"auto"` or `(n, N)`.
fn levels_arg(levels: Option<&Bound<'_, PyAny>>) -> PyResult<Option<(u32, u32)>> {
    let Some(obj) = levels else { return Ok(None) };
    if let Ok(s) = obj.extract::<String>() {
        return if s == "auto" {
            Ok(None)
        } else {
            Err(invalid(format!(
                "levels={s:?} is neither \"auto\" nor a pair (n, N) such as (4, 9)"
            )))
        };
    }
    obj.extract::<(u32, u32)>()
        .map(Some)
        .map_err(|_| invalid("levels must be \"auto\" or a pair of levels (n, N) such as (4, 9)"))
}

/// Fits scattered samples `y` at positions `x` by least squares in a CDV wavelet basis
/// `Psi(n, N)` on `domain` (default: `[min x, max x]`), as `rkwave reconstruct`.
///
/// `y` is `(m,)` or `(m, channels)`. `p` (1..=10) sets the vanishing moments, `levels` is
/// `"auto"` (from the samples and `rho`) or `(n, N)`, `method` is `"single"` (global least
/// squares through the single-scale basis, the default), `"local"` (local inversion, knobs
/// `rings`, `solver`, `cutoff`), `"global"` (sparse least squares) or `"dense"` (SVD
/// pseudo-inverse, small problems). Fallbacks are issued as `RkwaveWarning` and listed in
/// `Fit.report`.
///
/// >>> import numpy as np, rkwave
/// >>> x = np.random.default_rng(7).uniform(0, 1, 2000)
/// >>> f = rkwave.fit(x, x**2, domain=(0, 1), p=3)
/// >>> bool(abs(f(np.array([0.3]))[0] - 0.09) < 1e-9)
/// True
#[pyfunction]
#[pyo3(signature = (x, y, domain=None, p=3, levels=None, method="single", *, family=None,
    rho=2.0, coarse_samples=256.0, rings=1, solver="svd", cutoff=1e-12, ridge=0.0,
    factorization="qr"))]
#[allow(clippy::too_many_arguments)]
pub fn fit<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    domain: Option<(f64, f64)>,
    p: usize,
    levels: Option<&Bound<'py, PyAny>>,
    method: &str,
    family: Option<&str>,
    rho: f64,
    coarse_samples: f64,
    rings: usize,
    solver: &str,
    cutoff: f64,
    ridge: f64,
    factorization: &str,
) -> PyResult<PyFit> {
    let params = fit_params(&FitArgs {
        p,
        family,
        levels: levels_arg(levels)?,
        method,
        rho,
        coarse_samples,
        rings,
        solver,
        cutoff,
        ridge,
        factorization,
    })?;
    let xd = floats(x, "x")?;
    let xv = xd.view();
    let xs = vector(&xv, "x")?;
    check_finite(&xs, "x")?;
    let yd = floats(y, "y")?;
    let yv = yd.view();
    let flat = yv.ndim() == 1;
    let ys = columns(&yv, "y")?;
    check_values_shape(&ys, yv.shape(), xs.len())?;
    let domain = match domain {
        Some(ab) => domain_of(ab)?,
        None => sample_domain(&xs)?,
    };
    let channels: Vec<&[f64]> = ys.iter().map(|c| c.as_ref()).collect();
    let (fitted, residual, seconds) = py
        .detach(|| {
            let (started, t0) = (unix_now(), Instant::now());
            let fitted = fit_samples(&xs, &channels, domain, &params)?;
            let solved = t0.elapsed().as_secs_f64();
            let residual = sample_residual(&fitted, &fitted.evaluator()?, &xs, &channels)?;
            let seconds = (solved, t0.elapsed().as_secs_f64(), started, unix_now());
            Ok((fitted, residual, seconds))
        })
        .map_err(to_py::<rkwave::reconstruct::ReconstructError>)?;
    let time_s = FitSeconds {
        kernel: fitted.timings.kernel_s,
        solve: fitted.timings.solve_s,
        residual: seconds.1 - seconds.0,
        total: seconds.1,
        started: seconds.2,
        finished: seconds.3,
    };
    let report = FitReport::new(&fitted, xs.len(), &params.method, residual, time_s);
    warn_all(py, &report.warnings)?;
    Ok(PyFit {
        fit: fitted,
        flat,
        report: serde_json::to_string(&report).expect("plain data"),
        samples: None,
    })
}

/// The local inversion against the global pseudo-inverse on a test signal (docs/design.md
/// §5), as a dict: the fields `rkwave report --json` prints.
///
/// >>> import rkwave
/// >>> r = rkwave.local_vs_global(p=3, fine=6, samples=512)
/// >>> r["functions"], r["reference"]
/// (128, 'dense_pinv')
#[pyfunction]
#[pyo3(signature = (p=3, fine=8, coarse=None, samples=1024, layout="uniform", seed=1,
    signal="smooth", rings=1, solver="svd", cutoff=1e-12, grid=8192, family=None))]
#[allow(clippy::too_many_arguments)]
pub fn local_vs_global<'py>(
    py: Python<'py>,
    p: usize,
    fine: u32,
    coarse: Option<u32>,
    samples: usize,
    layout: &str,
    seed: u64,
    signal: &str,
    rings: usize,
    solver: &str,
    cutoff: f64,
    grid: usize,
    family: Option<&str>,
) -> PyResult<Bound<'py, PyAny>> {
    let setting = report_setting(
        p, family, coarse, fine, samples, layout, seed, signal, rings, solver, cutoff, grid,
    )?;
    let report = py
        .detach(|| report_local_vs_global(&setting))
        .map_err(to_py)?;
    to_dict(py, &serde_json::to_string(&report).expect("plain data"))
}
