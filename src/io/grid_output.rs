//! A reconstruction written while it is evaluated: rows `x, value_1, ..., value_C` go to the
//! file block by block, so the grid is never held whole.
//!
//! Two formats, chosen by the file name: `.npy` (NumPy, `float64`, C order, shape
//! `(G, 1 + C)`, through the `npyz` crate; `numpy.load` reads it back exactly) and CSV for
//! anything else (header `x,NAME...`, every number the shortest decimal that reads back to the
//! same `f64`, formatted by `zmij`).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use npyz::WriterBuilder;

use super::IoError;

/// Output buffer size: large writes, few system calls.
const BUFFER: usize = 1 << 20;

/// The format of a grid file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridFormat {
    /// Comma-separated text with a header.
    Csv,
    /// NumPy `.npy`, `float64`.
    Npy,
}

impl GridFormat {
    /// `.npy` (any case) for NumPy, CSV otherwise.
    pub fn from_path(path: &Path) -> Self {
        match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("npy") => Self::Npy,
            _ => Self::Csv,
        }
    }
}

enum Sink {
    Csv(BufWriter<File>),
    Npy(npyz::NpyWriter<f64, BufWriter<File>>),
}

/// Writes `rows` grid rows of `x` and the channels, block by block.
pub struct GridWriter {
    path: PathBuf,
    sink: Sink,
    channels: usize,
    rows: usize,
    written: usize,
    line: Vec<u8>,
}

impl GridWriter {
    /// Creates the file (replacing an existing one: the caller decides whether that is
    /// allowed) for `rows` rows of `x` and one column per channel name.
    pub fn create(path: &Path, names: &[String], rows: usize) -> Result<Self, IoError> {
        let write_err = |source: std::io::Error| IoError::Write {
            file: path.to_path_buf(),
            source,
        };
        if names.is_empty() {
            return Err(IoError::InvalidSampleSet {
                problem: "no value channels; a grid file needs at least one".to_string(),
            });
        }
        let file = BufWriter::with_capacity(BUFFER, File::create(path).map_err(write_err)?);
        let sink = match GridFormat::from_path(path) {
            GridFormat::Npy => Sink::Npy(
                npyz::WriteOptions::new()
                    .default_dtype()
                    .shape(&[rows as u64, 1 + names.len() as u64])
                    .writer(file)
                    .begin_nd()
                    .map_err(write_err)?,
            ),
            GridFormat::Csv => {
                for name in names {
                    if name.is_empty() || name.trim() != name || name.contains([',', '\n', '\r']) {
                        return Err(IoError::InvalidSampleSet {
                            problem: format!(
                                "the channel name `{name}` cannot be written to a CSV header; \
                                 use a non-empty name without commas, line breaks or \
                                 surrounding spaces"
                            ),
                        });
                    }
                }
                let mut file = file;
                writeln!(file, "x,{}", names.join(",")).map_err(write_err)?;
                Sink::Csv(file)
            }
        };
        Ok(Self {
            path: path.to_path_buf(),
            sink,
            channels: names.len(),
            rows,
            written: 0,
            line: Vec::with_capacity(64),
        })
    }

    /// Appends the rows `xs[i], values[0][i], ..., values[C-1][i]`. A NaN or infinite number
    /// is an error naming its row and column.
    pub fn write_block(&mut self, xs: &[f64], values: &[Vec<f64>]) -> Result<(), IoError> {
        assert_eq!(values.len(), self.channels, "one value vector per channel");
        assert!(
            values.iter().all(|v| v.len() == xs.len()),
            "one value per position"
        );
        assert!(
            self.written + xs.len() <= self.rows,
            "more rows than declared"
        );
        let file = &self.path;
        let write_err = |source: std::io::Error| IoError::Write {
            file: file.clone(),
            source,
        };
        let mut buf = zmij::Buffer::new();
        for (i, &x) in xs.iter().enumerate() {
            let row = std::iter::once(x).chain(values.iter().map(|v| v[i]));
            self.line.clear();
            for (j, v) in row.enumerate() {
                if !v.is_finite() {
                    return Err(IoError::NonFinite {
                        file: self.path.clone(),
                        line: None,
                        row: self.written + i + 1,
                        column: j + 1,
                        name: if j == 0 {
                            "x".to_string()
                        } else {
                            format!("value {j}")
                        },
                        value: v,
                    });
                }
                match &mut self.sink {
                    Sink::Npy(w) => w.push(&v).map_err(write_err)?,
                    Sink::Csv(_) => {
                        if j > 0 {
                            self.line.push(b',');
                        }
                        self.line.extend_from_slice(buf.format_finite(v).as_bytes());
                    }
                }
            }
            if let Sink::Csv(w) = &mut self.sink {
                self.line.push(b'\n');
                w.write_all(&self.line).map_err(write_err)?;
            }
        }
        self.written += xs.len();
        Ok(())
    }

    /// Flushes the file; every declared row must have been written.
    pub fn finish(self) -> Result<(), IoError> {
        assert_eq!(self.written, self.rows, "every declared row written");
        let write_err = |source: std::io::Error| IoError::Write {
            file: self.path.clone(),
            source,
        };
        match self.sink {
            Sink::Npy(w) => w.finish().map_err(write_err),
            Sink::Csv(mut w) => w.flush().map_err(write_err),
        }
    }
}
