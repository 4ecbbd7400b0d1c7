//! The NumPy `.npy` sample format.
//!
//! Layout of a file: the magic `\x93NUMPY`, two version bytes, the header
//! length (`u16` little-endian for version 1.0, `u32` for 2.0 and 3.0), the
//! header — a Python dict literal such as
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (m, k), }` padded with
//! spaces and ending in `\n` — and then the raw array data.
//!
//! The header is parsed by a small hand-written parser for Python literals
//! (strings, integers, `True`/`False`/`None`, tuples, lists, dicts) with a
//! nesting limit, so no input can make it panic or overflow the stack.

use std::path::Path;

use super::{check_for_writing, read_bytes, shorten, write_bytes, IoError, SampleSet};

/// The `.npy` magic string.
const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Deepest nesting of brackets accepted in a header.
const MAX_DEPTH: usize = 16;

/// Reads a NumPy `.npy` sample file.
pub fn read_npy(path: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    let path = path.as_ref();
    parse_npy(&read_bytes(path)?, path)
}

/// Parses `.npy` bytes; `file` only names the source in errors.
///
/// Accepts versions 1.0, 2.0 and 3.0; dtypes `<f8`, `<f4`, `>f8`, `>f4`; C or
/// Fortran order; a 2-D shape `(m, k)` with `m >= 1` and `k >= 2`. Column 0
/// holds the positions, columns `1..k` the channels. The data must fill the
/// rest of the file exactly.
pub fn parse_npy(bytes: &[u8], file: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    let file = file.as_ref();
    let truncated = |what: &str, expected: usize| IoError::Truncated {
        file: file.to_path_buf(),
        what: what.to_string(),
        expected,
        found: bytes.len(),
    };
    if bytes.is_empty() {
        return Err(IoError::Empty {
            file: file.to_path_buf(),
        });
    }
    let n = bytes.len().min(MAGIC.len());
    if bytes[..n] != MAGIC[..n] {
        return Err(IoError::BadMagic {
            file: file.to_path_buf(),
        });
    }
    if bytes.len() < MAGIC.len() + 2 {
        return Err(truncated("magic string and version", MAGIC.len() + 2));
    }
    let (major, minor) = (bytes[6], bytes[7]);
    let (header_start, header_len) = match major {
        1 => {
            let Some(len) = bytes.get(8..10).and_then(|s| <[u8; 2]>::try_from(s).ok()) else {
                return Err(truncated("header length", 10));
            };
            (10, usize::from(u16::from_le_bytes(len)))
        }
        2 | 3 => {
            let Some(len) = bytes.get(8..12).and_then(|s| <[u8; 4]>::try_from(s).ok()) else {
                return Err(truncated("header length", 12));
            };
            (12, u32::from_le_bytes(len) as usize)
        }
        _ => {
            return Err(IoError::UnsupportedVersion {
                file: file.to_path_buf(),
                major,
                minor,
            })
        }
    };
    let data_start = header_start + header_len;
    let Some(header_bytes) = bytes.get(header_start..data_start) else {
        return Err(truncated("header", data_start));
    };
    let bad_header = |problem: String| IoError::BadNpyHeader {
        file: file.to_path_buf(),
        problem,
    };
    let header_text: String = if major == 3 {
        std::str::from_utf8(header_bytes)
            .map_err(|_| bad_header("the header is not UTF-8".to_string()))?
            .to_string()
    } else {
        // Versions 1 and 2 use latin-1, which maps bytes to code points.
        header_bytes.iter().map(|&b| char::from(b)).collect()
    };
    let header = Header::parse(&header_text).map_err(bad_header)?;

    let (little, size) = match header.descr.as_str() {
        "<f8" => (true, 8),
        "<f4" => (true, 4),
        ">f8" => (false, 8),
        ">f4" => (false, 4),
        _ => {
            return Err(IoError::UnsupportedDtype {
                file: file.to_path_buf(),
                descr: shorten(&header.descr, 40),
            })
        }
    };
    // Python's tuple syntax: `(4,)`, `(3, 2)`.
    let shape_text = match header.shape.as_slice() {
        [d] => format!("({d},)"),
        dims => format!(
            "({})",
            dims.iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ),
    };
    let mismatch = |problem: String| IoError::ShapeMismatch {
        file: file.to_path_buf(),
        problem,
    };
    let &[m, k] = header.shape.as_slice() else {
        return Err(mismatch(format!(
            "the array has shape {shape_text}, which is not 2-D"
        )));
    };
    if k < 2 {
        return Err(mismatch(format!(
            "the array has shape {shape_text}: {k} column(s), but it needs x and at least one \
             value column"
        )));
    }
    let (Ok(m), Ok(k)) = (usize::try_from(m), usize::try_from(k)) else {
        return Err(mismatch(format!("the shape {shape_text} is too large")));
    };
    if m == 0 {
        return Err(IoError::Empty {
            file: file.to_path_buf(),
        });
    }
    let Some(data_len) = m
        .checked_mul(k)
        .and_then(|n| n.checked_mul(size))
        .filter(|len| len.checked_add(data_start).is_some())
    else {
        return Err(mismatch(format!("the shape {shape_text} is too large")));
    };
    let data = &bytes[data_start..];
    if data.len() < data_len {
        return Err(truncated(
            &format!("data of shape {shape_text}"),
            data_start + data_len,
        ));
    }
    if data.len() > data_len {
        return Err(mismatch(format!(
            "the file has {} bytes of data, but shape {shape_text} of {} needs {data_len}; \
             {} bytes are left over",
            data.len(),
            header.descr,
            data.len() - data_len
        )));
    }

    let read = |index: usize| -> f64 {
        let at = index * size;
        let chunk = &data[at..at + size];
        if size == 8 {
            let mut b = [0u8; 8];
            b.copy_from_slice(chunk);
            if little {
                f64::from_le_bytes(b)
            } else {
                f64::from_be_bytes(b)
            }
        } else {
            let mut b = [0u8; 4];
            b.copy_from_slice(chunk);
            f64::from(if little {
                f32::from_le_bytes(b)
            } else {
                f32::from_be_bytes(b)
            })
        }
    };
    let names = SampleSet::default_names(k - 1);
    let mut positions = Vec::with_capacity(m);
    let mut values = vec![Vec::with_capacity(m); k - 1];
    for i in 0..m {
        for j in 0..k {
            let index = if header.fortran_order {
                j * m + i
            } else {
                i * k + j
            };
            let value = read(index);
            if !value.is_finite() {
                return Err(IoError::NonFinite {
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
                });
            }
            if j == 0 {
                positions.push(value);
            } else {
                values[j - 1].push(value);
            }
        }
    }
    Ok(SampleSet {
        positions,
        values,
        names,
    })
}

/// Encodes a sample set as a version 1.0 `.npy` file of `<f8` in C order,
/// shape `(m, 1 + channels)`, the header padded to a multiple of 64 bytes as
/// NumPy does. Channel names are not stored.
///
/// Fails if the set is inconsistent, has no channel or holds NaN/Inf.
pub fn npy_bytes(set: &SampleSet) -> Result<Vec<u8>, IoError> {
    npy_bytes_for(set, Path::new("<npy>"))
}

/// [`npy_bytes`] naming `file` in errors.
fn npy_bytes_for(set: &SampleSet, file: &Path) -> Result<Vec<u8>, IoError> {
    check_for_writing(set, file)?;
    let (m, k) = (set.len(), 1 + set.channels());
    let mut header = format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({m}, {k}), }}");
    // magic (6) + version (2) + length (2) + header + '\n' ≡ 0 (mod 64).
    let unpadded = MAGIC.len() + 4 + header.len() + 1;
    header.extend(std::iter::repeat_n(' ', (64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = Vec::with_capacity(MAGIC.len() + 4 + header.len() + 8 * m * k);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&[1, 0]);
    // The header of a 2-D shape is far below 64 KiB.
    let len = u16::try_from(header.len()).map_err(|_| IoError::InvalidSampleSet {
        problem: "the .npy header is too long".to_string(),
    })?;
    out.extend_from_slice(&len.to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for i in 0..m {
        out.extend_from_slice(&set.positions[i].to_le_bytes());
        for v in &set.values {
            out.extend_from_slice(&v[i].to_le_bytes());
        }
    }
    Ok(out)
}

/// Writes a sample set as a `.npy` file (see [`npy_bytes`]).
pub fn write_npy(path: impl AsRef<Path>, set: &SampleSet) -> Result<(), IoError> {
    let path = path.as_ref();
    let bytes = npy_bytes_for(set, path)?;
    write_bytes(path, &bytes)
}

/// The three entries of an `.npy` header.
struct Header {
    descr: String,
    fortran_order: bool,
    shape: Vec<u64>,
}

impl Header {
    /// Parses the header dict; the error says what is wrong.
    fn parse(text: &str) -> Result<Header, String> {
        let mut parser = Parser {
            chars: text.chars().collect(),
            pos: 0,
        };
        let value = parser.value(0)?;
        parser.skip_ws();
        if parser.pos != parser.chars.len() {
            return Err(format!(
                "unexpected text after the dictionary at character {}",
                parser.pos + 1
            ));
        }
        let Py::Dict(entries) = value else {
            return Err("the header is not a dictionary".to_string());
        };
        let get = |key: &str| {
            entries
                .iter()
                .find(|(k, _)| matches!(k, Py::Str(s) if s == key))
                .map(|(_, v)| v)
                .ok_or_else(|| format!("the key '{key}' is missing"))
        };
        let descr = match get("descr")? {
            Py::Str(s) => s.clone(),
            Py::List(fields) => format!("a structured dtype with {} fields", fields.len()),
            _ => "a dtype that is not a string".to_string(),
        };
        let fortran_order = match get("fortran_order")? {
            Py::Bool(b) => *b,
            _ => return Err("'fortran_order' is not True or False".to_string()),
        };
        let shape = match get("shape")? {
            Py::Tuple(items) => items
                .iter()
                .map(|item| match item {
                    Py::Int(n) if *n < 0 => Err(format!("the shape has a negative dimension {n}")),
                    Py::Int(n) => u64::try_from(*n)
                        .map_err(|_| format!("the shape has a too large dimension {n}")),
                    _ => Err("the shape holds something other than integers".to_string()),
                })
                .collect::<Result<Vec<u64>, String>>()?,
            _ => return Err("'shape' is not a tuple".to_string()),
        };
        Ok(Header {
            descr,
            fortran_order,
            shape,
        })
    }
}

/// A Python literal value.
#[derive(Debug)]
enum Py {
    Str(String),
    Int(i128),
    Bool(bool),
    None,
    Tuple(Vec<Py>),
    List(Vec<Py>),
    Dict(Vec<(Py, Py)>),
}

/// A recursive-descent parser for Python literals.
struct Parser {
    chars: Vec<char>,
    pos: usize,
}

impl Parser {
    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
        while self.peek().is_some_and(char::is_whitespace) {
            self.pos += 1;
        }
    }

    fn expected(&self, what: &str) -> String {
        match self.peek() {
            Some(c) => format!(
                "expected {what} at character {} but found `{}`",
                self.pos + 1,
                c.escape_default()
            ),
            None => format!("expected {what} but the header ended"),
        }
    }

    fn value(&mut self, depth: usize) -> Result<Py, String> {
        if depth > MAX_DEPTH {
            return Err("the header is nested too deeply".to_string());
        }
        self.skip_ws();
        match self.peek() {
            Some(q @ ('\'' | '"')) => {
                self.pos += 1;
                self.string(q).map(Py::Str)
            }
            Some('(') => {
                self.pos += 1;
                self.sequence(')', depth).map(Py::Tuple)
            }
            Some('[') => {
                self.pos += 1;
                self.sequence(']', depth).map(Py::List)
            }
            Some('{') => {
                self.pos += 1;
                self.dict(depth)
            }
            Some(c) if c.is_ascii_digit() || c == '-' || c == '+' => self.int(),
            Some(c) if c.is_ascii_alphabetic() => {
                let start = self.pos;
                while self.peek().is_some_and(|c| c.is_ascii_alphanumeric()) {
                    self.pos += 1;
                }
                let word: String = self.chars[start..self.pos].iter().collect();
                match word.as_str() {
                    "True" => Ok(Py::Bool(true)),
                    "False" => Ok(Py::Bool(false)),
                    "None" => Ok(Py::None),
                    _ => Err(format!(
                        "unknown name `{}` at character {}",
                        shorten(&word, 20),
                        start + 1
                    )),
                }
            }
            _ => Err(self.expected("a value")),
        }
    }

    /// The rest of a string literal after its opening quote `quote`.
    fn string(&mut self, quote: char) -> Result<String, String> {
        let mut out = String::new();
        loop {
            match self.peek() {
                None => return Err("a string in the header is not closed".to_string()),
                Some(c) if c == quote => {
                    self.pos += 1;
                    return Ok(out);
                }
                Some('\\') => {
                    self.pos += 1;
                    match self.peek() {
                        Some(c) => {
                            out.push(c);
                            self.pos += 1;
                        }
                        None => return Err("a string in the header is not closed".to_string()),
                    }
                }
                Some(c) => {
                    out.push(c);
                    self.pos += 1;
                }
            }
        }
    }

    /// An integer, with an optional sign and Python 2's `L` suffix.
    fn int(&mut self) -> Result<Py, String> {
        let start = self.pos;
        if matches!(self.peek(), Some('-' | '+')) {
            self.pos += 1;
        }
        let digits = self.pos;
        while self.peek().is_some_and(|c| c.is_ascii_digit()) {
            self.pos += 1;
        }
        if self.pos == digits {
            return Err(self.expected("a digit"));
        }
        let text: String = self.chars[start..self.pos].iter().collect();
        if matches!(self.peek(), Some('L' | 'l')) {
            self.pos += 1;
        }
        text.parse::<i128>()
            .map(Py::Int)
            .map_err(|_| format!("the integer {} is too large", shorten(&text, 30)))
    }

    /// Comma-separated values up to `close` (a trailing comma is allowed).
    fn sequence(&mut self, close: char, depth: usize) -> Result<Vec<Py>, String> {
        let mut items = Vec::new();
        loop {
            self.skip_ws();
            if self.peek() == Some(close) {
                self.pos += 1;
                return Ok(items);
            }
            items.push(self.value(depth + 1)?);
            self.skip_ws();
            match self.peek() {
                Some(',') => self.pos += 1,
                Some(c) if c == close => {}
                _ => return Err(self.expected(&format!("`,` or `{close}`"))),
            }
        }
    }

    /// The rest of a dict after `{`.
    fn dict(&mut self, depth: usize) -> Result<Py, String> {
        let mut entries = Vec::new();
        loop {
            self.skip_ws();
            if self.peek() == Some('}') {
                self.pos += 1;
                return Ok(Py::Dict(entries));
            }
            let key = self.value(depth + 1)?;
            self.skip_ws();
            if self.peek() != Some(':') {
                return Err(self.expected("`:`"));
            }
            self.pos += 1;
            let value = self.value(depth + 1)?;
            entries.push((key, value));
            self.skip_ws();
            match self.peek() {
                Some(',') => self.pos += 1,
                Some('}') => {}
                _ => return Err(self.expected("`,` or `}`")),
            }
        }
    }
}
