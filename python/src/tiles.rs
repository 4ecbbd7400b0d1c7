//! `rkwave.TileGeometry` and `rkwave.fit_tile`: one tile of the tiled image-plane fit
//! ([`rkwave::image::tiles`]), so a task scheduler (`rkwave.dask.reconstruct_image_tiles`)
//! can fit each tile in its own task.
//!
//! Tile `t` of a `W x H` image in tiles of `T` pixels has the interior
//! `[tx T, min((tx+1) T, W)) x [ty T, min((ty+1) T, H))` and the window grown by the halo
//! `H_a` on every side, clipped to the image. Its fit is the untiled fit's normal equations
//! restricted to the functions whose support meets the window and to the samples in it, at
//! the levels of the whole image (from its total sample count `m`); it reads nothing but its
//! arguments, so the same window samples in the same order give the same pixels, bit for bit,
//! as `rkwave reconstruct --dim 2 --tile T --halo H_a` (which gives each tile its window's
//! samples in file order).

use std::sync::{Arc, Mutex};

use pyo3::prelude::*;
use pyo3::types::PyTuple;
use rkwave::image::tiles::{PixelRect, TileBasis, TileError, TileGeometry, TileParams};
use rkwave::image::NonFinitePolicy;

use crate::arrays::image_out;
use crate::errors::{invalid, to_py};
use crate::image::{plane_of, samples_of};
use crate::params::image_p;
use crate::report::to_dict;

/// The last grid's whole-image basis and pixel matrices, kept by this process: a worker that
/// fits many tiles of one image builds them once, as the one-process tiled fit does (the same
/// deterministic construction, so the pixels are the same bits).
static LAST_BASIS: Mutex<Option<Arc<TileBasis>>> = Mutex::new(None);

/// The [`TileBasis`] of `geometry` and `params`: the kept one if it matches, else built
/// (and kept in place of the last).
fn tile_basis(geometry: &TileGeometry, params: &TileParams) -> Result<Arc<TileBasis>, TileError> {
    let mut last = LAST_BASIS.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(b) = last.as_ref() {
        if b.geometry() == geometry && b.params() == params {
            return Ok(Arc::clone(b));
        }
    }
    let built = Arc::new(TileBasis::new(geometry, params)?);
    *last = Some(Arc::clone(&built));
    Ok(built)
}

/// The rectangle as `(x0, x1, y0, y1)`: columns `x0..x1`, rows `y0..y1`.
fn rect(r: PixelRect) -> (usize, usize, usize, usize) {
    (r.x0, r.x1, r.y0, r.y1)
}

/// The tile grid of a `W x H` image: square tiles of `tile` pixels (the last row and column
/// clipped), each fitted on its window, the interior grown by `halo` pixels (at most `tile`)
/// and clipped to the image. Tiles are numbered row-major, `t = ty * nx + tx`. Picklable.
///
/// >>> import rkwave
/// >>> g = rkwave.TileGeometry((100, 60), tile=32, halo=8)
/// >>> g.grid, g.count, g.interior(4), g.window(4)
/// ((4, 2), 8, (0, 32, 32, 60), (0, 40, 24, 60))
#[pyclass(name = "TileGeometry", module = "rkwave", frozen, eq)]
#[derive(PartialEq)]
pub struct PyTileGeometry {
    pub(crate) geometry: TileGeometry,
}

impl PyTileGeometry {
    fn checked(&self, index: usize) -> PyResult<()> {
        self.geometry.check_index(index).map_err(to_py)
    }
}

#[pymethods]
impl PyTileGeometry {
    #[new]
    #[pyo3(signature = (resolution, tile, halo=12))]
    fn new(resolution: (usize, usize), tile: usize, halo: usize) -> PyResult<Self> {
        let plane = plane_of(resolution)?;
        let geometry = TileGeometry::new(plane, tile, halo).map_err(to_py)?;
        Ok(Self { geometry })
    }

    /// The image `(W, H)`.
    #[getter]
    fn resolution(&self) -> (usize, usize) {
        (self.geometry.plane.width(), self.geometry.plane.height())
    }

    /// Tile size `T` in pixels.
    #[getter]
    fn tile(&self) -> usize {
        self.geometry.tile
    }

    /// Halo in pixels.
    #[getter]
    fn halo(&self) -> usize {
        self.geometry.halo
    }

    /// Tiles per row and per column `(nx, ny)`.
    #[getter]
    fn grid(&self) -> (usize, usize) {
        self.geometry.grid()
    }

    /// Number of tiles `nx ny`.
    #[getter]
    fn count(&self) -> usize {
        self.geometry.count()
    }

