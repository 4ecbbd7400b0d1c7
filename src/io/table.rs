//! The sample table and its errors, shared by every format: [`SampleSet`] (positions and
//! channels), [`IoError`] (what reading or writing one can go wrong with, and its kind), and
//! the byte helpers the CSV and `.npy` readers and writers go through. A leaf of `io`: the
//! formats depend on it, it depends on none of them.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::sampling::Domain;

/// Scattered samples: positions and one or more channels of values.
///
/// Row `i` is the sample `(positions[i], values[0][i], values[1][i], …)`;
/// `values` is channel-major. `names` holds one name per channel (the CSV
/// header names); writers use [`SampleSet::default_names`] when it is empty.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SampleSet {
    /// Sample positions `x_i`, in file order (not necessarily sorted).
    pub positions: Vec<f64>,
    /// Channel-major values: `values[c][i]` is channel `c` at `positions[i]`.
    pub values: Vec<Vec<f64>>,
    /// One name per channel, e.g. from the CSV header.
    pub names: Vec<String>,
}

impl SampleSet {
    /// Builds a sample set with the default channel names, checking that
    /// every channel has one value per position.
    pub fn new(positions: Vec<f64>, values: Vec<Vec<f64>>) -> Result<SampleSet, IoError> {
        let names = Self::default_names(values.len());
        let set = SampleSet {
            positions,
            values,
            names,
        };
        set.check()?;
        Ok(set)
    }

    /// Replaces the channel names (one per channel).
    pub fn with_names(mut self, names: Vec<String>) -> Result<SampleSet, IoError> {
        self.names = names;
        self.check()?;
        Ok(self)
    }

    /// The default channel names: `value` for one channel, otherwise
    /// `value1`, `value2`, ….
    pub fn default_names(channels: usize) -> Vec<String> {
        if channels == 1 {
            vec!["value".to_string()]
        } else {
            (1..=channels).map(|c| format!("value{c}")).collect()
        }
    }

    /// The number of value channels.
    pub fn channels(&self) -> usize {
        self.values.len()
    }

    /// The number of samples (rows).
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The values of channel `c`.
    ///
    /// # Panics
    /// If `c >= self.channels()`.
    pub fn channel(&self, c: usize) -> &[f64] {
        &self.values[c]
    }

    /// The smallest and largest position, or `None` when empty. NaN positions
    /// are ignored.
    pub fn bounds(&self) -> Option<(f64, f64)> {
        let mut it = self.positions.iter().copied().filter(|x| !x.is_nan());
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), x| (lo.min(x), hi.max(x))))
    }

    /// The channel names, or the defaults when `names` is empty.
    pub fn names_or_default(&self) -> Vec<String> {
        if self.names.is_empty() {
            Self::default_names(self.channels())
        } else {
            self.names.clone()
        }
    }

    /// Checks the shape: every channel has `len()` values and `names` is
    /// empty or has one name per channel.
    pub fn check(&self) -> Result<(), IoError> {
        for (c, v) in self.values.iter().enumerate() {
            if v.len() != self.len() {
                return Err(IoError::InvalidSampleSet {
                    problem: format!(
                        "channel {} has {} values but there are {} positions",
                        c + 1,
                        v.len(),
                        self.len()
                    ),
                });
            }
        }
        if !self.names.is_empty() && self.names.len() != self.channels() {
            return Err(IoError::InvalidSampleSet {
                problem: format!(
                    "{} channel names for {} channels",
                    self.names.len(),
                    self.channels()
                ),
            });
        }
        Ok(())
    }
}

/// ` line L,` or `:` for errors that may or may not have a line number.
fn line_part(line: &Option<usize>) -> String {
    match line {
        Some(l) => format!(" line {l},"),
        None => ":".to_string(),
    }
}

