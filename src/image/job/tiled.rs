//! The uniform fit tile by tile: validate, decide the halo, then fit
//! ([`crate::image::tiles::reconstruct_tiled`], which checks its memory from the sample count
//! before it holds any tile).

use std::path::PathBuf;

use crate::error::Param;
use crate::image::tiles::{
    reconstruct_tiled, TileGeometry, TileGeometryError, TileReport, TiledError, TiledInput,
    TiledOutput, TiledParams, DEFAULT_HALO,
};
use crate::image::{ImageMethod, ImagePlane, NonFinitePolicy, UniformEstimate, WaveletParams};

use super::{in_range, ImageParams, JobError, UniformJob};

/// The tiles of a tiled fit (`None`: the default).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TileOptions {
    /// Tile side in pixels (at least 1).
    pub tile: usize,
    /// Halo in pixels, at most the tile (default [`DEFAULT_HALO`], clipped to the tile,
    /// said in the notes).
    pub halo: Option<usize>,
    /// Tiles fitted at once, at least 1 (default [`TiledParams`]'s).
    pub workers: Option<usize>,
    /// An existing folder for a sample file's band files (default: the system's temporary
    /// folder).
    pub scratch: Option<PathBuf>,
}

/// A validated tiled fit (module docs).
#[derive(Debug, Clone)]
pub struct TiledJob {
    geometry: TileGeometry,
    wavelet: WaveletParams,
    tiled: TiledParams,
    clipped_halo: bool,
    /// No pixel estimate was asked for: the tiles make the fit's box pixels, where the
    /// untiled job's default is `auto` (said in the notes).
    fit_pixels_by_default: bool,
}

/// What a [`TiledJob`] made.
#[derive(Debug)]
pub struct TiledRun {
    /// The pixels and the report of every tile.
    pub output: TiledOutput,
    /// The decisions and what happened on the way, in words.
    pub notes: Vec<String>,
}

impl TiledJob {
    /// Validates a tiled fit of `plane` by `params` (the uniform job's ranges,
    /// [`UniformJob::new`]): the fit's global method only (each tile is the global solve of
    /// its window), the fit's box pixels only, no dropping of non-finite samples (the tiles
    /// read the samples in chunks and refuse them); the tile, halo, workers and scratch
    /// folder checked. Allocates nothing.
    pub fn new(
        plane: ImagePlane,
        params: &ImageParams,
        tiles: &TileOptions,
        nonfinite: NonFinitePolicy,
    ) -> Result<TiledJob, JobError> {
        let job = UniformJob::new(plane, params)?;
        if params.method != ImageMethod::Wavelet {
            return Err(JobError::Conflict {
                first: Param::Tile,
                second: Param::Method,
                reason: "fits each tile by the global solve of its window, the fit's default \
                         method",
            });
        }
        if params.pixels.is_some_and(|p| p != UniformEstimate::Fit) {
            return Err(JobError::Conflict {
                first: Param::Pixels,
                second: Param::Tile,
                reason: "is not computed by the tiled fit, which makes the fit's box pixels",
            });
        }
        if nonfinite == NonFinitePolicy::Drop {
            return Err(JobError::TilesKeepNonFinite);
        }
        let halo = tiles.halo.unwrap_or(DEFAULT_HALO.min(tiles.tile));
        let geometry = TileGeometry::new(plane, tiles.tile, halo).map_err(|e| {
            let param = match e {
                TileGeometryError::HaloLargerThanTile { .. } => Param::Halo,
                _ => Param::Tile,
            };
            JobError::TileGrid {
                param,
                source: TiledError::from(crate::image::tiles::TileError::from(e)),
            }
        })?;
        let defaults = TiledParams::default();
        let workers = match tiles.workers {
            None => defaults.workers,
            Some(n) => in_range(
                Param::Workers,
                n,
                n >= 1,
                ": give at least 1 (tiles fitted at once)",
            )?,
        };
        if let Some(dir) = tiles.scratch.as_ref().filter(|d| !d.is_dir()) {
            return Err(JobError::OutOfRange {
                param: Param::Scratch,
                value: format!("`{}`", dir.display()),
                rule: " is not a folder: give an existing folder with room for about the \
                       input's size",
            });
        }
        Ok(TiledJob {
            geometry,
            wavelet: *job.wavelet(),
            tiled: TiledParams {
                workers,
                scratch: tiles.scratch.clone(),
                ..defaults
            },
            clipped_halo: tiles.halo.is_none() && tiles.tile < DEFAULT_HALO,
            fit_pixels_by_default: params.pixels.is_none(),
        })
    }

    /// The tile grid.
    pub fn geometry(&self) -> &TileGeometry {
        &self.geometry
    }

    /// The fit's parameters, defaults filled in.
    pub fn wavelet(&self) -> &WaveletParams {
        &self.wavelet
    }

    /// Fits `input` tile by tile (`progress` is told each tile as it is done), then says
    /// what was decided and what happened: the halo clipped to the tile, tiles with
    /// functions pinned to 0 or pivots replaced, samples spilled to band files.
    pub fn run(
        &self,
        input: TiledInput,
        progress: &(dyn Fn(&TileReport) + Sync),
    ) -> Result<TiledRun, JobError> {
        let output = reconstruct_tiled(input, &self.geometry, &self.wavelet, &self.tiled, progress)
            .map_err(JobError::Tiled)?;
        let r = &output.report;
        let mut notes = Vec::new();
        if self.clipped_halo {
            notes.push(format!(
                "halo {}: the default halo {DEFAULT_HALO} clipped to the tile size (a halo is \
                 at most one tile)",
                r.tile
            ));
        }
        if self.fit_pixels_by_default {
            notes.push(
                "pixels: the fit's box pixels (the tiled fit makes only these; the untiled \
                 default is `auto`, a per-pixel choice by estimated risk, so the two images \
                 differ by more than the tiling)"
                    .to_string(),
            );
        }
        notes.extend(pinned_note(&r.tiles));
        if let Some(spill) = &r.spill {
            notes.push(format!(
                "spilled {} sample rows ({}) into {} band files in {} ({:.3} s), removed after \
                 the fit",
                spill.rows,
                crate::resources::format_bytes(spill.bytes as f64),
                spill.bands,
                spill.folder.display(),
                spill.seconds
            ));
        }
        Ok(TiledRun { output, notes })
    }
}

/// One line for the tiles with functions pinned to 0 or pivots replaced: how many, the totals
/// and the three tiles with the most (a 4096² image has a thousand tiles).
fn pinned_note(tiles: &[TileReport]) -> Option<String> {
    let mut hit: Vec<_> = tiles
        .iter()
        .filter(|t| t.unsampled > 0 || t.replaced_pivots > 0)
        .collect();
    if hit.is_empty() {
        return None;
    }
    let unsampled: usize = hit.iter().map(|t| t.unsampled).sum();
    let replaced: usize = hit.iter().map(|t| t.replaced_pivots).sum();
    hit.sort_by_key(|t| std::cmp::Reverse(t.unsampled + t.replaced_pivots));
    let most: Vec<String> = hit
        .iter()
        .take(3)
        .map(|t| {
            format!(
                "tile {} (pixels {}): {} + {}",
                t.tile, t.interior, t.unsampled, t.replaced_pivots
            )
        })
        .collect();
    Some(format!(
        "{} of {} tiles have functions without samples pinned to 0 ({unsampled} in all) or \
         Cholesky pivots replaced ({replaced} in all); the most (pinned + replaced): {}",
        hit.len(),
        tiles.len(),
        most.join(", ")
    ))
}
