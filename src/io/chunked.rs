//! A `.npy` sample file read in chunks of rows, never whole
//! ([`crate::reconstruct::stream::SampleChunks`]).
//!
//! The header gives the shape `(m, k)`, the dtype and the order, so row `i` of a C-order file
//! starts at byte `data_start + i k size`: any range of rows is read by one seek and one
//! sequential read (a Fortran-order file: one read per column). The checks are those of
//! [`super::parse_npy`] (dtype, shape, data length against the file's length, finite values),
//! the header's at [`NpyChunks::open`], each value's as its chunk is read.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::ops::Range;
use std::path::{Path, PathBuf};

use super::npy::{npy_layout, NpyLayout};
use super::{IoError, SampleSet};
use crate::reconstruct::stream::{ChunkSink, SampleChunks, StreamError};

/// Bytes of a file read to find its header (a `.npy` header is at most a few hundred bytes;
/// NumPy pads it to 64).
const HEADER_BYTES: usize = 1 << 16;

/// Rows per chunk: 64 Ki rows of a few columns is a few MB.
pub const CHUNK_ROWS: usize = 1 << 16;

/// A `.npy` sample file (`m x (1 + channels)`, column 0 the positions) opened for reading in
/// chunks.
pub struct NpyChunks {
    path: PathBuf,
    layout: NpyLayout,
    names: Vec<String>,
    chunk: usize,
}

impl NpyChunks {
    /// Opens `path` and checks its header and length.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let read_err = |source| IoError::Read {
            file: path.to_path_buf(),
            source,
        };
        let mut file = File::open(path).map_err(read_err)?;
        let total = file.metadata().map_err(read_err)?.len() as usize;
        let mut prefix = vec![0; total.min(HEADER_BYTES)];
        file.read_exact(&mut prefix).map_err(read_err)?;
        let layout = npy_layout(&prefix, total, path)?;
        Ok(Self {
            path: path.to_path_buf(),
            names: SampleSet::default_names(layout.k - 1),
            layout,
            chunk: CHUNK_ROWS,
        })
    }

    /// The same reader with `rows` rows per chunk (at least 1).
    pub fn with_chunk(mut self, rows: usize) -> Self {
        self.chunk = rows.max(1);
        self
    }

    /// Samples `m`.
    pub fn rows(&self) -> usize {
        self.layout.m
    }

    /// Value channels.
    pub fn value_channels(&self) -> usize {
        self.layout.k - 1
    }

    /// Channel names (the defaults of [`SampleSet::default_names`]).
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Calls `each` with the rows `rows` in chunks, in order: positions and one vector of
    /// values per channel, every value checked finite.
    pub fn read_rows<E: From<IoError>>(
        &self,
        rows: Range<usize>,
        mut each: impl FnMut(&[f64], &[Vec<f64>]) -> Result<(), E>,
    ) -> Result<(), E> {
        let l = &self.layout;
        let read_err = |source| IoError::Read {
            file: self.path.clone(),
            source,
        };
        let mut file = File::open(&self.path).map_err(read_err)?;
        let mut raw = Vec::new();
        let mut columns = vec![Vec::new(); l.k];
        for start in rows.clone().step_by(self.chunk) {
            let n = self.chunk.min(rows.end - start);
            raw.resize(n * l.k * l.size, 0);
            if l.fortran {
                let width = n * l.size;
                for j in 0..l.k {
                    let at = l.data_start + (j * l.m + start) * l.size;
                    file.seek(SeekFrom::Start(at as u64)).map_err(read_err)?;
                    file.read_exact(&mut raw[j * width..(j + 1) * width])
                        .map_err(read_err)?;
                }
            } else {
                let at = l.data_start + start * l.k * l.size;
                file.seek(SeekFrom::Start(at as u64)).map_err(read_err)?;
                file.read_exact(&mut raw).map_err(read_err)?;
            }
            for (j, col) in columns.iter_mut().enumerate() {
                col.clear();
                col.extend((0..n).map(|i| {
                    let cell = if l.fortran { j * n + i } else { i * l.k + j };
                    self.value(&raw[cell * l.size..(cell + 1) * l.size])
                }));
                if let Some((i, &v)) = col.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                    return Err(
                        IoError::non_finite_cell(&self.path, start + i, j, &self.names, v).into(),
                    );
                }
            }
            each(&columns[0], &columns[1..])?;
        }
        Ok(())
    }

    /// One stored value, widened to f64 (exact for float32).
    fn value(&self, b: &[u8]) -> f64 {
        match (self.layout.size, self.layout.big_endian) {
            (8, false) => f64::from_le_bytes(b.try_into().expect("8 bytes")),
            (8, true) => f64::from_be_bytes(b.try_into().expect("8 bytes")),
            (_, false) => f64::from(f32::from_le_bytes(b.try_into().expect("4 bytes"))),
            (_, true) => f64::from(f32::from_be_bytes(b.try_into().expect("4 bytes"))),
        }
    }

    /// The smallest and the largest position (one pass over the file).
    pub fn bounds(&self) -> Result<(f64, f64), IoError> {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        self.read_rows(0..self.rows(), |xs, _| {
            for &x in xs {
                lo = lo.min(x);
                hi = hi.max(x);
            }
            Ok::<(), IoError>(())
        })?;
        Ok((lo, hi))
    }
}

impl SampleChunks for NpyChunks {
    fn len(&self) -> usize {
        self.rows()
    }
    fn channels(&self) -> usize {
        self.value_channels()
    }
    fn read(&self, rows: Range<usize>, each: &mut ChunkSink<'_>) -> Result<(), StreamError> {
        let wrap = |e: IoError| StreamError::Source(Box::new(e));
        self.read_rows(rows, |xs, vs| {
            let vs: Vec<&[f64]> = vs.iter().map(Vec::as_slice).collect();
            each(xs, &vs).map_err(ChunkError::Stream)
        })
        .map_err(|e| match e {
            ChunkError::Io(e) => wrap(e),
            ChunkError::Stream(e) => e,
        })
    }
}

/// A read failure or the consumer's error.
enum ChunkError {
    Io(IoError),
    Stream(StreamError),
}

impl From<IoError> for ChunkError {
    fn from(e: IoError) -> Self {
        Self::Io(e)
    }
}
