//! The fit of one tile: the untiled fit's normal equations restricted to the functions whose
//! support meets the tile's window and to the samples in it (module docs of
//! [`crate::image::tiles`]).

use std::time::Instant;

use serde::Serialize;
use thiserror::Error;

use super::geometry::{PixelRect, TileGeometry, TileGeometryError};
use crate::basis::tensor::{auto_level, TensorBasis, TensorError, TensorLevelParams};
use crate::basis::{BasisValue, CdvBasis, FilterFamily};
use crate::image::filters::FilmFilterKind;
use crate::image::fit::normal::{NormalEquations2d, Ranges};
use crate::image::fit::{FillOrdering, NormalSystem, StencilPattern};
use crate::image::pixels::{FilterQuadrature, PixelError, PixelIntegrals};
use crate::image::wavelet::WaveletParams;
use crate::image::{ImagePlane, ImageSamples};
use crate::solve::cholesky::CholeskyError;

/// The parameters of a tile's fit: those of the untiled fit, with its levels resolved from
/// the whole image ([`TileParams::for_image`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TileParams {
    /// Vanishing moments `p` (CDV's filter family for it, as the untiled fit).
    pub p: usize,
    /// Single-scale levels `(Jx, Jy)` of the whole image: the cell width `W / 2^Jx` of the
    /// untiled fit, shared by every tile.
    pub levels: (u32, u32),
    /// Relative ridge on the equilibrated normal matrix (as [`WaveletParams::ridge`]).
    pub ridge: f64,
    /// Pixel filter (as [`WaveletParams::pixel_filter`]): a film filter's weights outside
    /// the window are dropped, so give a halo of at least the filter's radius.
    pub pixel_filter: Option<FilmFilterKind>,
}

impl TileParams {
    /// The tile parameters of the untiled fit with `params` of `total_samples` samples on
    /// `plane`: the levels of [`crate::basis::tensor::auto_level`] for the whole image.
    pub fn for_image(
        params: &WaveletParams,
        plane: ImagePlane,
        total_samples: usize,
    ) -> Result<Self, TileError> {
        if params.smoothing != 0.0 {
            return Err(TileError::Smoothing {
                smoothing: params.smoothing,
            });
        }
        let lp = TensorLevelParams {
            rho: params.rho,
            ..TensorLevelParams::default()
        };
        let (w, h) = (plane.width(), plane.height());
        let pixels = w.saturating_mul(h);
        Ok(Self {
            p: params.p,
            levels: (
                auto_level(w, total_samples, pixels, params.p, lp),
                auto_level(h, total_samples, pixels, params.p, lp),
            ),
            ridge: params.ridge,
            pixel_filter: params.pixel_filter,
        })
    }
}