/// Everything that can go wrong reading, writing or validating samples.
///
/// Rows, lines and columns are 1-based; the position column `x` is column 1.
/// For CSV files `line` counts every physical line of the file and `row`
/// counts data rows only (no header, comments or blank lines).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum IoError {
    /// The file could not be opened or read.
    #[error("cannot read `{}`: {source}; check that the path exists and is readable", .file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// The file could not be created or written.
    #[error(
        "cannot write `{}`: {source}; check that the directory exists and is writable",
        .file.display()
    )]
    Write {
        /// The file.
        file: PathBuf,
        /// The operating-system error.
        source: std::io::Error,
    },
    /// A CSV line is not valid UTF-8.
    #[error("`{}` line {line}: not valid UTF-8 text; save the file as UTF-8 or plain ASCII", .file.display())]
    NotUtf8 {
        /// The file.
        file: PathBuf,
        /// The 1-based line.
        line: usize,
    },
    /// The file holds no samples (no bytes, only a header, or only comments).
    #[error(
        "`{}` holds no samples; a sample file needs a header `x,value` and at least one row \
         `x,value` (or an .npy array of shape (m, 2) with m >= 1)",
        .file.display()
    )]
    Empty {
        /// The file.
        file: PathBuf,
    },
    /// The first CSV line is data, not a header.
    #[error(
        "`{}` line {line}: missing header: found the data `{found}` where the header belongs; \
         add a first line `x,value` (one name per value column, e.g. `x,value1,value2`)",
        .file.display()
    )]
    MissingHeader {
        /// The file.
        file: PathBuf,
        /// The 1-based line of the first non-comment line.
        line: usize,
        /// That line (shortened).
        found: String,
    },
    /// The CSV header is malformed.
    #[error(
        "`{}` line {line}: bad header `{found}`: {problem}; the header must be `x,NAME[,NAME...]`, \
         e.g. `x,value`",
        .file.display()
    )]
    BadHeader {
        /// The file.
        file: PathBuf,
        /// The 1-based line of the header.
        line: usize,
        /// The header line (shortened).
        found: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A CSV row has the wrong number of fields.
    #[error(
        "`{}` line {line}: row {row} has {found} columns, expected {expected} as in the header; \
         give every row the position and one value per channel, separated by commas",
        .file.display()
    )]
    ColumnCount {
        /// The file.
        file: PathBuf,
        /// The 1-based line.
        line: usize,
        /// The 1-based data row.
        row: usize,
        /// Columns in the header.
        expected: usize,
        /// Columns in this row.
        found: usize,
    },
    /// A CSV field is not a number.
    #[error(
        "`{}` line {line}: row {row}, column {column} (`{name}`): `{field}` is not a number; \
         write a decimal number such as 0.25 or -1.5e-3",
        .file.display()
    )]
    NotANumber {
        /// The file.
        file: PathBuf,
        /// The 1-based line.
        line: usize,
        /// The 1-based data row.
        row: usize,
        /// The 1-based column (`x` is column 1).
        column: usize,
        /// The column's header name.
        name: String,
        /// The offending field (shortened).
        field: String,
    },
    /// A value or position is NaN or infinite.
    #[error(
        "`{}`{} row {row}, column {column} (`{name}`): the value {value} is not finite; \
         remove the sample or replace the NaN/Inf by a finite number",
        .file.display(),
        line_part(.line)
    )]
    NonFinite {
        /// The file.
        file: PathBuf,
        /// The 1-based line (CSV only).
        line: Option<usize>,
        /// The 1-based data row.
        row: usize,
        /// The 1-based column (`x` is column 1).
        column: usize,
        /// The column's name.
        name: String,
        /// The value read.
        value: f64,
    },
    /// The file does not start with the `.npy` magic string `\x93NUMPY`.
    #[error(
        "`{}` is not a NumPy .npy file (it does not start with \\x93NUMPY); \
         save the array with numpy.save, or use a .csv file",
        .file.display()
    )]
    BadMagic {
        /// The file.
        file: PathBuf,
    },
    /// An `.npy` format version other than 1.0, 2.0 or 3.0.
    #[error(
        "`{}` uses .npy format version {major}.{minor}, which is not supported (1.0, 2.0 and 3.0 \
         are); save it again with numpy.save",
        .file.display()
    )]
    UnsupportedVersion {
        /// The file.
        file: PathBuf,
        /// Major version byte.
        major: u8,
        /// Minor version byte.
        minor: u8,
    },
    /// The `.npy` header dictionary cannot be parsed.
    #[error(
        "`{}`: bad .npy header: {problem}; save the array again with numpy.save",
        .file.display()
    )]
    BadNpyHeader {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The `.npy` dtype is not a 4- or 8-byte float.
    #[error(
        "`{}`: unsupported dtype `{descr}`; only float64 ('<f8') and float32 ('<f4') are \
         read: convert with numpy.save(path, array.astype('<f8'))",
        .file.display()
    )]
    UnsupportedDtype {
        /// The file.
        file: PathBuf,
        /// The `descr` entry of the header.
        descr: String,
    },
    /// The file ends before the data its header announces.
    #[error(
        "`{}` is truncated: it needs {expected} bytes for the {what} but has only {found}; \
         the file was cut short, so write it again",
        .file.display()
    )]
    Truncated {
        /// The file.
        file: PathBuf,
        /// Which part is cut short (magic, header, data).
        what: String,
        /// Bytes needed.
        expected: usize,
        /// Bytes present.
        found: usize,
    },
    /// The `.npy` shape is not `(m, 1 + channels)` or disagrees with the data.
    #[error(
        "`{}`: {problem}; the array must be 2-D of shape (m, 1 + channels): column 0 the \
         positions, the others the values",
        .file.display()
    )]
    ShapeMismatch {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A position lies outside the domain (from [`validate_positions`]).
    #[error(
        "row {row}: the position x = {} lies outside the domain {domain}; \
         choose a domain that contains every position, or drop the sample",
        crate::norms::show(*.value)
    )]
    OutOfDomain {
        /// The 1-based row.
        row: usize,
        /// The position.
        value: f64,
        /// The domain it should lie in.
        domain: Domain,
    },
    /// A [`SampleSet`] given to a writer or constructor is inconsistent.
    #[error("invalid sample set: {problem}")]
    InvalidSampleSet {
        /// What is wrong.
        problem: String,
    },
    /// An image-plane sample file has the wrong number of columns.
    #[error(
        "{}: image samples need 3 to 6 columns `x, y, c1[, c2, c3, c4]` (positions in pixel \
         units, 1 to 4 channels), found {columns}",
        .file.display()
    )]
    ImageColumns {
        /// The file.
        file: PathBuf,
        /// Columns found.
        columns: usize,
    },
    /// An image-plane sample file's samples do not fit the image plane.
    #[error("{}: {source}", .file.display())]
    ImageSamples {
        /// The file.
        file: PathBuf,
        /// What is wrong with the samples.
        source: crate::image::ImageError,
    },
}

