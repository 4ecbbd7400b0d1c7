//! `rkwave.partial` and `rkwave.PartialFits`: the single-scale least squares of a set of 1D
//! samples as a reduction over chunks ([`rkwave::reconstruct::stream::SingleScaleAccumulator`]),
//! for a task scheduler (`rkwave.dask.fit_chunks`) that fits chunks in separate processes.
//!
//! The banded QR triangle `R` of the rows of `K_J` (`J = N + 1`, the single-scale level of
//! `Psi(n, N)`) and `z = Q^T f` of a chunk is its partial fit; the triangle of two
//! consecutive chunks is the QR of their stacked triangles (`merge`), and the root's back
//! substitution and FWT (`finish`) give the coefficients of `rkwave.fit` on all the samples,
//! within the rounding of the QR (another merge tree rounds differently). A partial pickles
//! as its bytes ([`SingleScaleAccumulator::to_bytes`]) and the basis it belongs to.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyTuple};
use rkwave::basis::CdvBasis;
use rkwave::reconstruct::stream::SingleScaleAccumulator;
use rkwave::reconstruct::{FitParams, Levels, Method, SingleScaleSolver};
use rkwave::sampling::Domain;

use crate::arrays::{check_finite, columns, floats, vector};
use crate::errors::{invalid, to_py, warn_all};
use crate::fit::{check_values_shape, unix_now, FitReport, FitSeconds, PyFit};
use crate::params::{domain as domain_of, family};

/// What a partial fit was built for: enough to rebuild its basis in another process.
#[derive(Clone, Debug, PartialEq)]
struct Spec {
    p: usize,
    family: Option<String>,
    levels: (u32, u32),
    domain: (f64, f64),
    /// Whether the values came as `(m,)` (the fit then evaluates to `(m,)`).
    flat: bool,
}

impl Spec {
    /// The spec of these arguments and its basis.
    fn checked(
        p: usize,
        family: Option<String>,
        levels: (u32, u32),
        domain: (f64, f64),
        flat: bool,
    ) -> PyResult<(Self, CdvBasis)> {
        let spec = Self {
            p,
            family,
            levels,
            domain,
            flat,
        };
        let (basis, _) = spec.basis()?;
        Ok((spec, basis))
    }

    /// The basis `Psi(n, N)` on the domain (checked as `rkwave.fit` checks it).
    fn basis(&self) -> PyResult<(CdvBasis, Domain)> {
        let domain = domain_of(self.domain)?;
        let params = FitParams {
            p: self.p,
            family: family(self.family.as_deref())?,
            levels: Levels::Fixed {
                coarse: self.levels.0,
                fine: self.levels.1,
            },
            ..FitParams::default()
        };
        let basis = params
            .basis(self.levels.0, self.levels.1, domain)
            .map_err(to_py)?;
        Ok((basis, domain))
    }
}

/// The partial single-scale fit of a range of consecutive samples (module docs): build it
/// with `rkwave.partial`, combine with `merge`, solve with `finish`. Picklable.
#[pyclass(name = "PartialFits", module = "rkwave", frozen)]
pub struct PyPartialFits {
    spec: Spec,
    basis: CdvBasis,
    acc: SingleScaleAccumulator,
}

#[pymethods]
impl PyPartialFits {
    /// Samples accumulated (merged ones included).
    #[getter]
    fn samples(&self) -> usize {
        self.acc.samples()
    }

    /// The levels `(n, N)` of the basis.
    #[getter]
    fn levels(&self) -> (u32, u32) {
        self.spec.levels
    }

    /// A new partial fit of this one's samples followed by `later`'s (the QR of the stacked
    /// triangles); neither is changed. `later` must hold the samples that follow this one's
    /// (not in an earlier cell than its last) and belong to the same basis and channels.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 4000); y = np.sin(5 * x)
    /// >>> a = rkwave.partial(x[:1500], y[:1500], (0, 1), 3, (4, 8))
    /// >>> b = rkwave.partial(x[1500:], y[1500:], (0, 1), 3, (4, 8), start=1500)
    /// >>> a.merge(b).samples
    /// 4000
    fn merge(&self, py: Python<'_>, later: &PyPartialFits) -> PyResult<PyPartialFits> {
        if later.spec != self.spec {
            return Err(invalid(format!(
                "these partial fits cannot merge: one is for {:?}, the other for {:?}; build \
                 every partial with the same domain, p, family, levels and value shape",
                self.spec, later.spec
            )));
        }
        let (mut acc, other) = (self.acc.clone(), later.acc.clone());
        py.detach(|| acc.merge(other)).map_err(to_py)?;
        Ok(PyPartialFits {
            spec: self.spec.clone(),
            basis: self.basis.clone(),
            acc,
        })
    }

