//! The samples of a sample file sorted into **bands of tile rows on disk** in one pass, so
//! that the tiled fit reads its input a fixed number of times whatever the image height.
//!
//! Band `ty` holds every sample whose `y` lies in the rows of the windows of tile row `ty`,
//! `[ty T - H_a, (ty + 1) T + H_a]` (a sample within `H_a` of a band edge goes to both
//! bands: with `H_a <= T` at most three); each sample is appended to its bands' files in the
//! order of the input, as `2 + c` little-endian `f64` (exact for float32 and float64
//! inputs). Reading band `ty` back gives the samples of that band in input order, the order
//! the band pass over the input would give, so the tiles see the same samples in the same
//! order and the image is the same bits. The files live in a fresh folder that is removed
//! when the [`BandSpill`] is dropped (after the fit, or on any error).

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use serde::Serialize;
use thiserror::Error;

use super::geometry::TileGeometry;

/// Writing or reading the band files failed.
#[derive(Debug, Error)]
#[error(
    "the band files in `{}` (about {needed} bytes): {source}; free space there or choose \
     another scratch folder ({} DIR)",
    .folder.display(),
    crate::error::Fix::Set(crate::error::Param::Scratch)
)]
pub struct ScratchError {
    /// The scratch folder.
    pub folder: PathBuf,
    /// Bytes the band files need (0 when reading).
    pub needed: u64,
    /// The operating system's error.
    pub source: std::io::Error,
}

/// What [`BandSpill::write`]'s source calls with each chunk: positions `x`, `y` and the
/// values per channel.
pub type BandSink<'a, E> = dyn FnMut(&[f64], &[f64], &[&[f64]]) -> Result<(), E> + 'a;

/// What the spill wrote.
#[derive(Clone, Debug, Serialize)]
pub struct SpillReport {
    /// The scratch folder (removed after the fit).
    pub folder: PathBuf,
    /// Band files written (one per tile row).
    pub bands: usize,
    /// Sample rows written over all bands (samples near a band edge count twice).
    pub rows: usize,
    /// Bytes written.
    pub bytes: u64,
    /// Seconds of the spill pass.
    pub seconds: f64,
}

/// The band files of one tiled fit; the folder is removed on drop.
pub struct BandSpill {
    folder: PathBuf,
    columns: usize,
    rows: Vec<usize>,
}

impl Drop for BandSpill {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.folder);
    }
}

/// A failure writing or reading the scratch files, naming the folder and the way out.
fn scratch_error(folder: &Path, needed: u64, source: std::io::Error) -> ScratchError {
    ScratchError {
        folder: folder.to_path_buf(),
        needed,
        source,
    }
}

impl BandSpill {
    /// Writes the samples that `source` hands its sink, chunk by chunk (`channels` channels,
    /// `m` rows validated by the counting pass), into one file per band in a fresh folder
    /// under `parent`.
    pub fn write<E: From<ScratchError>>(
        geometry: &TileGeometry,
        channels: usize,
        m: usize,
        parent: &Path,
        source: impl FnOnce(&mut BandSink<'_, E>) -> Result<(), E>,
    ) -> Result<(Self, SpillReport), E> {
        let t0 = std::time::Instant::now();
        let (_, ny) = geometry.grid();
        let columns = 2 + channels;
        // upper bound of the bytes, for the message if the disk fills
        let overlap = 1.0 + 2.0 * geometry.halo as f64 / geometry.tile as f64;
        let needed = (m as f64 * overlap * columns as f64 * 8.0) as u64;
        let folder = unique_folder(parent);
        std::fs::create_dir_all(&folder).map_err(|e| scratch_error(&folder, needed, e))?;
        let mut spill = Self {
            folder,
            columns,
            rows: vec![0; ny],
        };
        let mut files = (0..ny)
            .map(|ty| {
                File::create(spill.band_path(ty))
                    .map(|f| BufWriter::with_capacity(1 << 18, f))
                    .map_err(|e| scratch_error(&spill.folder, needed, e))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let nx = geometry.grid().0;
        let mut row = Vec::with_capacity(columns * 8);
        let folder = spill.folder.clone();
        let rows = &mut spill.rows;
        source(&mut |xs, ys, values| {
            for i in 0..xs.len() {
                row.clear();
                row.extend_from_slice(&xs[i].to_le_bytes());
                row.extend_from_slice(&ys[i].to_le_bytes());
                for v in values {
                    row.extend_from_slice(&v[i].to_le_bytes());
                }
                let (lo, hi) = geometry.rows_of(ys[i]);
                for ty in lo.saturating_sub(1)..(hi + 2).min(ny) {
                    let band = geometry.window(ty * nx);
                    if (band.y0 as f64..=band.y1 as f64).contains(&ys[i]) {
                        files[ty]
                            .write_all(&row)
                            .map_err(|e| scratch_error(&folder, needed, e))?;
                        rows[ty] += 1;
                    }
                }
            }
            Ok(())
        })?;
        for f in &mut files {
            f.flush().map_err(|e| scratch_error(&folder, needed, e))?;
        }
        let written: usize = spill.rows.iter().sum();
        let report = SpillReport {
            folder: spill.folder.clone(),
            bands: ny,
            rows: written,
            bytes: (written * columns * 8) as u64,
            seconds: t0.elapsed().as_secs_f64(),
        };
        Ok((spill, report))
    }

    fn band_path(&self, ty: usize) -> PathBuf {
        self.folder.join(format!("band-{ty:05}.f64"))
    }

    /// Calls `each(xs, ys, values)` on chunks of at most `chunk_rows` samples of band `ty`,
    /// in input order.
    pub fn read_band<E: From<ScratchError>>(
        &self,
        ty: usize,
        chunk_rows: usize,
        mut each: impl FnMut(&[f64], &[f64], &[&[f64]]) -> Result<(), E>,
    ) -> Result<(), E> {
        let path = self.band_path(ty);
        let file = File::open(&path).map_err(|e| scratch_error(&self.folder, 0, e))?;
        let mut file = BufReader::with_capacity(1 << 20, file);
        let k = self.columns;
        let chunk_rows = chunk_rows.max(1);
        let mut raw = Vec::new();
        let mut columns = vec![Vec::new(); k];
        let total = self.rows[ty];
        let mut done = 0;
        while done < total {
            let n = chunk_rows.min(total - done);
            raw.resize(n * k * 8, 0);
            file.read_exact(&mut raw)
                .map_err(|e| scratch_error(&self.folder, 0, e))?;
            for c in &mut columns {
                c.clear();
            }
            for (t, b) in raw.chunks_exact(8).enumerate() {
                columns[t % k].push(f64::from_le_bytes(b.try_into().expect("8 bytes")));
            }
            let values: Vec<&[f64]> = columns[2..].iter().map(Vec::as_slice).collect();
            each(&columns[0], &columns[1], &values)?;
            done += n;
        }
        Ok(())
    }
}

/// `parent/.rkwave-tiles-<pid>-<n>`: a folder no other run uses.
fn unique_folder(parent: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    parent.join(format!(".rkwave-tiles-{}-{n}", std::process::id()))
}