/// Checks that every position of `set` lies in `domain` (endpoints
/// included); the first offender gives [`IoError::OutOfDomain`].
pub fn validate_positions(set: &SampleSet, domain: Domain) -> Result<(), IoError> {
    match set.positions.iter().position(|&x| !domain.contains(x)) {
        Some(i) => Err(IoError::OutOfDomain {
            row: i + 1,
            value: set.positions[i],
            domain,
        }),
        None => Ok(()),
    }
}

/// Whether the path has the extension `.npy`.
pub(super) fn is_npy(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("npy"))
}

/// Reads a whole file, mapping failures to [`IoError::Read`].
pub(super) fn read_bytes(path: &Path) -> Result<Vec<u8>, IoError> {
    std::fs::read(path).map_err(|source| IoError::Read {
        file: path.to_path_buf(),
        source,
    })
}

/// Writes a whole file, mapping failures to [`IoError::Write`].
pub(super) fn write_bytes(path: &Path, bytes: &[u8]) -> Result<(), IoError> {
    std::fs::write(path, bytes).map_err(|source| IoError::Write {
        file: path.to_path_buf(),
        source,
    })
}

impl IoError {
    /// [`IoError::NonFinite`] for 0-based data row `i` and column `j` of an array file
    /// (column 0 is `x`, column `j > 0` the value channel `names[j - 1]`).
    pub(crate) fn non_finite_cell(
        file: &Path,
        i: usize,
        j: usize,
        names: &[String],
        value: f64,
    ) -> Self {
        IoError::NonFinite {
            file: file.to_path_buf(),
            line: None,
            row: i + 1,
            column: j + 1,
            name: if j == 0 {
                "x".to_string()
            } else {
                names[j - 1].clone()
            },
            value,
        }
    }
}

/// At most `max` characters of `s`, with `…` when cut.
pub(super) fn shorten(s: &str, max: usize) -> String {
    let mut out: String = s.chars().take(max).collect();
    if s.chars().nth(max).is_some() {
        out.push('…');
    }
    out
}

/// Checks a set before writing: consistent shape, at least one channel,
/// finite numbers. `file` names the destination in errors.
pub(super) fn check_for_writing(set: &SampleSet, file: &Path) -> Result<Vec<String>, IoError> {
    set.check()?;
    if set.channels() == 0 {
        return Err(IoError::InvalidSampleSet {
            problem: "no value channels; a sample file needs at least one".to_string(),
        });
    }
    let names = set.names_or_default();
    for i in 0..set.len() {
        let row = std::iter::once(set.positions[i]).chain(set.values.iter().map(|v| v[i]));
        for (j, value) in row.enumerate() {
            if !value.is_finite() {
                return Err(IoError::non_finite_cell(file, i, j, &names, value));
            }
        }
    }
    Ok(names)
}

impl IoError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            IoError::Read { .. } => crate::error::ErrorKind::Unreadable,
            IoError::Write { .. } => crate::error::ErrorKind::WriteFailed,
            IoError::NotUtf8 { .. }
            | IoError::Empty { .. }
            | IoError::MissingHeader { .. }
            | IoError::BadHeader { .. }
            | IoError::ColumnCount { .. }
            | IoError::NotANumber { .. }
            | IoError::NonFinite { .. }
            | IoError::BadMagic { .. }
            | IoError::UnsupportedVersion { .. }
            | IoError::BadNpyHeader { .. }
            | IoError::UnsupportedDtype { .. }
            | IoError::Truncated { .. }
            | IoError::ShapeMismatch { .. }
            | IoError::OutOfDomain { .. }
            | IoError::InvalidSampleSet { .. }
            | IoError::ImageColumns { .. } => crate::error::ErrorKind::InvalidInput,
            IoError::ImageSamples { source, .. } => source.kind(),
        }
    }
}

crate::error::classified!(IoError);
