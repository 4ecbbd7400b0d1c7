//! The tiled image: every tile of a [`TileGeometry`] fitted on its window
//! ([`super::fit::TileBasis::fit`]) and its interior kept, the samples never held whole.
//!
//! The samples are taken in **bands**: band `ty` is the tile row `ty` with its halo, the rows
//! `[ty T - H_a, (ty + 1) T + H_a]`. First one validating pass counts the samples `m` (the
//! levels come from the whole image's `m`) and checks every position lies in the image;
//! then a sample file is spilled in one more pass into one scratch file per band
//! ([`super::spill`]: two reads of the input and one write and read of about its size,
//! whatever the image height), while samples in memory are scanned once per band. Each band's
//! samples are bucketed by tile in input order and its tiles fitted, at most `workers` at
//! once. Memory holds one band's samples (`W (T + 2 H_a)` pixels' worth), `workers` tile fits
//! and the output image. Each tile sees its samples in input order whatever the worker count
//! or the path, so the image is the same bits for every `workers`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use thiserror::Error;

use super::fit::{TileBasis, TileError, TileParams, TileReport};
use super::geometry::TileGeometry;
use super::spill::{BandSpill, ScratchError, SpillReport};
use crate::image::fit::NormalSolver;
use crate::image::wavelet::WaveletParams;
use crate::image::{ImageSamples, PixelImage};
use crate::io::chunks::SampleChunkReader;
use crate::io::IoError;
use crate::resources::{format_bytes, ImageEstimate, ImageRequest, ImageSolve, ResourceError};

/// Where the samples of a tiled fit come from.
#[derive(Clone, Copy, Debug)]
pub enum TiledInput<'a> {
    /// Samples in memory (read once per pass all the same).
    Samples(&'a ImageSamples),
    /// A sample file (`.npy` or CSV, columns `x, y, c1..`), read in chunks of rows.
    File(&'a Path),
}

/// Parameters of the tiled fit besides the tile's.
#[derive(Clone, Debug, Serialize)]
pub struct TiledParams {
    /// Tiles fitted at once (each holds its samples and its factor): more is faster on more
    /// cores and costs one tile's memory each.
    pub workers: usize,
    /// Rows read per chunk of a sample file: larger reads fewer times and holds more.
    pub chunk_rows: usize,
    /// Where a sample file's band files are written (a fresh folder inside it, removed after
    /// the fit); `None`: the system's temporary folder. About the input's size at 8 bytes a
    /// value is written there.
    pub scratch: Option<PathBuf>,
}

impl Default for TiledParams {
    fn default() -> Self {
        Self {
            workers: rayon::current_num_threads().max(1),
            chunk_rows: 1 << 16,
            scratch: None,
        }
    }
}

/// Why the tiled fit failed: each names the value at fault and the way out.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TiledError {
    /// Reading the samples.
    #[error(transparent)]
    Io(#[from] IoError),
    /// A tile (its geometry, or a tile that cannot be solved).
    #[error(transparent)]
    Tile(#[from] TileError),
    /// A sample outside the image.
    #[error(
        "sample {row} (0-based row) at ({x}, {y}) is outside the {width} x {height} image: give \
         positions in pixel units within [0, W] x [0, H] (or the right {})",
        crate::error::Fix::Set(crate::error::Param::Resolution)
    )]
    SampleOutside {
        /// 0-based row of the input.
        row: usize,
        /// x.
        x: f64,
        /// y.
        y: f64,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
    },
    /// A file with a column count the image plane cannot take.
    #[error(
        "the samples have {columns} columns: an image-plane sample file has x, y and 1 to 4 \
         channels (3 to 6 columns)"
    )]
    Columns {
        /// Columns found.
        columns: usize,
    },
    /// No samples at all.
    #[error("the input holds no samples: give at least one sample inside the image")]
    Empty,
    /// The tiled fit would need more memory than the limit (checked after the counting
    /// pass, before any band is read or any tile fitted).
    #[error(transparent)]
    Resources(#[from] ResourceError),
    /// Writing or reading the band files of a sample file.
    #[error(transparent)]
    Scratch(#[from] ScratchError),
}

/// What the tiled fit did.
#[derive(Clone, Debug, Serialize)]
pub struct TiledReport {
    /// Tile size `T`.
    pub tile: usize,
    /// Halo `H_a`.
    pub halo: usize,
    /// Tiles per row and column.
    pub grid: (usize, usize),
    /// Samples `m`.
    pub samples: usize,
    /// Channels.
    pub channels: usize,
    /// The tile parameters (the whole image's levels).
    pub params: TileParams,
    /// How every tile's normal equations are solved: always the sparse Cholesky (exact up to
    /// rounding), whatever the untiled fit would choose by size. The untiled fit's default
    /// above `CHOLESKY_MAX_FUNCTIONS` unknowns, Jacobi PCG to a relative residual of `1e-6`,
    /// leaves a coefficient error up to `cond(G) 1e-6`, which near Nyquist reaches `1e-4` to
    /// `1e-2` of the value range: the tiled image is within the tile study's tolerance of the
    /// untiled fit solved exactly, not of the CG's iterate (tests/tiles_nyquist.rs).
    pub solver: NormalSolver,
    /// Tiles fitted at once.
    pub workers: usize,
    /// Passes over the input: the validating pass, then one spill pass (a file) or one pass
    /// per band (samples in memory).
    pub passes: usize,
    /// The band files of a sample file.
    pub spill: Option<SpillReport>,
    /// Seconds reading and bucketing (all passes).
    pub read_s: f64,
    /// Seconds fitting (wall clock, all bands).
    pub fit_s: f64,
    /// Every tile's report, in tile order.
    pub tiles: Vec<TileReport>,
}

/// The tiled image and its report.
#[derive(Clone, Debug)]
pub struct TiledOutput {
    /// The pixels.
    pub image: PixelImage,
    /// What was done.
    pub report: TiledReport,
}

/// One tile's samples, gathered in input order.
#[derive(Default)]
struct Bucket {
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
}

impl TiledInput<'_> {
    /// Calls `each(first_row, xs, ys, channels)` on consecutive chunks of the input.
    fn pass(
        &self,
        chunk_rows: usize,
        mut each: impl FnMut(usize, &[f64], &[f64], &[&[f64]]) -> Result<(), TiledError>,
    ) -> Result<(), TiledError> {
        match self {
            TiledInput::Samples(s) => {
                let values: Vec<&[f64]> = s.values().iter().map(|v| v.as_slice()).collect();
                each(0, s.xs(), s.ys(), &values)
            }
            TiledInput::File(path) => {
                let reader = SampleChunkReader::open(path)?;
                let names = crate::io::image_column_names;
                reader.for_each_chunk(chunk_rows, names, |first, set| {
                    let columns = 1 + set.values.len();
                    if !(3..=6).contains(&columns) {
                        return Err(TiledError::Columns { columns });
                    }
                    let channels: Vec<&[f64]> =
                        set.values[1..].iter().map(|v| v.as_slice()).collect();
                    each(first, &set.positions, &set.values[0], &channels)
                })
            }
        }
    }
}

