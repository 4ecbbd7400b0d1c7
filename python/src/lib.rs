//! `import rkwave`: the engine's entry points for Python, numpy in and out (PyO3 + rust-numpy).
//!
//! Each function calls the library entry point the command line calls for the same work, so
//! results are bit for bit those of the CLI and the Rust library on the same input:
//!
//! | Python | library | command line |
//! |---|---|---|
//! | `fit(x, y, ...)` → `Fit` | `reconstruct::fit` | `rkwave reconstruct` |
//! | `local_vs_global(...)` | `report::local_vs_global` | `rkwave report` |
//! | `reconstruct_image(xy, values, resolution, ...)` | `image::reconstruct` | `rkwave reconstruct --dim 2` |
//! | `Plan(...)`, `positions`, `add`, `image`, `save`, `load` | `image::adaptive::protocol::PlanState` | `rkwave plan`, `reconstruct --dim 2 --state` |
//! | `adapt(f, domain, ...)` | `refine::refine` | `rkwave adapt` |
//!
//! The GIL is released during every computation (`Python::detach`). Errors map by kind
//! ([`errors`]); conversions of arrays are in [`arrays`]; every parameter struct is built in
//! [`params`].

#![deny(missing_docs)]

mod adapt;
mod arrays;
mod errors;
mod fit;
mod image;
mod params;
mod plan;
mod report;

use pyo3::prelude::*;

/// The compiled part of the `rkwave` package (re-exported by `rkwave/__init__.py`).
#[pymodule]
fn _rkwave(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(fit::local_vs_global, m)?)?;
    m.add_function(wrap_pyfunction!(image::reconstruct_image, m)?)?;
    m.add_function(wrap_pyfunction!(adapt::adapt, m)?)?;
    m.add_class::<fit::PyFit>()?;
    m.add_class::<plan::PyPlan>()?;
    m.add("RkwaveError", py.get_type::<errors::RkwaveError>())?;
    m.add("ResourceLimitError", py.get_type::<errors::ResourceLimitError>())?;
    m.add("RkwaveWarning", py.get_type::<errors::RkwaveWarning>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
