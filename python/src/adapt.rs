//! 1D adaptive sampling with a Python oracle: `rkwave.adapt(f, domain, budget=...)`, the
//! library's refiner ([`rkwave::refine::refine`], what `rkwave adapt` runs) asking a Python
//! callable `f(x) -> float` for every sample it places. The GIL is released while the refiner
//! works and taken back for each call of `f`; an exception raised by `f` stops the refinement
//! and is raised again from `adapt`.

use std::sync::Mutex;
use std::time::Instant;

use pyo3::prelude::*;
use rkwave::refine::{
    refine, ExpressionOracle, RefineError, RoundLog, SampleOracle, SignalOracle, StopReason,
};
use rkwave::report::reconstruction::sample_residual;
use rkwave::sampling::Signal;
use serde::Serialize;

use crate::errors::{invalid, to_py, warn_all};
use crate::fit::{unix_now, FitReport, FitSeconds, PyFit};
use crate::params::{domain as domain_of, refine_params, AdaptArgs};

/// A Python callable as the refiner's oracle.
struct PythonOracle {
    f: Py<PyAny>,
    /// The first exception `f` raised (later calls return NaN without calling `f`).
    error: Mutex<Option<PyErr>>,
}

impl SampleOracle for PythonOracle {
    fn sample(&self, x: f64) -> f64 {
        let mut error = self
            .error
            .lock()
            .expect("the oracle's lock is never poisoned");
        if error.is_some() {
            return f64::NAN;
        }
        Python::attach(
            |py| match self.f.call1(py, (x,)).and_then(|v| v.extract::<f64>(py)) {
                Ok(v) => v,
                Err(e) => {
                    *error = Some(e);
                    f64::NAN
                }
            },
        )
    }
}

/// The report of `rkwave.adapt`: the fit's report and the refinement's.
#[derive(Serialize)]
struct AdaptReport {
    #[serde(flatten)]
    fit: FitReport,
    /// Why the refinement stopped.
    stop: StopReason,
    /// Depth of the base tree.
    base_depth: u32,
    /// One entry per round.
    rounds: Vec<RoundLog>,
}

/// Adaptive sampling and reconstruction of `f` on `domain`, as `rkwave adapt`: the wavelet
/// tree and the samples grow together where `f` needs detail, until the estimated RMS error
/// is below `tolerance`, the depth limit or the sample `budget`. Returns a `Fit` whose report
/// also has the rounds and the stop reason, and whose `samples` are the positions and values
/// asked for.
///
/// `f` is a Python callable `f(x: float) -> float` (called once per sample, with the GIL
/// taken for each call; an exception it raises is raised again here), a built-in signal name
/// (`"jumps"`, `"heavisine"`, ...) or an expression in `x` (`"sin(8*x) + (x > 0.6)"`).
///
/// >>> import rkwave
/// >>> g = rkwave.adapt(lambda x: 0.0 if x < 0.4 else 1.0, budget=3000, max_depth=12)
/// >>> g.report["stop"] in ("tolerance", "depth_limit", "budget")
/// True
#[pyfunction]
#[pyo3(signature = (f, domain=(0.0, 1.0), budget=100_000, *, p=3, tolerance=1e-6,
    max_depth=32, base_samples=256, seed=1, rho=2.0, theta=0.5, indicator="coefficients",
    probes=1, layout="jittered", coarse=None, base_depth=None, family=None))]
#[allow(clippy::too_many_arguments)]
pub fn adapt(
    py: Python<'_>,
    f: &Bound<'_, PyAny>,
    domain: (f64, f64),
    budget: usize,
    p: usize,
    tolerance: f64,
    max_depth: u32,
    base_samples: usize,
    seed: u64,
    rho: f64,
    theta: f64,
    indicator: &str,
    probes: usize,
    layout: &str,
    coarse: Option<u32>,
    base_depth: Option<u32>,
    family: Option<&str>,
) -> PyResult<PyFit> {
    let domain = domain_of(domain)?;
    let params = refine_params(&AdaptArgs {
        domain,
        p,
        family,
        coarse,
        tolerance,
        max_depth,
        budget,
        seed,
        base_samples,
        base_depth,
        layout,
        rho,
        theta,
        indicator,
        probes,
    })?;
    let (started, t0) = (unix_now(), Instant::now());
    let result = if let Ok(text) = f.extract::<String>() {
        // A built-in signal or an expression in x, as `rkwave adapt --signal`.
        if let Ok(signal) = text.parse::<Signal>() {
            py.detach(|| refine(&SignalOracle::new(signal, domain), &params))
        } else {
            let oracle = ExpressionOracle::parse(&text).map_err(|e| {
                invalid(format!(
                    "f: {e} (built-in signals: smooth, polynomialN, jumps, kink, cusp, blocks, \
                     bumps, heavisine, doppler)"
                ))
            })?;
            py.detach(|| refine(&oracle, &params))
        }
    } else if f.is_callable() {
        let oracle = PythonOracle {
            f: f.clone().unbind(),
            error: Mutex::new(None),
        };
        let result = py.detach(|| refine(&oracle, &params));
        if let Some(e) = oracle.error.into_inner().expect("never poisoned") {
            return Err(e);
        }
        result
    } else {
        return Err(invalid(
            "f must be a callable f(x) -> float, a built-in signal name or an expression in x",
        ));
    };
    let refinement = result.map_err(to_py::<RefineError>)?;
    let solved = t0.elapsed().as_secs_f64();
    let xs: Vec<f64> = refinement.samples.iter().map(|s| s.x).collect();
    let values: Vec<f64> = refinement.samples.iter().map(|s| s.value).collect();
    let fit = refinement.fit;
    let residual = py
        .detach(|| sample_residual(&fit, &fit.evaluator()?, &xs, &[&values]))
        .map_err(to_py)?;
    let total = t0.elapsed().as_secs_f64();
    let time_s = FitSeconds {
        kernel: fit.timings.kernel_s,
        solve: fit.timings.solve_s,
        residual: total - solved,
        total,
        started,
        finished: unix_now(),
    };
    let method = rkwave::reconstruct::Method::Global(params.solve);
    let report = AdaptReport {
        fit: FitReport::new(&fit, xs.len(), &method, residual, time_s),
        stop: refinement.stop,
        base_depth: refinement.base_depth,
        rounds: refinement.rounds,
    };
    warn_all(py, &report.fit.warnings)?;
    Ok(PyFit {
        fit,
        flat: true,
        report: serde_json::to_string(&report).expect("plain data"),
        samples: Some((xs, values)),
    })
}