/// The validating pass: the sample count and the channel count; every position in the
/// image.
fn count(
    input: &TiledInput,
    geometry: &TileGeometry,
    chunk_rows: usize,
) -> Result<(usize, usize), TiledError> {
    let (w, h) = (geometry.plane.width(), geometry.plane.height());
    let (mut m, mut channels) = (0usize, 0usize);
    input.pass(chunk_rows, |first, xs, ys, values| {
        if let Some(i) = (0..xs.len()).find(|&i| !geometry.plane.contains(xs[i], ys[i])) {
            return Err(TiledError::SampleOutside {
                row: first + i,
                x: xs[i],
                y: ys[i],
                width: w,
                height: h,
            });
        }
        m += xs.len();
        channels = values.len();
        Ok(())
    })?;
    if m == 0 {
        return Err(TiledError::Empty);
    }
    Ok((m, channels))
}

/// The memory of a tiled fit of `samples` samples of `channels` channels (module docs):
/// one band of windows' samples and a chunk of rows being read, `workers` tile fits (a
/// uniform fit of a window's functions and samples each) and the output image with its
/// encoded copy.
pub fn tiled_estimate(
    geometry: &TileGeometry,
    params: &TileParams,
    channels: usize,
    samples: f64,
    tiled: &TiledParams,
) -> ImageEstimate {
    let workers = tiled.workers;
    let chunk = 3.0 * 8.0 * (2.0 + channels as f64) * tiled.chunk_rows as f64;
    let (w, h) = (
        geometry.plane.width() as f64,
        geometry.plane.height() as f64,
    );
    let per_pixel = samples / (w * h);
    let side = (geometry.tile + 2 * geometry.halo) as f64;
    let window_samples = per_pixel * side.min(w) * side.min(h);
    let band_samples = per_pixel * w * side.min(h) * side.min(w) / (geometry.tile as f64).min(w);
    let margin = 2.0 * (2 * params.p) as f64;
    let functions = |size: f64, level: u32| {
        (side.min(size) * 2f64.powi(level as i32) / size + margin).min(2f64.powi(level as i32))
    };
    let window_functions = functions(w, params.levels.0) * functions(h, params.levels.1);
    let tile = ImageRequest {
        pixels: 0.0,
        channels,
        samples: window_samples,
        from_file: false,
        positions: 0.0,
        solve: ImageSolve::Uniform {
            p: params.p,
            functions: window_functions,
        },
        images: 0,
    }
    .estimate();
    let k = workers.max(1) as f64;
    ImageEstimate {
        samples: 8.0 * (2.0 + channels as f64) * band_samples + k * tile.samples + chunk,
        normal_matrix: k * tile.normal_matrix,
        factor: k * tile.factor,
        scratch: k * tile.scratch,
        output_images: 2.0 * 8.0 * w * h * channels as f64,
        ..ImageEstimate::default()
    }
}

