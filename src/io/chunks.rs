//! Sample files read in chunks of rows, never whole: a `.npy` file's header is parsed and
//! checked once (`super::npy`), then its rows are decoded a chunk at a time (C order: one
//! sequential read per chunk; Fortran order: one read per column per chunk); a CSV file is
//! cut at line ends into blocks parsed by the whole-file parser ([`super::csv::parse_csv`])
//! with the header line in front, its errors' line and row numbers moved to the file's.
//! Every value is checked finite, with the same typed errors as the whole-file readers.
//!
//! One reader serves both streamed paths: the tiled image plane reads the whole file in
//! order ([`SampleChunkReader::for_each_chunk`]); the streamed 1D fit reads ranges of rows
//! ([`SampleChunkReader::read_rows`]: a `.npy` range starts with one seek, a CSV range after
//! the rows before it are skipped unparsed) through [`CountedChunks`], its
//! [`SampleChunks`] view.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::ops::Range;
use std::path::{Path, PathBuf};

use super::table::{IoError, SampleSet};
use crate::reconstruct::stream::{ChunkSink, SampleChunks, StreamError};

/// Rows per chunk of the streamed paths: 64 Ki rows of a few columns is a few MB.
pub const CHUNK_ROWS: usize = 1 << 16;

/// A sample file opened for reading in chunks.
#[derive(Debug)]
pub struct SampleChunkReader {
    file: PathBuf,
    kind: Kind,
}

#[derive(Debug)]
enum Kind {
    Npy {
        data_start: u64,
        rows: usize,
        columns: usize,
        size: usize,
        big_endian: bool,
        fortran: bool,
    },
    Csv,
}

fn read_error(file: &Path, source: std::io::Error) -> IoError {
    IoError::Read {
        file: file.to_path_buf(),
        source,
    }
}

