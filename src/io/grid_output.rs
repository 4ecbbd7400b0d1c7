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

use super::output::{persist, temporary, OutputError};
use super::table::IoError;

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

/// The open file and its format (for `.npy` the header is written; the rows follow as
/// little-endian `float64`, C order, which is what the header declares).
enum Sink {
    Csv(BufWriter<File>),
    Npy(BufWriter<File>),
}

/// Writes `rows` grid rows of `x` and the channels, block by block.
pub struct GridWriter {
    path: PathBuf,
    tmp: PathBuf,
    /// `None` once finished; a writer dropped before [`GridWriter::finish`] removes its
    /// temporary file (the target is never touched).
    sink: Option<Sink>,
    channels: usize,
    rows: usize,
    written: usize,
    line: Vec<u8>,
}

impl GridWriter {
    /// Starts the file for `rows` rows of `x` and one column per channel name: the rows go to
    /// a temporary file beside `path`, moved into place by [`GridWriter::finish`].
    pub fn create(path: &Path, names: &[String], rows: usize) -> Result<Self, IoError> {
        let tmp = temporary(path);
        let write_err = |source: std::io::Error| IoError::Write {
            file: path.to_path_buf(),
            source,
        };
        if names.is_empty() {
            return Err(IoError::InvalidSampleSet {
                problem: "no value channels; a grid file needs at least one".to_string(),
            });
        }
        let file = BufWriter::with_capacity(BUFFER, File::create(&tmp).map_err(write_err)?);
        let sink = match GridFormat::from_path(path) {
            GridFormat::Npy => Sink::Npy(
                npyz::WriteOptions::<f64>::new()
                    .dtype(npyz::DType::new_scalar(
                        "<f8".parse().expect("a valid NumPy type string"),
                    ))
                    .shape(&[rows as u64, 1 + names.len() as u64])
                    .writer(file)
                    .write_header_only()
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
            tmp,
            sink: Some(sink),
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
        // The whole block is formatted into one buffer and written at once.
        let npy = matches!(self.sink, Some(Sink::Npy(_)));
        let mut buf = zmij::Buffer::new();
        self.line.clear();
        for (i, &x) in xs.iter().enumerate() {
            let row = std::iter::once(x).chain(values.iter().map(|v| v[i]));
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
                if npy {
                    self.line.extend_from_slice(&v.to_le_bytes());
                } else {
                    if j > 0 {
                        self.line.push(b',');
                    }
                    self.line.extend_from_slice(buf.format_finite(v).as_bytes());
                }
            }
            if !npy {
                self.line.push(b'\n');
            }
        }
        let (Sink::Npy(w) | Sink::Csv(w)) = self.sink.as_mut().expect("not finished");
        w.write_all(&self.line).map_err(write_err)?;
        self.written += xs.len();
        Ok(())
    }

    /// Flushes the rows and moves the file into place; without `overwrite`, an existing target
    /// is left alone (an error). Every declared row must have been written.
    pub fn finish(mut self, overwrite: bool) -> Result<(), OutputError> {
        assert_eq!(self.written, self.rows, "every declared row written");
        let (Sink::Npy(mut w) | Sink::Csv(mut w)) = self.sink.take().expect("finished once");
        let flushed = w.flush();
        if let Err(source) = flushed {
            let _ = std::fs::remove_file(&self.tmp);
            return Err(OutputError::NotWritable {
                file: self.path.clone(),
                source,
            });
        }
        persist(&self.tmp, &self.path, overwrite)
    }
}

impl Drop for GridWriter {
    fn drop(&mut self) {
        if self.sink.take().is_some() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