    /// The `rkwave.Fit` of all the samples accumulated (the fit `rkwave.fit` returns), with
    /// the relative `ridge` of `rkwave.fit`. Refused when the samples leave single-scale
    /// directions undetermined (the in-memory fit would lower the level or invert locally):
    /// give lower levels.
    ///
    /// >>> import numpy as np, rkwave
    /// >>> x = np.linspace(0, 1, 4000)
    /// >>> f = rkwave.partial(x, x**2, (0, 1), 3, (4, 8)).finish()
    /// >>> bool(abs(f(np.array([0.5]))[0] - 0.25) < 1e-9)
    /// True
    #[pyo3(signature = (ridge=0.0))]
    fn finish(&self, py: Python<'_>, ridge: f64) -> PyResult<PyFit> {
        if !(ridge.is_finite() && (0.0..1.0).contains(&ridge)) {
            return Err(invalid(format!(
                "ridge={ridge} must be in [0, 1), e.g. 1e-16"
            )));
        }
        let (acc, basis) = (self.acc.clone(), &self.basis);
        let m = acc.samples();
        let (started, t0) = (unix_now(), std::time::Instant::now());
        let fitted = py.detach(|| acc.finish_fit(basis, ridge)).map_err(to_py)?;
        let total = t0.elapsed().as_secs_f64();
        let residual = match &fitted.solve {
            rkwave::reconstruct::SolveReport::SingleScale(r) => {
                r.residual_rms.clone().unwrap_or_default()
            }
            _ => Vec::new(),
        };
        let time_s = FitSeconds {
            kernel: 0.0,
            solve: fitted.timings.solve_s,
            residual: 0.0,
            total,
            started,
            finished: unix_now(),
        };
        let method = Method::SingleScale {
            ridge,
            solver: SingleScaleSolver::Qr,
        };
        let report = FitReport::new(&fitted, m, &method, residual, time_s);
        warn_all(py, &report.warnings)?;
        Ok(PyFit {
            fit: fitted,
            flat: self.spec.flat,
            report: serde_json::to_string(&report).expect("plain data"),
            samples: None,
        })
    }

    /// Pickling: the spec and the accumulator's bytes, rebuilt by `rkwave._rkwave._partial_from_state`.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let rebuild = py
            .import("rkwave._rkwave")?
            .getattr("_partial_from_state")?;
        let s = &self.spec;
        let state = (
            s.p,
            s.family.clone(),
            s.levels,
            s.domain,
            s.flat,
            PyBytes::new(py, &self.acc.to_bytes()),
        );
        PyTuple::new(py, [rebuild, state.into_pyobject(py)?.into_any()])
    }

    fn __repr__(&self) -> String {
        format!(
            "rkwave.PartialFits(p={}, levels={:?}, domain={:?}, samples={})",
            self.spec.p,
            self.spec.levels,
            self.spec.domain,
            self.acc.samples()
        )
    }
}

/// Rebuilds a pickled partial fit (`PartialFits.__reduce__`).
#[pyfunction]
#[allow(clippy::type_complexity)]
pub fn _partial_from_state(
    py: Python<'_>,
    p: usize,
    family: Option<String>,
    levels: (u32, u32),
    domain: (f64, f64),
    flat: bool,
    bytes: &[u8],
) -> PyResult<PyPartialFits> {
    let (spec, basis) = Spec::checked(p, family, levels, domain, flat)?;
    let acc = py
        .detach(|| SingleScaleAccumulator::from_bytes(bytes, &basis))
        .map_err(to_py)?;
    Ok(PyPartialFits { spec, basis, acc })
}

/// The partial single-scale fit of one chunk of samples sorted by `x`: `y` is `(m,)` or
/// `(m, channels)`, `domain=(a, b)` and `levels=(n, N)` are those of the whole set (every
/// chunk the same), `start` the 0-based index of the chunk's first sample in the whole set
/// (errors name whole-set rows). Merge the partials of consecutive chunks in order and
/// `finish` the result: the `rkwave.fit(x, y, domain, p, levels)` of all the samples.
///
/// >>> import numpy as np, rkwave
/// >>> x = np.linspace(0, 1, 4000)
/// >>> rkwave.partial(x, np.sin(x), (0, 1), p=3, levels=(4, 8)).samples
/// 4000
#[pyfunction]
#[pyo3(signature = (x, y, domain, p=3, levels=(4, 8), start=0, *, family=None))]
#[allow(clippy::too_many_arguments)]
pub fn partial(
    py: Python<'_>,
    x: &Bound<'_, PyAny>,
    y: &Bound<'_, PyAny>,
    domain: (f64, f64),
    p: usize,
    levels: (u32, u32),
    start: usize,
    family: Option<String>,
) -> PyResult<PyPartialFits> {
    let xd = floats(x, "x")?;
    let xv = xd.view();
    let xs = vector(&xv, "x")?;
    check_finite(&xs, "x")?;
    let yd = floats(y, "y")?;
    let yv = yd.view();
    let flat = yv.ndim() == 1;
    let ys = columns(&yv, "y")?;
    check_values_shape(&ys, yv.shape(), xs.len())?;
    let (spec, basis) = Spec::checked(p, family, levels, domain, flat)?;
    let channels: Vec<&[f64]> = ys.iter().map(|c| c.as_ref()).collect();
    let acc = py
        .detach(|| {
            let mut acc = SingleScaleAccumulator::new(&basis, channels.len()).starting_at(start);
            acc.add_chunk(&xs, &channels).map(|_| acc)
        })
        .map_err(to_py)?;
    Ok(PyPartialFits { spec, basis, acc })
}

/// The automatic levels `(n, N)` of `rkwave.fit` for `samples` samples (from the count alone:
/// the rule `rkwave.fit` starts from, before any level it lowers on the samples' layout);
/// what `rkwave.dask.fit_chunks` uses when no levels are given.
///
/// >>> import rkwave
/// >>> n, N = rkwave.auto_levels(1_000_000, p=3)
/// >>> n <= N
/// True
#[pyfunction]
#[pyo3(signature = (samples, p=3, *, rho=2.0, coarse_samples=256.0))]
pub fn auto_levels(
    samples: usize,
    p: usize,
    rho: f64,
    coarse_samples: f64,
) -> PyResult<(u32, u32)> {
    let params = crate::params::fit_params(&crate::params::FitArgs {
        p,
        family: None,
        levels: None,
        method: "single",
        rho,
        coarse_samples,
        rings: 1,
        solver: "svd",
        cutoff: 1e-12,
        ridge: 0.0,
        factorization: "qr",
    })?;
    let l = rkwave::reconstruct::choose_levels(samples, &params);
    Ok((l.coarse, l.fine))
}