impl SampleChunkReader {
    /// Opens `path` (`.npy` by its extension, CSV otherwise) and checks a `.npy` header.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let file = path.to_path_buf();
        if !super::table::is_npy(path) {
            File::open(path).map_err(|e| read_error(path, e))?;
            return Ok(Self {
                file,
                kind: Kind::Csv,
            });
        }
        let mut f = File::open(path).map_err(|e| read_error(path, e))?;
        let total = f.metadata().map_err(|e| read_error(path, e))?.len() as usize;
        // magic, version and header length, then the header (at most the file)
        let mut prefix = vec![0u8; total.min(12)];
        f.read_exact(&mut prefix).map_err(|e| read_error(path, e))?;
        let header_len = match (prefix.get(6), prefix.len()) {
            (Some(1), n) if n >= 10 => 10 + u16::from_le_bytes([prefix[8], prefix[9]]) as usize,
            (Some(2 | 3), 12) => {
                12 + u32::from_le_bytes([prefix[8], prefix[9], prefix[10], prefix[11]]) as usize
            }
            _ => 0,
        };
        let want = header_len.min(total);
        if want > prefix.len() {
            let mut rest = vec![0u8; want - prefix.len()];
            f.read_exact(&mut rest).map_err(|e| read_error(path, e))?;
            prefix.extend_from_slice(&rest);
        }
        let layout = super::npy::npy_layout(&prefix, total, path)?;
        Ok(Self {
            file,
            kind: Kind::Npy {
                data_start: layout.data_start as u64,
                rows: layout.m,
                columns: layout.k,
                size: layout.size,
                big_endian: layout.big_endian,
                fortran: layout.fortran,
            },
        })
    }

    /// Rows of a `.npy` file (`None` for CSV: known after a pass).
    pub fn rows(&self) -> Option<usize> {
        match self.kind {
            Kind::Npy { rows, .. } => Some(rows),
            Kind::Csv => None,
        }
    }

    /// Calls `each(first_row, chunk)` on consecutive chunks of about `chunk_rows` rows, in
    /// file order, each a [`SampleSet`] (column 0 the positions); `names(k - 1)` names the
    /// columns after the first in errors.
    pub fn for_each_chunk<E: From<IoError>>(
        &self,
        chunk_rows: usize,
        names: impl Fn(usize) -> Vec<String>,
        each: impl FnMut(usize, SampleSet) -> Result<(), E>,
    ) -> Result<(), E> {
        self.read_rows(0..usize::MAX, chunk_rows, names, each)
    }

    /// [`Self::for_each_chunk`] on the rows `rows` alone (cut at the end of the file).
    pub fn read_rows<E: From<IoError>>(
        &self,
        rows: Range<usize>,
        chunk_rows: usize,
        names: impl Fn(usize) -> Vec<String>,
        mut each: impl FnMut(usize, SampleSet) -> Result<(), E>,
    ) -> Result<(), E> {
        let chunk_rows = chunk_rows.max(1);
        match self.kind {
            Kind::Npy {
                data_start,
                rows: rows_in_file,
                columns,
                size,
                big_endian,
                fortran,
            } => {
                let path = &self.file;
                let f = File::open(path).map_err(|e| read_error(path, e))?;
                let mut f = BufReader::with_capacity(1 << 20, f);
                let names = names(columns - 1);
                let decode = |b: &[u8]| super::npy::decode(b, big_endian);
                let mut buf = Vec::new();
                let range = rows.start.min(rows_in_file)..rows.end.min(rows_in_file);
                let first = range.start;
                for r0 in range.clone().step_by(chunk_rows) {
                    let n = chunk_rows.min(range.end - r0);
                    let mut cols = vec![Vec::with_capacity(n); columns];
                    if fortran {
                        buf.resize(n * size, 0);
                        for (j, col) in cols.iter_mut().enumerate() {
                            let at = data_start + ((j * rows_in_file + r0) * size) as u64;
                            f.seek(SeekFrom::Start(at))
                                .and_then(|_| f.read_exact(&mut buf))
                                .map_err(|e| read_error(path, e))?;
                            col.extend(buf.chunks_exact(size).map(decode));
                        }
                    } else {
                        buf.resize(n * columns * size, 0);
                        if r0 == first {
                            let at = data_start + (first * columns * size) as u64;
                            f.seek(SeekFrom::Start(at))
                                .map_err(|e| read_error(path, e))?;
                        }
                        f.read_exact(&mut buf).map_err(|e| read_error(path, e))?;
                        for (t, b) in buf.chunks_exact(size).enumerate() {
                            cols[t % columns].push(decode(b));
                        }
                    }
                    for (j, col) in cols.iter().enumerate() {
                        if let Some((i, &v)) = col.iter().enumerate().find(|(_, v)| !v.is_finite())
                        {
                            return Err(IoError::non_finite_cell(path, r0 + i, j, &names, v).into());
                        }
                    }
                    let positions = cols.remove(0);
                    let set = SampleSet {
                        positions,
                        values: cols,
                        names: names.clone(),
                    };
                    each(r0, set)?;
                }
                Ok(())
            }
            Kind::Csv => self.csv_chunks(rows, chunk_rows, each),
        }
    }

    /// CSV: the rows before `rows` skipped unparsed, then blocks of `chunk_rows` rows, each
    /// parsed with the header in front.
    fn csv_chunks<E: From<IoError>>(
        &self,
        rows: Range<usize>,
        chunk_rows: usize,
        mut each: impl FnMut(usize, SampleSet) -> Result<(), E>,
    ) -> Result<(), E> {
        let path = &self.file;
        let f = File::open(path).map_err(|e| read_error(path, e))?;
        let mut lines = BufReader::with_capacity(1 << 20, f).split(b'\n');
        // the header: the first line that is not blank or a comment
        let mut header = Vec::new();
        let mut header_line = 0;
        for raw in lines.by_ref() {
            let raw = raw.map_err(|e| read_error(path, e))?;
            header_line += 1;
            let text = String::from_utf8_lossy(&raw);
            let t = text.trim().trim_start_matches('\u{feff}');
            if !t.is_empty() && !t.starts_with('#') {
                header = raw;
                break;
            }
        }
        if header.is_empty() {
            return Err(IoError::Empty {
                file: path.to_path_buf(),
            }
            .into());
        }
        let (mut line, mut row) = (header_line, 0usize);
        while row < rows.start {
            let Some(raw) = lines.next() else { break };
            let raw = raw.map_err(|e| read_error(path, e))?;
            line += 1;
            if is_data_line(&raw) {
                row += 1;
            }
        }
        loop {
            let mut block = header.clone();
            let mut count = 0;
            let mut rows_in = 0;
            let chunk_rows = chunk_rows.min(rows.end.saturating_sub(row));
            if chunk_rows == 0 {
                return Ok(());
            }
            for raw in lines.by_ref() {
                let raw = raw.map_err(|e| read_error(path, e))?;
                count += 1;
                if is_data_line(&raw) {
                    rows_in += 1;
                }
                block.push(b'\n');
                block.extend_from_slice(&raw);
                if rows_in >= chunk_rows {
                    break;
                }
            }
            if rows_in == 0 {
                if row == 0 {
                    return Err(IoError::Empty {
                        file: path.to_path_buf(),
                    }
                    .into());
                }
                return Ok(());
            }
            // lines of the block: 1 is the header, 2.. are file lines `line + 1..`
            let set =
                super::csv::parse_csv(&block, path).map_err(|e| shift_lines(e, line - 1, row))?;
            each(row, set)?;
            line += count;
            row += rows_in;
        }
    }
}

impl SampleChunkReader {
    /// Whether the file is a `.npy` file (else CSV).
    pub fn is_npy(&self) -> bool {
        matches!(self.kind, Kind::Npy { .. })
    }

