//! numpy in, numpy out.
//!
//! Inputs of any stride and of dtype `float64` or `float32` are accepted; anything else numpy
//! can turn into `float64` without losing information (lists, booleans, integers of up to 32
//! bits, `float16`; 64-bit integers whose values are all at most `2^53` in magnitude) is
//! converted by `numpy.asarray` once. A dtype whose values `float64` cannot hold exactly is
//! refused with its name and the explicit conversion to make ([`lossless`]): complex (the
//! imaginary part would be dropped), `longdouble` (its extra precision) and 64-bit integers
//! beyond `2^53`. A
//! `float64` input whose data the library can read in place (a contiguous vector, a column of
//! a Fortran-ordered array) is borrowed, not copied; a `float32` input or a strided one is
//! converted or gathered into `float64` once. The library's inputs are channel-major
//! (one slice per channel), so a C-ordered `(m, channels)` array with more than one channel is
//! gathered into columns: its one copy.
//!
//! Outputs are fresh `float64` arrays that take over the library's vectors without a copy
//! where the layout agrees (a single channel), or are interleaved into `(m, channels)` /
//! `(H, W, C)` once.

use std::borrow::Cow;

use numpy::ndarray::{Array2, Array3, ArrayD, ArrayViewD, Axis, Ix1, Ix2};
use numpy::{IntoPyArray, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::invalid;

/// A `float64` view of a Python array: borrowed from a `float64` array, or converted once.
pub enum Floats<'py> {
    /// A `float64` numpy array, read in place.
    Borrowed(PyReadonlyArrayDyn<'py, f64>),
    /// Converted from `float32` or another dtype.
    Owned(ArrayD<f64>),
}

impl Floats<'_> {
    /// The data as an n-dimensional view.
    pub fn view(&self) -> ArrayViewD<'_, f64> {
        match self {
            Floats::Borrowed(a) => a.as_array(),
            Floats::Owned(a) => a.view(),
        }
    }
}

/// `obj` as `float64` (module docs); `name` is the argument's name in errors.
pub fn floats<'py>(obj: &Bound<'py, PyAny>, name: &str) -> PyResult<Floats<'py>> {
    if let Ok(a) = obj.cast::<PyArrayDyn<f64>>() {
        return Ok(Floats::Borrowed(a.readonly()));
    }
    if let Ok(a) = obj.cast::<PyArrayDyn<f32>>() {
        return Ok(Floats::Owned(a.readonly().as_array().mapv(f64::from)));
    }
    let py = obj.py();
    lossless(obj, name)?;
    let kwargs = PyDict::new(py);
    kwargs.set_item("dtype", "float64")?;
    let converted = py
        .import("numpy")?
        .getattr("asarray")?
        .call((obj,), Some(&kwargs))
        .map_err(|e| {
            invalid(format!(
                "{name} must be a float64 or float32 array (or convertible to float64): {e}"
            ))
        })?;
    let a = converted
        .cast_into::<PyArrayDyn<f64>>()
        .map_err(|_| invalid(format!("{name} could not be converted to a float64 array")))?;
    Ok(Floats::Borrowed(a.readonly()))
}

