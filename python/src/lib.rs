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
//! | `Plan(...)`, `positions`, `add`, `image`, `save`, `load` | `image::job::{PlanStart, PlanRound, PlanFinal}` on `image::plan::PlanState` | `rkwave plan`, `reconstruct --dim 2 --state` |
//! | `adapt(f, domain, ...)` | `refine::refine` | `rkwave adapt` |
//! | `partial(...)` → `PartialFits` (`merge`, `finish`), `auto_levels` | `reconstruct::stream::SingleScaleAccumulator` | `rkwave reconstruct --stream` |
//! | `TileGeometry(...)`, `fit_tile(...)` | `image::tiles::fit_tile` | `rkwave reconstruct --dim 2 --tile` |
//! | `TiledPlanRounds(...)`, `tiled_plan_band(...)`, `HeldBand` (`rkwave.dask.TiledPlan`) | `image::job::tiled_plan::{HeldBandTask, BandedRound}` | `rkwave plan --tile` |
//!
//! The GIL is released during every computation (`Python::detach`). Errors map by kind
//! ([`errors`]); conversions of arrays are in [`arrays`]; every parameter struct is built in
//! [`params`].

#![deny(missing_docs)]

mod adapt;
mod arrays;
mod dask_plan;
mod errors;
mod fit;
mod image;
mod params;
mod plan;
mod report;
mod stream;
mod tiled_plan;
mod tiles;

use pyo3::prelude::*;

/// Sets the memory a request may use (as the command line's `--memory-limit`): bytes as an
/// int, or a size such as `"4G"`; `None` restores the default (3/4 of the machine's memory).
/// Larger requests raise `ResourceLimitError` (a `MemoryError`) before allocating.
///
/// >>> import rkwave
/// >>> rkwave.set_memory_limit("8G"); rkwave.set_memory_limit(None)
#[pyfunction]
#[pyo3(signature = (limit))]
fn set_memory_limit(limit: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
    let bytes = match limit {
        None => None,
        Some(obj) => Some(match obj.extract::<u64>() {
            Ok(b) => b,
            Err(_) => {
                let text: String = obj.extract().map_err(|_| {
                    errors::invalid("limit must be bytes (int), a size such as \"4G\", or None")
                })?;
                rkwave::resources::parse_size(&text).map_err(errors::to_py)?
            }
        }),
    };
    rkwave::resources::set_memory_limit(bytes);
    Ok(())
}

/// The compiled part of the `rkwave` package (re-exported by `rkwave/__init__.py`).
#[pymodule]
fn _rkwave(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(fit::local_vs_global, m)?)?;
    m.add_function(wrap_pyfunction!(image::reconstruct_image, m)?)?;
    m.add_function(wrap_pyfunction!(adapt::adapt, m)?)?;
    m.add_function(wrap_pyfunction!(set_memory_limit, m)?)?;
    m.add_function(wrap_pyfunction!(stream::partial, m)?)?;
    m.add_function(wrap_pyfunction!(stream::auto_levels, m)?)?;
    m.add_function(wrap_pyfunction!(stream::_partial_from_state, m)?)?;
    m.add_function(wrap_pyfunction!(tiles::fit_tile, m)?)?;
    m.add_class::<stream::PyPartialFits>()?;
    m.add_class::<tiles::PyTileGeometry>()?;
    m.add_class::<fit::PyFit>()?;
    m.add_class::<plan::PyPlan>()?;
    m.add_class::<dask_plan::PyTiledPlanRounds>()?;
    m.add_class::<dask_plan::PyPendingRound>()?;
    m.add_class::<dask_plan::PyHeldBand>()?;
    m.add_function(wrap_pyfunction!(dask_plan::_held_band_from_bytes, m)?)?;
    m.add_function(wrap_pyfunction!(dask_plan::tiled_plan_band, m)?)?;
    m.add_function(wrap_pyfunction!(dask_plan::tiled_plan_final_band, m)?)?;
    m.add("RkwaveError", py.get_type::<errors::RkwaveError>())?;
    m.add(
        "ResourceLimitError",
        py.get_type::<errors::ResourceLimitError>(),
    )?;
    m.add("RkwaveWarning", py.get_type::<errors::RkwaveWarning>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