/// The tiled fit of `input` (module docs) with the untiled fit's `wavelet` parameters (its
/// levels from the whole image's sample count, [`TileParams::for_image`]); refused above
/// the memory limit ([`tiled_estimate`]) after the counting pass, before any tile;
/// `progress` is called after each tile.
pub fn reconstruct_tiled(
    input: TiledInput,
    geometry: &TileGeometry,
    wavelet: &WaveletParams,
    tiled: &TiledParams,
    progress: &(dyn Fn(&TileReport) + Sync),
) -> Result<TiledOutput, TiledError> {
    geometry.validate().map_err(TileError::from)?;
    TileParams::for_image(wavelet, geometry.plane, 1)?;
    let t0 = Instant::now();
    let (m, channels) = count(&input, geometry, tiled.chunk_rows)?;
    let params = TileParams::for_image(wavelet, geometry.plane, m)?;
    tiled_estimate(geometry, &params, channels, m as f64, tiled).check(
        || {
            format!(
                "the tiled fit of {m} samples on {} pixels in tiles of {} (halo {}, {} workers, \
                 chunks of {} rows)",
                geometry.plane, geometry.tile, geometry.halo, tiled.workers, tiled.chunk_rows
            )
        },
        || {
            format!(
                "smaller {} or fewer {} (the limit is {})",
                crate::error::Fix::Set(crate::error::Param::Tile),
                crate::error::Fix::Set(crate::error::Param::Workers),
                format_bytes(crate::resources::memory_limit() as f64)
            )
        },
    )?;
    let basis = TileBasis::new(geometry, &params)?;
    let spill = match input {
        TiledInput::File(_) => {
            let parent = tiled.scratch.clone().unwrap_or_else(std::env::temp_dir);
            let chunk = tiled.chunk_rows;
            Some(BandSpill::write(geometry, channels, m, &parent, |sink| {
                input.pass(chunk, |_, xs, ys, values| sink(xs, ys, values))
            })?)
        }
        TiledInput::Samples(_) => None,
    };
    let mut read_s = t0.elapsed().as_secs_f64();
    let mut fit_s = 0.0;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(tiled.workers.max(1))
        .build()
        .map_err(|e| TileError::Thread {
            tile: 0,
            reason: e.to_string(),
        })?;
    let (nx, ny) = geometry.grid();
    let mut image = PixelImage::zeros(geometry.plane, channels);
    let mut reports = Vec::with_capacity(nx * ny);
    let width = geometry.plane.width();
    for ty in 0..ny {
        let t_read = Instant::now();
        let mut buckets: Vec<Bucket> = (0..nx)
            .map(|_| Bucket {
                values: vec![Vec::new(); channels],
                ..Bucket::default()
            })
            .collect();
        let band = geometry.window(ty * nx);
        let mut take = |xs: &[f64], ys: &[f64], values: &[&[f64]]| {
            for i in 0..xs.len() {
                if !(band.y0 as f64..=band.y1 as f64).contains(&ys[i]) {
                    continue;
                }
                let (lo, hi) = geometry.columns_of(xs[i]);
                for (tx, b) in buckets
                    .iter_mut()
                    .enumerate()
                    .take((hi + 2).min(nx))
                    .skip(lo.saturating_sub(1))
                {
                    if geometry.window(ty * nx + tx).contains(xs[i], ys[i]) {
                        b.xs.push(xs[i]);
                        b.ys.push(ys[i]);
                        for (c, v) in values.iter().enumerate() {
                            b.values[c].push(v[i]);
                        }
                    }
                }
            }
            Ok(())
        };
        match &spill {
            Some((files, _)) => files.read_band(ty, tiled.chunk_rows, take)?,
            None => input.pass(tiled.chunk_rows, |_, xs, ys, values| take(xs, ys, values))?,
        }
        read_s += t_read.elapsed().as_secs_f64();
        let t_fit = Instant::now();
        let results: Vec<Result<super::TileImage, TileError>> = pool.install(|| {
            buckets
                .into_par_iter()
                .enumerate()
                .map(|(tx, b)| {
                    let tile = ty * nx + tx;
                    let samples = ImageSamples::new(geometry.plane, b.xs, b.ys, b.values)
                        .expect("samples checked in the validating pass");
                    let out = basis.fit(&samples, tile);
                    if let Ok(t) = &out {
                        progress(&t.report);
                    }
                    out
                })
                .collect()
        });
        fit_s += t_fit.elapsed().as_secs_f64();
        for result in results {
            let tile = result?;
            let r = tile.interior;
            for (c, px) in tile.channels.iter().enumerate() {
                for y in r.y0..r.y1 {
                    image.channels[c][y * width + r.x0..y * width + r.x1]
                        .copy_from_slice(&px[(y - r.y0) * r.width()..(y - r.y0 + 1) * r.width()]);
                }
            }
            reports.push(tile.report);
        }
    }
    Ok(TiledOutput {
        image,
        report: TiledReport {
            tile: geometry.tile,
            halo: geometry.halo,
            grid: (nx, ny),
            samples: m,
            channels,
            params,
            solver: NormalSolver::Cholesky,
            workers: tiled.workers.max(1),
            passes: if spill.is_some() { 2 } else { 1 + ny },
            spill: spill.map(|(_, report)| report),
            read_s,
            fit_s,
            tiles: reports,
        },
    })
}
