//! The image plane: `rkwave.reconstruct_image` (scattered samples `(x_i, y_i, f_i)` in pixel
//! units to an `(H, W, C)` image by the library's [`rkwave::image::reconstruct`], the entry
//! point `rkwave reconstruct --dim 2` calls): the wavelet fit, its local inversion, or a film
//! filter on the same samples.

use std::path::Path;
use std::time::Instant;

use pyo3::prelude::*;
use rkwave::error::{spelled, Param};
use rkwave::image::filters::FilmFilterKind;
use rkwave::image::job::{FitOptions, ImageParams, JobError, UniformJob};
use rkwave::image::report::FileReconstructionReport;
use rkwave::image::{
    split_finite, DroppedSamples, ImageMethod, ImagePlane, ImageSamples, NonFinitePolicy,
};

use crate::arrays::{columns, floats, image_out};
use crate::errors::{invalid, keyword, to_py, warn_all};
use crate::report::to_dict;

/// The method from `method` and `filter` (a film filter by name: `box`, `triangle`,
/// `gaussian`, `mitchell`, `lanczos`).
fn method_of(method: &str, filter: Option<&str>) -> PyResult<ImageMethod> {
    let chosen: ImageMethod = method
        .parse()
        .map_err(|e| invalid(format!("method: {e}")))?;
    match filter {
        None => Ok(chosen),
        Some(name) => {
            let kind: FilmFilterKind = name.parse().map_err(|e| invalid(format!("filter: {e}")))?;
            match chosen {
                ImageMethod::Wavelet => Ok(ImageMethod::Film(kind)),
                ImageMethod::Film(k) if k == kind => Ok(chosen),
                other => Err(invalid(format!(
                    "method={:?} and filter={name:?} ask for two methods: give one",
                    other.name()
                ))),
            }
        }
    }
}

/// The image plane `(W, H)`.
pub fn plane_of(resolution: (usize, usize)) -> PyResult<ImagePlane> {
    ImagePlane::new(resolution.0, resolution.1).map_err(to_py)
}

/// Checked samples on `plane` from `xy` `(m, 2)` and `values` `(m,)` or `(m, channels)`,
/// the samples with a non-finite value handled by `policy`: the finite ones and those
/// dropped.
pub fn samples_of(
    plane: ImagePlane,
    xy: &Bound<'_, PyAny>,
    values: &Bound<'_, PyAny>,
    policy: NonFinitePolicy,
) -> PyResult<(ImageSamples, DroppedSamples)> {
    let xyd = floats(xy, "xy")?;
    let xyv = xyd.view();
    let pos = columns(&xyv, "xy")?;
    if xyv.ndim() != 2 || pos.len() != 2 {
        return Err(invalid(format!(
            "xy must have shape (m, 2) (x, y in pixel units), got {}",
            crate::arrays::shape(xyv.shape())
        )));
    }
    let vd = floats(values, "values")?;
    let vv = vd.view();
    let vals = columns(&vv, "values")?;
    if vv.shape()[0] != pos[0].len() {
        return Err(invalid(format!(
            "values has shape {} but xy has {} samples: give values as (m,) or (m, channels) \
             with m = {}",
            crate::arrays::shape(vv.shape()),
            pos[0].len(),
            pos[0].len()
        )));
    }
    let mut pos = pos.into_iter().map(|c| c.into_owned());
    let (xs, ys) = (pos.next().expect("x"), pos.next().expect("y"));
    if let Some(i) = xs
        .iter()
        .zip(&ys)
        .position(|(x, y)| !(x.is_finite() && y.is_finite()))
    {
        return Err(invalid(format!(
            "sample {i}: position ({}, {}) is not finite: fix or remove that sample",
            xs[i], ys[i]
        )));
    }
    split_finite(
        plane,
        xs,
        ys,
        vals.into_iter().map(|c| c.into_owned()).collect(),
        policy,
    )
    .map_err(to_py)
}

/// The number of samples and channels of `xy` `(m, 2)` and `values` `(m,)` or `(m, C)` from
/// their shapes alone (`None` when either is not an array), for the memory check before
/// anything is converted.
fn sizes(xy: &Bound<'_, PyAny>, values: &Bound<'_, PyAny>) -> Option<(usize, usize)> {
    let shape = |a: &Bound<'_, PyAny>| a.getattr("shape").ok()?.extract::<Vec<usize>>().ok();
    let (xy, values) = (shape(xy)?, shape(values)?);
    let m = *xy.first()?;
    let channels = match values.as_slice() {
        [_] => 1,
        [_, c] => *c,
        _ => return None,
    };
    Some((m, channels))
}