/// Why a tile could not be fitted: each names the value at fault and the way out.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TileError {
    /// The tile grid.
    #[error(transparent)]
    Geometry(#[from] TileGeometryError),
    /// The samples live on another image than the grid.
    #[error(
        "the samples are on a {samples} image, the tile grid on {image}: give both the same \
         resolution"
    )]
    PlaneMismatch {
        /// The samples' image.
        samples: ImagePlane,
        /// The grid's image.
        image: ImagePlane,
    },
    /// A sample outside the tile's window.
    #[error(
        "sample {index} at ({x}, {y}) is outside the window {window} of tile {tile}: give \
         only the samples of the tile's window (TileGeometry::window)"
    )]
    SampleOutsideWindow {
        /// The tile.
        tile: usize,
        /// 0-based sample index.
        index: usize,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// The tile's window.
        window: PixelRect,
    },
    /// A smoothing penalty (its weight is relative to the whole image's normal matrix).
    #[error(
        "smoothing {smoothing} with tiles: the tiled fit has no smoothing penalty; use \
         {} 0 or fit the image untiled (no {})",
        crate::error::Fix::Set(crate::error::Param::Smoothing),
        crate::error::Fix::Set(crate::error::Param::Tile)
    )]
    Smoothing {
        /// The weight given.
        smoothing: f64,
    },
    /// The basis (levels out of range for `p`).
    #[error(transparent)]
    Basis(#[from] TensorError),
    /// The pixel integrals.
    #[error(transparent)]
    Pixels(#[from] PixelError),
    /// The tile's normal equations could not be solved.
    #[error("tile {tile} (pixels {interior}) cannot be solved: {reason}")]
    Unsolvable {
        /// The tile.
        tile: usize,
        /// Its interior pixels.
        interior: PixelRect,
        /// Why.
        reason: String,
    },
    /// The tile's private one-thread pool could not be started.
    #[error("tile {tile}: could not start its thread ({reason}); retry with fewer workers")]
    Thread {
        /// The tile.
        tile: usize,
        /// The pool's error.
        reason: String,
    },
}

/// What the fit of one tile did.
#[derive(Clone, Debug, Serialize)]
pub struct TileReport {
    /// The tile.
    pub tile: usize,
    /// Its interior pixels.
    pub interior: PixelRect,
    /// Its fit window.
    pub window: PixelRect,
    /// Samples fitted.
    pub samples: usize,
    /// Functions of the window `nx ny`.
    pub functions: usize,
    /// Functions with no sample (coefficients pinned to 0).
    pub unsampled: usize,
    /// Functions with fewer than `(2p - 1)^2` samples.
    pub undersampled: usize,
    /// Cholesky pivots replaced (undetermined directions).
    pub replaced_pivots: usize,
    /// Relative ridge in the end (raised on a negative pivot).
    pub ridge: f64,
    /// Seconds for the fit and the pixels.
    pub seconds: f64,
}

/// The interior pixels of one tile.
#[derive(Clone, Debug)]
pub struct TileImage {
    /// The interior pixels' rectangle.
    pub interior: PixelRect,
    /// Per channel, the interior pixels row by row (`(Y - y0) width + (X - x0)`).
    pub channels: Vec<Vec<f64>>,
    /// What the fit did.
    pub report: TileReport,
}

/// The whole image's single-scale basis and pixel matrices, shared by the tiles of a grid.
#[derive(Clone, Debug)]
pub struct TileBasis {
    geometry: TileGeometry,
    params: TileParams,
    basis: TensorBasis,
    bx: PixelIntegrals,
    by: PixelIntegrals,
}

/// The functions of one axis whose support meets `[a, b]`: the first global index and the
/// structural ranges in window indices (functions sharing a cell inside `[a, b]`).
fn axis_window(scale: &CdvBasis, size: usize, a: usize, b: usize) -> (usize, Ranges) {
    let n = 1usize << scale.coarse();
    let cell = |v: usize| ((v as f64 * n as f64 / size as f64).floor() as usize).min(n - 1);
    let mut ev = scale.evaluator();
    let mut out = Vec::new();
    let mut lists: Vec<(usize, usize)> = Vec::new();
    let points = (cell(a)..=cell(b))
        .map(|c| (c as f64 + 0.5) / n as f64)
        .chain([a as f64 / size as f64, b as f64 / size as f64]);
    for t in points {
        ev.eval_scaling_unit_into(t, &mut out);
        if let (Some(f), Some(l)) = (out.first(), out.last()) {
            lists.push((f.index, l.index));
        }
    }
    let first = lists.iter().map(|l| l.0).min().unwrap_or(0);
    let last = lists.iter().map(|l| l.1).max().unwrap_or(0);
    let mut lo: Vec<usize> = (0..=last - first).collect();
    let mut hi = lo.clone();
    for &(f, l) in &lists {
        for k in f..=l {
            lo[k - first] = lo[k - first].min(f - first);
            hi[k - first] = hi[k - first].max(l - first);
        }
    }
    (first, Ranges { lo, hi })
}

/// Global indices shifted to window indices.
fn shift(values: &[BasisValue], first: usize, out: &mut Vec<BasisValue>) {
    out.clear();
    out.extend(values.iter().map(|v| BasisValue {
        index: v.index - first,
        value: v.value,
    }));
}

impl TileBasis {
    /// The basis of the whole image at `params.levels` and its pixel matrices.
    pub fn new(geometry: &TileGeometry, params: &TileParams) -> Result<Self, TileError> {
        geometry.validate()?;
        let (w, h) = (geometry.plane.width(), geometry.plane.height());
        let family = FilterFamily::cdv_default(params.p);
        let basis = TensorBasis::new(params.p, family, w, h, params.levels)?;
        let (bx, by) = match params.pixel_filter {
            None | Some(FilmFilterKind::Box) => (
                PixelIntegrals::new(basis.scale_x(), w)?,
                PixelIntegrals::new(basis.scale_y(), h)?,
            ),
            Some(kind) => {
                let f = kind.build();
                let q = FilterQuadrature::default();
                (
                    PixelIntegrals::filtered(basis.scale_x(), w, f.as_ref(), q)?,
                    PixelIntegrals::filtered(basis.scale_y(), h, f.as_ref(), q)?,
                )
            }
        };
        Ok(Self {
            geometry: *geometry,
            params: *params,
            basis,
            bx,
            by,
        })
    }

    /// The grid.
    pub fn geometry(&self) -> &TileGeometry {
        &self.geometry
    }

    /// The parameters.
    pub fn params(&self) -> &TileParams {
        &self.params
    }

    /// Fits tile `tile` from the samples of its window (module docs); pure: the same
    /// samples in the same order give the same bits, whatever thread pool calls it (the fit
    /// runs on the calling thread: [`NormalSystem::sequential`]).
    pub fn fit(&self, samples: &ImageSamples, tile: usize) -> Result<TileImage, TileError> {
        self.geometry.check_index(tile)?;
        if samples.plane() != self.geometry.plane {
            return Err(TileError::PlaneMismatch {
                samples: samples.plane(),
                image: self.geometry.plane,
            });
        }
        let window = self.geometry.window(tile);
        let (xs, ys) = (samples.xs(), samples.ys());
        if let Some(index) = (0..xs.len()).find(|&i| !window.contains(xs[i], ys[i])) {
            return Err(TileError::SampleOutsideWindow {
                tile,
                index,
                x: xs[index],
                y: ys[index],
                window,
            });
        }
        self.fit_window(samples, tile, window)
    }

    fn fit_window(
        &self,
        samples: &ImageSamples,
        tile: usize,
        window: PixelRect,
    ) -> Result<TileImage, TileError> {
        let t0 = Instant::now();
        let interior = self.geometry.interior(tile);
        let (w, h) = (self.geometry.plane.width(), self.geometry.plane.height());
        let (fx0, rx) = axis_window(self.basis.scale_x(), w, window.x0, window.x1);
        let (fy0, ry) = axis_window(self.basis.scale_y(), h, window.y0, window.y1);
        let (nx, ny) = (rx.lo.len(), ry.lo.len());
        let pattern = StencilPattern::from_ranges(rx, ry);
        let channels = samples.channels();
        let values: Vec<&[f64]> = samples.values().iter().map(|v| v.as_slice()).collect();
        let mut ne = NormalEquations2d {
            values: vec![0.0; pattern.nnz()],
            rhs: vec![vec![0.0; nx * ny]; channels],
            support_samples: vec![0; nx * ny],
        };
        let mut ev = self.basis.evaluator();
        let (mut lx, mut ly, mut prod) = (Vec::new(), Vec::new(), Vec::new());
        for i in 0..samples.len() {
            let (gx, gy) = ev.factors_unchecked(samples.xs()[i], samples.ys()[i]);
            shift(gx, fx0, &mut lx);
            shift(gy, fy0, &mut ly);
            ne.add_sample(&pattern, &lx, &ly, &values, i, &mut prod);
        }
        let full = (2 * self.params.p - 1).pow(2) as u32;
        let unsampled = ne.support_samples.iter().filter(|&&c| c == 0).count();
        let undersampled = ne.support_samples.iter().filter(|&&c| c < full).count();
        let unsolvable = |reason: String| TileError::Unsolvable {
            tile,
            interior,
            reason,
        };
        let mut system = NormalSystem::new(pattern, ne.values, self.params.ridge).sequential();
        let factor = system
            .factor(FillOrdering::default())
            .map_err(|e: CholeskyError| unsolvable(e.to_string()))?;
        let rhs: Vec<&[f64]> = ne.rhs.iter().map(|r| r.as_slice()).collect();
        let z = system.solve_factored(&rhs);
        if let Some(c) = z.iter().position(|c| c.iter().any(|v| !v.is_finite())) {
            return Err(unsolvable(format!(
                "channel {c} has non-finite coefficients (an internal error: please report)"
            )));
        }
        let channels = z
            .iter()
            .map(|c| self.pixels(c, (fx0, nx), (fy0, ny), interior))
            .collect();
        Ok(TileImage {
            interior,
            channels,
            report: TileReport {
                tile,
                interior,
                window,
                samples: samples.len(),
                functions: nx * ny,
                unsampled,
                undersampled,
                replaced_pivots: factor.replaced_pivots,
                ridge: system.ridge(),
                seconds: t0.elapsed().as_secs_f64(),
            },
        })
    }

    /// `I[Y, X] = sum B_y[Y, ky] z[ky, kx] B_x[X, kx]` over the window's functions, for the
    /// interior pixels.
    fn pixels(
        &self,
        z: &[f64],
        (fx0, nx): (usize, usize),
        (fy0, ny): (usize, usize),
        r: PixelRect,
    ) -> Vec<f64> {
        let iw = r.width();
        // t[ky, X] = sum_kx z[ky, kx] B_x[X, kx]
        let mut t = vec![0.0; ny * iw];
        let bx = self.bx.matrix();
        for x in r.x0..r.x1 {
            let row = bx.outer_view(x).expect("a pixel row of B_x");
            for (k, &v) in row.iter() {
                if (fx0..fx0 + nx).contains(&k) {
                    for ky in 0..ny {
                        t[ky * iw + x - r.x0] += v * z[ky * nx + k - fx0];
                    }
                }
            }
        }
        let mut out = vec![0.0; r.pixels()];
        let by = self.by.matrix();
        for y in r.y0..r.y1 {
            let row = by.outer_view(y).expect("a pixel row of B_y");
            let o = &mut out[(y - r.y0) * iw..(y - r.y0 + 1) * iw];
            for (k, &v) in row.iter() {
                if (fy0..fy0 + ny).contains(&k) {
                    let src = &t[(k - fy0) * iw..(k - fy0 + 1) * iw];
                    o.iter_mut().zip(src).for_each(|(a, b)| *a += v * b);
                }
            }
        }
        out
    }
}

/// Fits tile `tile` of `geometry` from the samples of its window (module docs of
/// [`crate::image::tiles`]) and returns its interior pixels: [`TileBasis::new`] then
/// [`TileBasis::fit`]. Pure: the same input gives the same bits (a retried task gives the
/// identical tile).
pub fn fit_tile(
    samples: &ImageSamples,
    geometry: &TileGeometry,
    tile: usize,
    params: &TileParams,
) -> Result<TileImage, TileError> {
    TileBasis::new(geometry, params)?.fit(samples, tile)
}

/// The samples of `samples` in the window of tile `tile`, in their order.
pub fn window_samples(
    samples: &ImageSamples,
    geometry: &TileGeometry,
    tile: usize,
) -> Result<ImageSamples, TileError> {
    geometry.check_index(tile)?;
    let window = geometry.window(tile);
    let (xs, ys) = (samples.xs(), samples.ys());
    let keep: Vec<usize> = (0..xs.len())
        .filter(|&i| window.contains(xs[i], ys[i]))
        .collect();
    let pick = |v: &[f64]| keep.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let values = samples.values().iter().map(|v| pick(v)).collect();
    Ok(
        ImageSamples::new(samples.plane(), pick(xs), pick(ys), values)
            .expect("a subset of valid samples is valid"),
    )
}
