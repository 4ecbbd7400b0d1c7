//! Reports as plain Python dicts: the library's typed reports serialise to JSON (the same
//! text `--json` prints) and Python's `json` turns that into dicts, lists and numbers.

use pyo3::prelude::*;

/// The JSON text `json` as Python objects.
pub fn to_dict<'py>(py: Python<'py>, json: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.getattr("loads")?.call1((json,))
}