/// Reconstructs a `W x H` image from scattered samples on the image plane, as `rkwave
/// reconstruct --dim 2`: returns the `(H, W, C)` float64 pixels and a report dict.
///
/// `xy` is `(m, 2)` in pixel units (pixel `(X, Y)` covers `[X, X+1] x [Y, Y+1]`), `values`
/// `(m,)` or `(m, C)` with 1 to 4 channels. `method` is `"wavelet"` (the least-squares fit,
/// box-integrated over each pixel), `"local"` (its local inversion), or a film filter;
/// `filter="gaussian"` (or `box`, `triangle`, `mitchell`, `lanczos`) splats the same samples
/// through that film filter for comparison. `pixels` is the pixel estimate of the wavelet
/// path, as the command line's `--pixels`: `"auto"` (per pixel the candidate of least estimated
/// risk against the mean of its samples: the mean, the films by SURE, shrinkage of the pixel
/// means, mixtures; every pixel within the range of the samples around it; falls back to the fit, with a warning, where a pixel has no sample or
/// most have one), `"fit"`, `"fit-clamped"`, `"box"` or `"shrunk"`; by default `"auto"`,
/// or `"fit"` (with a warning) when `p`, `rho`, `ridge`, `smoothing` or `method="local"` is
/// given, as on the command line. `rho` (samples per tensor function, default 4), `ridge`
/// (relative, in `[0, 1)`, default 1e-9) and `smoothing` (`>= 0`, default 0) set the fit as
/// `--rho`, `--ridge` and `--smoothing` do. The request is validated and its memory estimated
/// by the same library call as the command line's, before the arrays are converted: above
/// the limit (`set_memory_limit`) it raises `ResourceLimitError` (a `MemoryError`).
/// A value that is NaN or infinite is refused (the error names the count and the first
/// sample); `drop_nonfinite=True` drops those samples and counts them in the report
/// (`nonfinite`) and a warning.
///
/// >>> import numpy as np, rkwave
/// >>> xy = np.random.default_rng(3).uniform(0, 16, (4 * 16 * 16, 2))
/// >>> f = np.c_[xy, xy[:, :1]] / 16
/// >>> img, rep = rkwave.reconstruct_image(xy, f, resolution=(16, 16), pixels="fit")
/// >>> img.shape, rep["method"]
/// ((16, 16, 3), 'wavelet')
/// >>> rkwave.reconstruct_image(xy, xy[:, 0], resolution=(16, 16), filter="gaussian")[1]["method"]
/// 'gaussian'
#[pyfunction]
#[pyo3(signature = (xy, values, resolution, p=None, method="wavelet", filter=None, *,
    pixels=None, rho=None, ridge=None, smoothing=None, drop_nonfinite=false))]
#[allow(clippy::too_many_arguments)]
pub fn reconstruct_image<'py>(
    py: Python<'py>,
    xy: &Bound<'py, PyAny>,
    values: &Bound<'py, PyAny>,
    resolution: (usize, usize),
    p: Option<usize>,
    method: &str,
    filter: Option<&str>,
    pixels: Option<&str>,
    rho: Option<f64>,
    ridge: Option<f64>,
    smoothing: Option<f64>,
    drop_nonfinite: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let params = ImageParams {
        method: method_of(method, filter)?,
        fit: FitOptions {
            p,
            rho,
            ridge,
            smoothing,
        },
        pixels: pixels
            .map(|name| name.parse().map_err(|e| invalid(format!("pixels: {e}"))))
            .transpose()?,
        ..ImageParams::default()
    };
    let plane = plane_of(resolution)?;
    // The library decides and refuses, as for `rkwave reconstruct --dim 2`; the memory is
    // checked from the arrays' shapes before they are converted.
    let job = UniformJob::new(plane, &params).map_err(|e| match e {
        // The film was asked for by `filter=`: name the keyword given.
        JobError::Conflict {
            second: Param::Method,
            ..
        } if filter.is_some() => invalid(
            "pixels= is the estimate of the wavelet path; a film filter splats the samples \
             itself: drop pixels= or filter=",
        ),
        e => to_py(e),
    })?;
    if let Some((m, channels)) = sizes(xy, values) {
        job.check_memory(channels.max(1), m).map_err(to_py)?;
    }
    let t0 = Instant::now();
    let (samples, dropped) =
        samples_of(plane, xy, values, NonFinitePolicy::dropping(drop_nonfinite))?;
    let convert_s = t0.elapsed().as_secs_f64();
    let out = py.detach(|| job.run(&samples)).map_err(to_py)?;
    let (done, method) = (out.reconstruction, out.method);
    // The report of `rkwave reconstruct --dim 2 --json`; the samples came from memory, and
    // "read" is checking and converting them.
    let memory = Path::new("<numpy>");
    let total = t0.elapsed().as_secs_f64();
    let mut report = FileReconstructionReport::new(
        memory,
        memory,
        plane,
        &samples,
        method,
        job.wavelet().p,
        &done,
        convert_s,
        0.0,
        total,
    );
    if let Some(estimated) = out.estimate {
        report = report.with_pixels(estimated);
    }
    let kept_fit = out.pixels.and_then(|c| spelled(keyword, || c.note()));
    report.notes.extend(kept_fit);
    report.notes.extend(dropped.note());
    report.nonfinite = dropped;
    warn_all(py, &report.notes)?;
    let image = image_out(py, &done.image.channels, plane.width(), plane.height());
    let report = to_dict(py, &serde_json::to_string(&report).expect("plain data"))?;
    Ok((image, report))
}