    /// The interior pixels of tile `index` as `(x0, x1, y0, y1)` (columns `x0..x1`, rows
    /// `y0..y1`): every pixel is in exactly one interior.
    fn interior(&self, index: usize) -> PyResult<(usize, usize, usize, usize)> {
        self.checked(index)?;
        Ok(rect(self.geometry.interior(index)))
    }

    /// The fit window of tile `index` as `(x0, x1, y0, y1)`: a sample `(x, y)` is one of the
    /// tile's when `x0 <= x <= x1` and `y0 <= y <= y1` (closed).
    fn window(&self, index: usize) -> PyResult<(usize, usize, usize, usize)> {
        self.checked(index)?;
        Ok(rect(self.geometry.window(index)))
    }

    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyTuple>> {
        let cls = py.get_type::<PyTileGeometry>().into_any();
        let args = (self.resolution(), self.geometry.tile, self.geometry.halo);
        PyTuple::new(py, [cls, args.into_pyobject(py)?.into_any()])
    }

    fn __repr__(&self) -> String {
        format!(
            "rkwave.TileGeometry(resolution={:?}, tile={}, halo={})",
            self.resolution(),
            self.geometry.tile,
            self.geometry.halo
        )
    }
}

/// Fits tile `tile` of `geometry` from the samples of its window and returns its interior
/// pixels `(h, w, C)` (the rows `y0..y1` and columns `x0..x1` of `geometry.interior(tile)`)
/// and the tile's report dict.
///
/// The whole image's basis and pixel matrices are built on the first tile of a grid and
/// kept for the next tiles of the same grid and parameters in this process.
///
/// `xy` `(k, 2)` and `values` `(k,)` or `(k, C)` are the samples in the tile's window
/// (`geometry.window(tile)`, closed), in the order of the whole sample set; `total_samples`
/// is the whole image's sample count `m`, which sets the levels of every tile. `p`, `rho`
/// and `ridge` are those of `rkwave reconstruct --dim 2` (defaults 2, 4, 1e-9). With the
/// window's samples in file order the pixels are those of `rkwave reconstruct --dim 2
/// --tile T --halo H`, bit for bit.
///
/// >>> import numpy as np, rkwave
/// >>> g = rkwave.TileGeometry((32, 32), tile=16, halo=4)
/// >>> xy = np.random.default_rng(1).uniform(0, 32, (4096, 2))
/// >>> x0, x1, y0, y1 = g.window(0)
/// >>> keep = (xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
/// >>> pixels, report = rkwave.fit_tile(xy[keep], xy[keep, 0] / 32, g, 0, total_samples=4096)
/// >>> pixels.shape, report["tile"]
/// ((16, 16, 1), 0)
#[pyfunction]
#[pyo3(signature = (xy, values, geometry, tile, total_samples, p=2, *, rho=None, ridge=None))]
#[allow(clippy::too_many_arguments)]
pub fn fit_tile<'py>(
    py: Python<'py>,
    xy: &Bound<'py, PyAny>,
    values: &Bound<'py, PyAny>,
    geometry: &PyTileGeometry,
    tile: usize,
    total_samples: usize,
    p: usize,
    rho: Option<f64>,
    ridge: Option<f64>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let g = geometry.geometry;
    geometry.checked(tile)?;
    let mut wavelet = rkwave::image::WaveletParams {
        p: image_p(p)?,
        pixel_filter: None,
        ..rkwave::image::WaveletParams::default()
    };
    if let Some(rho) = rho {
        if !(rho.is_finite() && rho > 0.0) {
            return Err(invalid(format!(
                "rho={rho} must be a positive number of samples per tensor function (default 4)"
            )));
        }
        wavelet.rho = rho;
    }
    if let Some(ridge) = ridge {
        if !(ridge.is_finite() && (0.0..1.0).contains(&ridge)) {
            return Err(invalid(format!(
                "ridge={ridge} must be in [0, 1) (default 1e-9)"
            )));
        }
        wavelet.ridge = ridge;
    }
    if total_samples == 0 {
        return Err(invalid(
            "total_samples=0: give the whole image's sample count (it sets the levels)",
        ));
    }
    let (samples, _) = samples_of(g.plane, xy, values, NonFinitePolicy::Refuse)?;
    if samples.len() > total_samples {
        return Err(invalid(format!(
            "the window holds {} samples but total_samples={total_samples}: give the whole \
             image's sample count",
            samples.len()
        )));
    }
    let params = TileParams::for_image(&wavelet, g.plane, total_samples).map_err(to_py)?;
    let out = py
        .detach(|| tile_basis(&g, &params)?.fit(&samples, tile))
        .map_err(to_py)?;
    let r = out.interior;
    let pixels = image_out(py, &out.channels, r.width(), r.height());
    let report = to_dict(py, &serde_json::to_string(&out.report).expect("plain data"))?;
    Ok((pixels, report))
}
