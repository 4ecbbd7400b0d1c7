//! The image plane: `rkwave.reconstruct_image` (scattered samples `(x_i, y_i, f_i)` in pixel
//! units to an `(H, W, C)` image by the library's [`rkwave::image::reconstruct`], the entry
//! point `rkwave reconstruct --dim 2` calls): the wavelet fit, its local inversion, or a film
//! filter on the same samples.

use std::path::Path;
use std::time::Instant;

use pyo3::prelude::*;
use rkwave::image::estimate::{reconstruct_estimated, ShrinkParams, UniformEstimate};
use rkwave::image::filters::FilmFilterKind;
use rkwave::image::report::FileReconstructionReport;
use rkwave::image::{
    reconstruct, split_finite, DroppedSamples, ImagePlane, ImageSamples, Method, NonFinitePolicy,
};

use crate::arrays::{columns, floats, image_out};
use crate::errors::{invalid, to_py, warn_all};
use crate::params::wavelet_params;
use crate::report::to_dict;

/// The method from `method` and `filter` (a film filter by name: `box`, `triangle`,
/// `gaussian`, `mitchell`, `lanczos`).
fn method_of(method: &str, filter: Option<&str>) -> PyResult<Method> {
    let chosen: Method = method
        .parse()
        .map_err(|e| invalid(format!("method: {e}")))?;
    match filter {
        None => Ok(chosen),
        Some(name) => {
            let kind: FilmFilterKind = name.parse().map_err(|e| invalid(format!("filter: {e}")))?;
            match chosen {
                Method::Wavelet => Ok(Method::Film(kind)),
                Method::Film(k) if k == kind => Ok(chosen),
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

/// The policy of a `drop_nonfinite` keyword.
pub fn nonfinite(drop: bool) -> NonFinitePolicy {
    if drop {
        NonFinitePolicy::Drop
    } else {
        NonFinitePolicy::Refuse
    }
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

/// The pixel estimate of the wavelet path: `pixels` by name, or as the command line's
/// `--pixels` default: `auto`, unless `p` or `method="local"` (read by the fit only) is given,
/// then `fit` with a note saying so.
fn estimate_of(
    pixels: Option<&str>,
    p_given: bool,
    method: Method,
) -> PyResult<(UniformEstimate, Option<String>)> {
    if let Some(name) = pixels {
        let e = name.parse().map_err(|e| invalid(format!("pixels: {e}")))?;
        return Ok((e, None));
    }
    let given: Vec<&str> = [
        ("p", p_given),
        ("method=\"local\"", method == Method::Local),
    ]
    .into_iter()
    .filter_map(|(k, g)| g.then_some(k))
    .collect();
    if given.is_empty() {
        return Ok((UniformEstimate::Auto, None));
    }
    Ok((
        UniformEstimate::Fit,
        Some(format!(
            "pixels: the least-squares fit, because {} (read by the fit only) was given without \
             pixels=; the default without them is pixels=\"auto\" (films chosen per pixel by \
             SURE), which uses no fit",
            given.join(", ")
        )),
    ))
}

/// Reconstructs a `W x H` image from scattered samples on the image plane, as `rkwave
/// reconstruct --dim 2`: returns the `(H, W, C)` float64 pixels and a report dict.
///
/// `xy` is `(m, 2)` in pixel units (pixel `(X, Y)` covers `[X, X+1] x [Y, Y+1]`), `values`
/// `(m,)` or `(m, C)` with 1 to 4 channels. `method` is `"wavelet"` (the least-squares fit,
/// box-integrated over each pixel), `"local"` (its local inversion), or a film filter;
/// `filter="gaussian"` (or `box`, `triangle`, `mitchell`, `lanczos`) splats the same samples
/// through that film filter for comparison. `pixels` is the pixel estimate of the wavelet
/// path, as the command line's `--pixels`: `"auto"` (the film of least SURE per pixel, then
/// Haar shrinkage; falls back to the fit, with a warning, where a pixel has no sample or
/// most have one), `"fit"`, `"fit-clamped"`, `"box"` or `"shrunk"`; by default `"auto"`,
/// or `"fit"` (with a warning) when `p` or `method="local"` is given, as on the command line.
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
    pixels=None, drop_nonfinite=false))]
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
    drop_nonfinite: bool,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let method = method_of(method, filter)?;
    let wavelet = wavelet_params(p.unwrap_or(2))?;
    let plane = plane_of(resolution)?;
    let film = matches!(method, Method::Film(_));
    if film && pixels.is_some() {
        return Err(invalid(
            "pixels= is the estimate of the wavelet path; a film filter splats the samples \
             itself: drop pixels= or filter=",
        ));
    }
    let estimate = (!film)
        .then(|| estimate_of(pixels, p.is_some(), method))
        .transpose()?;
    let t0 = Instant::now();
    let (samples, dropped) = samples_of(plane, xy, values, nonfinite(drop_nonfinite))?;
    let convert_s = t0.elapsed().as_secs_f64();
    let (done, estimated) = match estimate {
        None => (
            py.detach(|| reconstruct(method, &samples, &wavelet))
                .map_err(to_py)?,
            None,
        ),
        Some((estimate, kept_fit)) => {
            let (done, estimated) = py
                .detach(|| {
                    reconstruct_estimated(
                        estimate,
                        method,
                        &samples,
                        &wavelet,
                        &ShrinkParams::default(),
                    )
                })
                .map_err(to_py)?;
            (done, Some((estimated, kept_fit)))
        }
    };
    // The report of `rkwave reconstruct --dim 2 --json`; the samples came from memory, and
    // "read" is checking and converting them.
    let memory = Path::new("<numpy>");
    let total = t0.elapsed().as_secs_f64();
    let mut report = FileReconstructionReport::new(
        memory, memory, plane, &samples, method, wavelet.p, &done, convert_s, 0.0, total,
    );
    if let Some((estimated, kept_fit)) = estimated {
        report = report.with_pixels(estimated);
        report.notes.extend(kept_fit);
    }
    report.notes.extend(dropped.note());
    report.nonfinite = dropped;
    warn_all(py, &report.notes)?;
    let image = image_out(py, &done.image.channels, plane.width(), plane.height());
    let report = to_dict(py, &serde_json::to_string(&report).expect("plain data"))?;
    Ok((image, report))
}
