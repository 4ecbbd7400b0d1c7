//! The CSV sample format.
//!
//! ```text
//! # comment lines and blank lines are skipped
//! x,value
//! 0.0, 1.5
//! 0.25,-2e-3
//! ```
//!
//! The first line that is neither blank nor a comment is the header: its
//! first field must be `x` (any case); each further field names one value
//! channel. Fields are separated by commas and surrounding whitespace is
//! trimmed; a UTF-8 byte-order mark and `\r\n` line ends are accepted. There
//! is no quoting and no inline comment.

use std::fmt::Write as _;
use std::path::Path;

use super::table::{check_for_writing, read_bytes, shorten, write_bytes, IoError, SampleSet};

/// Longest field or line quoted in an error message, in characters.
const QUOTE_MAX: usize = 60;

/// Reads a CSV sample file.
pub fn read_csv(path: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    let path = path.as_ref();
    parse_csv(&read_bytes(path)?, path)
}

/// Parses CSV bytes; `file` only names the source in errors.
pub fn parse_csv(bytes: &[u8], file: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    parse_csv_cells(bytes, file.as_ref(), usize::MAX)
}

/// [`parse_csv`] where only the first `finite_columns` columns must be finite: the others
/// may hold NaN or infinities, kept as read (a renderer's radiance, split by the caller).
pub(crate) fn parse_csv_cells(
    bytes: &[u8],
    file: &Path,
    finite_columns: usize,
) -> Result<SampleSet, IoError> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    // Line ends `\n`, `\r\n` and a lone `\r` (old Mac) all end a line.
    let unified;
    let bytes = if bytes.contains(&b'\r') {
        unified = unify_line_ends(bytes);
        unified.as_slice()
    } else {
        bytes
    };
    let mut names: Option<Vec<String>> = None;
    let mut positions = Vec::new();
    let mut values: Vec<Vec<f64>> = Vec::new();
    for (index, raw) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = index + 1;
        let text = std::str::from_utf8(raw).map_err(|_| IoError::NotUtf8 {
            file: file.to_path_buf(),
            line,
        })?;
        let text = text.trim();
        if text.is_empty() || text.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = text.split(',').map(str::trim).collect();
        let Some(header) = &names else {
            let header = parse_header(&fields, text, line, file)?;
            values = vec![Vec::new(); header.len()];
            names = Some(header);
            continue;
        };
        let row = positions.len() + 1;
        if fields.len() != header.len() + 1 {
            return Err(IoError::ColumnCount {
                file: file.to_path_buf(),
                line,
                row,
                expected: header.len() + 1,
                found: fields.len(),
            });
        }
        for (j, field) in fields.iter().enumerate() {
            let name = || {
                if j == 0 {
                    "x".to_string()
                } else {
                    header[j - 1].clone()
                }
            };
            let value: f64 = field.parse().map_err(|_| IoError::NotANumber {
                file: file.to_path_buf(),
                line,
                row,
                column: j + 1,
                name: name(),
                field: shorten(field, QUOTE_MAX),
            })?;
            if !value.is_finite() && j < finite_columns {
                return Err(IoError::NonFinite {
                    file: file.to_path_buf(),
                    line: Some(line),
                    row,
                    column: j + 1,
                    name: name(),
                    value,
                });
            }
            if j == 0 {
                positions.push(value);
            } else {
                values[j - 1].push(value);
            }
        }
    }
    match names {
        Some(names) if !positions.is_empty() => Ok(SampleSet {
            positions,
            values,
            names,
        }),
        _ => Err(IoError::Empty {
            file: file.to_path_buf(),
        }),
    }
}

/// `\r\n` and lone `\r` replaced by `\n`.
fn unify_line_ends(bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'\r' {
            out.push(b'\n');
            if bytes.get(i + 1) == Some(&b'\n') {
                i += 1;
            }
        } else {
            out.push(bytes[i]);
        }
        i += 1;
    }
    out
}

/// Validates the header fields and returns the channel names.
fn parse_header(
    fields: &[&str],
    text: &str,
    line: usize,
    file: &Path,
) -> Result<Vec<String>, IoError> {
    let bad = |problem: String| IoError::BadHeader {
        file: file.to_path_buf(),
        line,
        found: shorten(text, QUOTE_MAX),
        problem,
    };
    let first = fields[0];
    if !first.eq_ignore_ascii_case("x") {
        if first.parse::<f64>().is_ok() {
            return Err(IoError::MissingHeader {
                file: file.to_path_buf(),
                line,
                found: shorten(text, QUOTE_MAX),
            });
        }
        return Err(bad(format!(
            "the first column is named `{}`, but it must be `x`",
            shorten(first, QUOTE_MAX)
        )));
    }
    if fields.len() < 2 {
        return Err(bad("there is no value column after `x`".to_string()));
    }
    if let Some(c) = fields.iter().position(|f| f.is_empty()) {
        return Err(bad(format!("column {} has no name", c + 1)));
    }
    Ok(fields[1..].iter().map(|s| s.to_string()).collect())
}

/// Formats `x` with the shortest decimal representation that reads back to
/// the same `f64` bit for bit: plain notation for moderate magnitudes
/// (`0.25`, `-3`, `-0`), scientific otherwise (`1e-7`, `6.02214076e23`).
pub fn format_f64(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// Renders a sample set as CSV text: a header `x,NAME…` and one row per
/// sample, every number in [`format_f64`] form so it reads back exactly.
///
/// Fails if the set is inconsistent, has no channel, holds NaN/Inf, or a
/// channel name could not be read back (empty, with a comma or line break,
/// or with surrounding whitespace).
pub fn csv_string(set: &SampleSet) -> Result<String, IoError> {
    csv_string_for(set, Path::new("<csv>"))
}

/// [`csv_string`] naming `file` in errors.
fn csv_string_for(set: &SampleSet, file: &Path) -> Result<String, IoError> {
    let names = check_for_writing(set, file)?;
    for name in &names {
        if name.is_empty() || name.trim() != name || name.contains([',', '\n', '\r']) {
            return Err(IoError::InvalidSampleSet {
                problem: format!(
                    "the channel name `{name}` cannot be written to a CSV header; use a \
                     non-empty name without commas, line breaks or surrounding spaces"
                ),
            });
        }
    }
    let mut out = String::with_capacity(16 + set.len() * 24 * (1 + set.channels()));
    out.push('x');
    for name in &names {
        out.push(',');
        out.push_str(name);
    }
    out.push('\n');
    for i in 0..set.len() {
        out.push_str(&format_f64(set.positions[i]));
        for v in &set.values {
            let _ = write!(out, ",{}", format_f64(v[i]));
        }
        out.push('\n');
    }
    Ok(out)
}

/// Writes a sample set as a CSV file (see [`csv_string`]).
pub fn write_csv(path: impl AsRef<Path>, set: &SampleSet) -> Result<(), IoError> {
    let path = path.as_ref();
    let text = csv_string_for(set, path)?;
    write_bytes(path, text.as_bytes())
}