/// Refuses an input whose values `float64` cannot hold exactly (module docs): numpy's
/// conversion would drop them without a word.
fn lossless(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<()> {
    let np = obj.py().import("numpy")?;
    // A list or a scalar: the dtype numpy would give it, by the same rules as an array's.
    let array = if obj.hasattr("dtype")? {
        obj.clone()
    } else {
        match np.getattr("asarray")?.call1((obj,)) {
            Ok(a) => a,
            // Ragged or otherwise unreadable: the float64 conversion names the problem.
            Err(_) => return Ok(()),
        }
    };
    let Ok(dtype) = array.getattr("dtype") else {
        return Ok(());
    };
    let kind: String = dtype.getattr("kind")?.extract()?;
    let itemsize: usize = dtype.getattr("itemsize")?.extract()?;
    let dtype_name: String = dtype.getattr("name")?.extract()?;
    let refuse = |why: &str, fix: &str| {
        Err(invalid(format!(
            "{name} has dtype {dtype_name}: {why}; {fix}"
        )))
    };
    match kind.as_str() {
        "b" | "f" if itemsize <= 8 => Ok(()),
        "i" | "u" if itemsize <= 4 => Ok(()),
        "i" | "u" => {
            // 64-bit integers: exact in float64 up to 2^53 in magnitude.
            let size: usize = array.getattr("size")?.extract()?;
            if size == 0 {
                return Ok(());
            }
            let as_float = np
                .getattr("abs")?
                .call1((array.call_method1("astype", ("float64",))?,))?;
            let largest: f64 = as_float.call_method0("max")?.extract()?;
            if largest <= 2f64.powi(53) {
                Ok(())
            } else {
                refuse(
                    &format!(
                        "its largest magnitude {largest:.0} is above 2^53, where float64 \
                         rounds integers"
                    ),
                    "scale the values or convert them to float64 yourself if the rounding is \
                     acceptable",
                )
            }
        }
        "f" => refuse(
            "float64 would drop its extra precision",
            "convert it with .astype(np.float64) if that is acceptable",
        ),
        "c" => refuse(
            "float64 would drop the imaginary part",
            "pass np.real(...) or np.abs(...) explicitly",
        ),
        // Strings, objects, dates: numpy's float64 conversion decides (and names the
        // problem where it fails).
        _ => Ok(()),
    }
}

/// The 1D data of `view` (`name` in errors): borrowed when contiguous, gathered otherwise.
pub fn vector<'a>(view: &'a ArrayViewD<'_, f64>, name: &str) -> PyResult<Cow<'a, [f64]>> {
    let v = view.view().into_dimensionality::<Ix1>().map_err(|_| {
        invalid(format!(
            "{name} must be 1-dimensional, got shape {}",
            shape(view.shape())
        ))
    })?;
    Ok(match v.to_slice() {
        Some(s) => Cow::Borrowed(s),
        None => Cow::Owned(v.to_vec()),
    })
}

/// The columns of `view`, `(m,)` as one column or `(m, k)` as `k` (`name` in errors): each
/// borrowed when contiguous (a Fortran-ordered array), gathered otherwise.
pub fn columns<'a>(view: &'a ArrayViewD<'_, f64>, name: &str) -> PyResult<Vec<Cow<'a, [f64]>>> {
    match view.ndim() {
        1 => Ok(vec![vector(view, name)?]),
        2 => {
            let v = view
                .view()
                .into_dimensionality::<Ix2>()
                .expect("2 dimensions");
            Ok((0..v.ncols())
                .map(|c| v.index_axis_move(Axis(1), c))
                .map(|c| match c.to_slice() {
                    Some(s) => Cow::Borrowed(s),
                    None => Cow::Owned(c.to_vec()),
                })
                .collect())
        }
        _ => Err(invalid(format!(
            "{name} must have shape (m,) or (m, channels), got {}",
            shape(view.shape())
        ))),
    }
}

/// A shape as Python prints it: `(3,)`, `(3, 2)`.
pub fn shape(dims: &[usize]) -> String {
    match dims {
        [one] => format!("({one},)"),
        _ => format!(
            "({})",
            dims.iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    }
}

/// Refuses a non-finite entry of `values` (`name` in errors), naming the first.
pub fn check_finite(values: &[f64], name: &str) -> PyResult<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(invalid(format!(
            "{name}[{i}] = {} is not finite: fix or remove that sample",
            values[i]
        ))),
        None => Ok(()),
    }
}

/// Per-channel vectors as `(m,)` (`flat` and one channel) or `(m, channels)`.
pub fn channels_out<'py>(
    py: Python<'py>,
    mut channels: Vec<Vec<f64>>,
    flat: bool,
) -> Bound<'py, PyAny> {
    if flat && channels.len() == 1 {
        return channels.swap_remove(0).into_pyarray(py).into_any();
    }
    let m = channels.first().map_or(0, Vec::len);
    let k = channels.len();
    Array2::from_shape_fn((m, k), |(i, c)| channels[c][i])
        .into_pyarray(py)
        .into_any()
}

/// Planar pixels (`channels[c][Y * W + X]`) as an `(H, W, C)` array.
pub fn image_out<'py>(
    py: Python<'py>,
    channels: &[Vec<f64>],
    width: usize,
    height: usize,
) -> Bound<'py, PyAny> {
    Array3::from_shape_fn((height, width, channels.len()), |(y, x, c)| {
        channels[c][y * width + x]
    })
    .into_pyarray(py)
    .into_any()
}

/// Positions `xs`, `ys` as an `(n, 2)` array.
pub fn positions_out<'py>(py: Python<'py>, xs: &[f64], ys: &[f64]) -> Bound<'py, PyAny> {
    Array2::from_shape_fn((xs.len(), 2), |(i, k)| if k == 0 { xs[i] } else { ys[i] })
        .into_pyarray(py)
        .into_any()
}