    /// The reader with its rows, channel names and (for CSV) position bounds known: a `.npy`
    /// file's from its header; a CSV file's from one validating pass over it.
    pub fn counted(self) -> Result<CountedChunks, IoError> {
        if let Kind::Npy { rows, columns, .. } = self.kind {
            return Ok(CountedChunks {
                names: SampleSet::default_names(columns - 1),
                rows,
                bounds: None,
                reader: self,
            });
        }
        let (mut rows, mut names, mut bounds) = (0, Vec::new(), (f64::INFINITY, f64::NEG_INFINITY));
        self.for_each_chunk(CHUNK_ROWS, SampleSet::default_names, |_, set| {
            rows += set.len();
            names = set.names;
            bounds = extend_bounds(bounds, &set.positions);
            Ok::<(), IoError>(())
        })?;
        Ok(CountedChunks {
            reader: self,
            rows,
            names,
            bounds: Some(bounds),
        })
    }
}

/// `(lo, hi)` widened by the positions `xs`.
fn extend_bounds((lo, hi): (f64, f64), xs: &[f64]) -> (f64, f64) {
    xs.iter()
        .fold((lo, hi), |(lo, hi), &x| (lo.min(x), hi.max(x)))
}

/// A sample file whose rows and channels are known, read in ranges of rows: the
/// [`SampleChunks`] of the streamed 1D fit ([`crate::reconstruct::stream::fit_streamed`]).
#[derive(Debug)]
pub struct CountedChunks {
    reader: SampleChunkReader,
    rows: usize,
    names: Vec<String>,
    bounds: Option<(f64, f64)>,
}

impl CountedChunks {
    /// Samples `m`.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Value channels.
    pub fn value_channels(&self) -> usize {
        self.names.len()
    }

    /// Names of the value channels (a CSV header's, or the defaults of
    /// [`SampleSet::default_names`]).
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// The file read.
    pub fn reader(&self) -> &SampleChunkReader {
        &self.reader
    }

    /// Whether the bounds of the positions are known without a pass (a CSV file's, from the
    /// counting pass).
    pub fn knows_bounds(&self) -> bool {
        self.bounds.is_some()
    }

    /// The smallest and the largest position (a pass over a `.npy` file; a CSV file's from
    /// its counting pass).
    pub fn bounds(&self) -> Result<(f64, f64), IoError> {
        if let Some(b) = self.bounds {
            return Ok(b);
        }
        let mut bounds = (f64::INFINITY, f64::NEG_INFINITY);
        self.read_rows(0..self.rows, |xs, _| {
            bounds = extend_bounds(bounds, xs);
            Ok::<(), IoError>(())
        })?;
        Ok(bounds)
    }

    /// Calls `each(positions, values per channel)` on consecutive chunks of the rows `rows`.
    pub fn read_rows<E: From<IoError>>(
        &self,
        rows: Range<usize>,
        mut each: impl FnMut(&[f64], &[Vec<f64>]) -> Result<(), E>,
    ) -> Result<(), E> {
        let names = |_| self.names.clone();
        self.reader.read_rows(rows, CHUNK_ROWS, names, |_, set| {
            each(&set.positions, &set.values)
        })
    }
}

impl SampleChunks for CountedChunks {
    fn len(&self) -> usize {
        self.rows
    }
    fn channels(&self) -> usize {
        self.value_channels()
    }
    fn read(&self, rows: Range<usize>, each: &mut ChunkSink<'_>) -> Result<(), StreamError> {
        let out = self.read_rows(rows, |xs, vs| {
            let vs: Vec<&[f64]> = vs.iter().map(Vec::as_slice).collect();
            each(xs, &vs).map_err(ChunkError::Stream)
        });
        out.map_err(|e| match e {
            ChunkError::Io(e) => StreamError::Source(Box::new(e)),
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

/// Whether a CSV line holds a row (not blank, not a `#` comment).
fn is_data_line(raw: &[u8]) -> bool {
    let t = String::from_utf8_lossy(raw);
    let t = t.trim();
    !t.is_empty() && !t.starts_with('#')
}

/// A block's error with its line and row numbers moved by `lines` and `rows`.
fn shift_lines(e: IoError, lines: usize, rows: usize) -> IoError {
    match e {
        IoError::ColumnCount {
            file,
            line,
            row,
            expected,
            found,
        } => IoError::ColumnCount {
            file,
            line: line + lines,
            row: row + rows,
            expected,
            found,
        },
        IoError::NotANumber {
            file,
            line,
            row,
            column,
            name,
            field,
        } => IoError::NotANumber {
            file,
            line: line + lines,
            row: row + rows,
            column,
            name,
            field,
        },
        IoError::NonFinite {
            file,
            line,
            row,
            column,
            name,
            value,
        } => IoError::NonFinite {
            file,
            line: line.map(|l| l + lines),
            row: row + rows,
            column,
            name,
            value,
        },
        IoError::NotUtf8 { file, line } => IoError::NotUtf8 {
            file,
            line: line + lines,
        },
        other => other,
    }
}
