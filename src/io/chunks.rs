//! Sample files read in chunks of rows, never whole: a `.npy` file's header is parsed and
//! checked once ([`super::npy`]), then its rows are decoded a chunk at a time (C order: one
//! sequential read per chunk; Fortran order: one read per column per chunk); a CSV file is
//! cut at line ends into blocks parsed by the whole-file parser ([`super::csv::parse_csv`])
//! with the header line in front, its errors' line and row numbers moved to the file's.
//! Every value is checked finite, with the same typed errors as the whole-file readers.

use std::fs::File;
use std::io::{BufRead, BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::{IoError, SampleSet};

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
        if !super::is_npy(path) {
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
        mut each: impl FnMut(usize, SampleSet) -> Result<(), E>,
    ) -> Result<(), E> {
        let chunk_rows = chunk_rows.max(1);
        match self.kind {
            Kind::Npy {
                data_start,
                rows,
                columns,
                size,
                big_endian,
                fortran,
            } => {
                let path = &self.file;
                let f = File::open(path).map_err(|e| read_error(path, e))?;
                let mut f = BufReader::with_capacity(1 << 20, f);
                let names = names(columns - 1);
                let decode = |b: &[u8]| -> f64 {
                    match (size, big_endian) {
                        (8, false) => f64::from_le_bytes(b.try_into().expect("8 bytes")),
                        (8, true) => f64::from_be_bytes(b.try_into().expect("8 bytes")),
                        (_, false) => f32::from_le_bytes(b.try_into().expect("4 bytes")) as f64,
                        (_, true) => f32::from_be_bytes(b.try_into().expect("4 bytes")) as f64,
                    }
                };
                let mut buf = Vec::new();
                for r0 in (0..rows).step_by(chunk_rows) {
                    let n = chunk_rows.min(rows - r0);
                    let mut cols = vec![Vec::with_capacity(n); columns];
                    if fortran {
                        buf.resize(n * size, 0);
                        for (j, col) in cols.iter_mut().enumerate() {
                            let at = data_start + ((j * rows + r0) * size) as u64;
                            f.seek(SeekFrom::Start(at))
                                .and_then(|_| f.read_exact(&mut buf))
                                .map_err(|e| read_error(path, e))?;
                            col.extend(buf.chunks_exact(size).map(decode));
                        }
                    } else {
                        buf.resize(n * columns * size, 0);
                        if r0 == 0 {
                            f.seek(SeekFrom::Start(data_start))
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
            Kind::Csv => self.csv_chunks(chunk_rows, each),
        }
    }

    /// CSV: blocks of `chunk_rows` lines after the header, each parsed with the header in
    /// front.
    fn csv_chunks<E: From<IoError>>(
        &self,
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
        loop {
            let mut block = header.clone();
            let mut count = 0;
            let mut rows_in = 0;
            for raw in lines.by_ref() {
                let raw = raw.map_err(|e| read_error(path, e))?;
                count += 1;
                let t = String::from_utf8_lossy(&raw);
                let t = t.trim();
                if !t.is_empty() && !t.starts_with('#') {
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
