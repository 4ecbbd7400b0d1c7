//! The NumPy `.npy` sample format, read and written through the `npyz` crate.
//!
//! Layout of a file: the magic `\x93NUMPY`, two version bytes, the header
//! length (`u16` little-endian for version 1.0, `u32` for 2.0 and 3.0), the
//! header — a Python dict literal such as
//! `{'descr': '<f8', 'fortran_order': False, 'shape': (m, k), }` padded with
//! spaces and ending in `\n` — and then the raw array data.
//!
//! `npyz` parses the header (dtype, order, shape); the data is decoded here, straight
//! into its columns ([`decode`]). Before handing `npyz` the bytes, [`parse_npy`] checks
//! what `npyz` would report only as a generic I/O error or could not survive: the magic
//! string, the version, that the header lies inside the file (so a forged `u32` length
//! allocates nothing), and the bracket nesting of the header (so no header can exhaust the
//! stack of its recursive-descent parser). After it, the dtype, the shape
//! and the data length are checked and every failure is a typed [`IoError`].

use std::path::Path;

use npyz::{DType, Endianness, NpyHeader, Order, TypeChar, TypeStr, WriterBuilder};

use super::table::{check_for_writing, read_bytes, shorten, write_bytes, IoError, SampleSet};

/// The `.npy` magic string.
const MAGIC: &[u8; 6] = b"\x93NUMPY";

/// Deepest bracket nesting accepted in a header. A float array's header
/// nests two deep (the dict and the shape tuple); structured dtypes a few
/// more. The cap keeps `npyz`'s recursive parser far from the stack's end.
const MAX_DEPTH: usize = 16;

/// Reads a NumPy `.npy` sample file.
pub fn read_npy(path: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    let path = path.as_ref();
    parse_npy(&read_bytes(path)?, path)
}

/// Parses `.npy` bytes; `file` only names the source in errors.
///
/// Accepts versions 1.0, 2.0 and 3.0; dtypes float64 and float32 in either
/// byte order (`<f8`, `>f8`, `<f4`, `>f4`; float32 is widened exactly); C or
/// Fortran order; a 2-D shape `(m, k)` with `m >= 1` and `k >= 2`. Column 0
/// holds the positions, columns `1..k` the channels. The data must fill the
/// rest of the file exactly, and every value must be finite.
///
/// ```
/// use rkwave::io::{npy_bytes, parse_npy, IoError, SampleSet};
///
/// let set = SampleSet::new(vec![0.0, 0.5], vec![vec![1.0, -2.0]])?;
/// let bytes = npy_bytes(&set)?;
/// assert_eq!(parse_npy(&bytes, "s.npy")?.values, set.values);
/// // Cut short: a typed error naming what is missing, never a panic.
/// let err = parse_npy(&bytes[..bytes.len() - 3], "s.npy").unwrap_err();
/// assert!(matches!(err, IoError::Truncated { .. }));
/// # Ok::<(), IoError>(())
/// ```
pub fn parse_npy(bytes: &[u8], file: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    parse_npy_named(bytes, file.as_ref(), SampleSet::default_names, usize::MAX)
}

/// [`parse_npy`] with the names of columns `1..k` given by `names(k - 1)` (errors name a
/// column by them: an image-plane file's column 1 is `y`, not a value channel), where only
/// the first `finite_columns` columns must be finite (the others are kept as read).
pub(crate) fn parse_npy_named(
    bytes: &[u8],
    file: &Path,
    names: impl FnOnce(usize) -> Vec<String>,
    finite_columns: usize,
) -> Result<SampleSet, IoError> {
    let NpyLayout {
        m,
        k,
        size,
        big_endian,
        fortran,
        data_start,
        data_len,
    } = npy_layout(bytes, bytes.len(), file)?;
    // The data decoded straight into its columns (one pass, no copy in storage order),
    // widened to f64 (exact for float32).
    let data = &bytes[data_start..data_start + data_len];
    let mut columns: Vec<Vec<f64>> = (0..k).map(|_| Vec::with_capacity(m)).collect();
    if fortran {
        for (column, stored) in columns.iter_mut().zip(data.chunks_exact(m * size)) {
            column.extend(stored.chunks_exact(size).map(|b| decode(b, big_endian)));
        }
    } else {
        for row in data.chunks_exact(k * size) {
            for (column, b) in columns.iter_mut().zip(row.chunks_exact(size)) {
                column.push(decode(b, big_endian));
            }
        }
    }
    let names = names(k - 1);
    // the first non-finite value in row order among the columns that must be finite
    let finite = &columns[..finite_columns.min(k)];
    if let Some((i, j)) = (0..m)
        .flat_map(|i| (0..finite.len()).map(move |j| (i, j)))
        .find(|&(i, j)| !finite[j][i].is_finite())
    {
        return Err(IoError::non_finite_cell(file, i, j, &names, columns[j][i]));
    }
    let positions = columns.remove(0);
    let values = columns;
    Ok(SampleSet {
        positions,
        values,
        names,
    })
}

/// One stored value of `b.len()` bytes (8: float64, 4: float32, widened exactly), in the
/// byte order the header gives.
pub(crate) fn decode(b: &[u8], big_endian: bool) -> f64 {
    match (b.len(), big_endian) {
        (8, false) => f64::from_le_bytes(b.try_into().expect("8 bytes")),
        (8, true) => f64::from_be_bytes(b.try_into().expect("8 bytes")),
        (_, false) => f32::from_le_bytes(b.try_into().expect("4 bytes")) as f64,
        (_, true) => f32::from_be_bytes(b.try_into().expect("4 bytes")) as f64,
    }
}

/// Parses the header with `npyz`. Files of versions 1.0 and 2.0 written by
/// Python 2 may spell shape dimensions as long literals (`(3L, 2L)`), which
/// NumPy still reads; if the header does not parse as it is, it is parsed
/// again with those suffixes removed, as NumPy's own reader does.
fn read_header(bytes: &[u8], major: u8, header_text: &[u8]) -> std::io::Result<NpyHeader> {
    let first = header_of(bytes);
    if first.is_ok() || major == 3 {
        return first;
    }
    let Some(filtered) = without_long_suffixes(header_text) else {
        return first;
    };
    // The filtered header is shorter, so its length fits the same field.
    let mut patched = bytes[..8].to_vec();
    if major == 1 {
        patched.extend_from_slice(&(filtered.len() as u16).to_le_bytes());
    } else {
        patched.extend_from_slice(&(filtered.len() as u32).to_le_bytes());
    }
    patched.extend_from_slice(&filtered);
    header_of(&patched).or(first)
}

/// `npyz`'s header parse. It multiplies the shape's dimensions without an
/// overflow check, which panics in builds with overflow checks (the release
/// profile has none); such a shape is reported as an error instead.
fn header_of(bytes: &[u8]) -> std::io::Result<NpyHeader> {
    std::panic::catch_unwind(|| NpyHeader::from_reader(bytes)).unwrap_or_else(|_| {
        Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            "the number of elements of the shape overflows",
        ))
    })
}

/// The header without Python 2's `L` suffix after integer literals outside
/// strings, or `None` if it has none.
fn without_long_suffixes(header: &[u8]) -> Option<Vec<u8>> {
    let mut out = Vec::with_capacity(header.len());
    let mut quote = None;
    let mut changed = false;
    for (i, &b) in header.iter().enumerate() {
        match quote {
            Some(q) if b == q && header.get(i.wrapping_sub(1)) != Some(&b'\\') => quote = None,
            Some(_) => {}
            None if b == b'\'' || b == b'"' => quote = Some(b),
            None if matches!(b, b'L' | b'l')
                && i > 0
                && header[i - 1].is_ascii_digit()
                && !header
                    .get(i + 1)
                    .is_some_and(|c| c.is_ascii_alphanumeric() || *c == b'_') =>
            {
                changed = true;
                continue;
            }
            None => {}
        }
        out.push(b);
    }
    changed.then_some(out)
}

/// Refuses headers whose brackets nest deeper than [`MAX_DEPTH`] (counted
/// without regard to quotes: no float array's header comes near the cap).
fn check_nesting(header: &[u8]) -> Result<(), String> {
    let mut depth = 0usize;
    for &b in header {
        match b {
            b'(' | b'[' | b'{' => {
                depth += 1;
                if depth > MAX_DEPTH {
                    return Err(format!(
                        "the header is nested more than {MAX_DEPTH} brackets deep"
                    ));
                }
            }
            b')' | b']' | b'}' => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    Ok(())
}

/// Encodes a sample set as a version 1.0 `.npy` file of `<f8` in C order,
/// shape `(m, 1 + channels)`, written by `npyz` (the header padded to a
/// multiple of 64 bytes as NumPy does). Channel names are not stored.
///
/// Fails if the set is inconsistent, has no channel or holds NaN/Inf.
pub fn npy_bytes(set: &SampleSet) -> Result<Vec<u8>, IoError> {
    npy_bytes_for(set, Path::new("<npy>"))
}

/// [`npy_bytes`] naming `file` in errors.
fn npy_bytes_for(set: &SampleSet, file: &Path) -> Result<Vec<u8>, IoError> {
    check_for_writing(set, file)?;
    let (m, k) = (set.len(), 1 + set.channels());
    let mut out = Vec::with_capacity(128 + 8 * m * k);
    let write_err = |source: std::io::Error| IoError::Write {
        file: file.to_path_buf(),
        source,
    };
    let mut writer = npyz::WriteOptions::new()
        .dtype(DType::Plain(
            "<f8"
                .parse::<TypeStr>()
                .expect("`<f8` is a valid type string"),
        ))
        .shape(&[m as u64, k as u64])
        .writer(&mut out)
        .begin_nd()
        .map_err(write_err)?;
    for i in 0..m {
        writer.push(&set.positions[i]).map_err(write_err)?;
        for v in &set.values {
            writer.push(&v[i]).map_err(write_err)?;
        }
    }
    writer.finish().map_err(write_err)?;
    Ok(out)
}

/// Writes a sample set as a `.npy` file (see [`npy_bytes`]).
pub fn write_npy(path: impl AsRef<Path>, set: &SampleSet) -> Result<(), IoError> {
    let path = path.as_ref();
    let bytes = npy_bytes_for(set, path)?;
    write_bytes(path, &bytes)
}

/// Where the samples of a `.npy` file lie: `m` rows of `k` columns of `size`-byte floats
/// from byte `data_start`, in C (row-major) or Fortran order.
pub(crate) struct NpyLayout {
    /// Rows.
    pub m: usize,
    /// Columns.
    pub k: usize,
    /// Bytes per value (4 or 8).
    pub size: usize,
    /// Big-endian values.
    pub big_endian: bool,
    /// Column-major storage.
    pub fortran: bool,
    /// Offset of the data.
    pub data_start: usize,
    /// Bytes of data, `m k size`.
    pub data_len: usize,
}

/// The checks of [`parse_npy`] that need only the header: `bytes` holds the file's first
/// bytes (at least its header), `total` is the file's length.
pub(crate) fn npy_layout(bytes: &[u8], total: usize, file: &Path) -> Result<NpyLayout, IoError> {
    let truncated = |what: &str, expected: usize| IoError::Truncated {
        file: file.to_path_buf(),
        what: what.to_string(),
        expected,
        found: total,
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
    let header_start = match (major, minor) {
        (1, 0) => 10,
        (2 | 3, 0) => 12,
        _ => {
            return Err(IoError::UnsupportedVersion {
                file: file.to_path_buf(),
                major,
                minor,
            })
        }
    };
    let Some(length) = bytes.get(8..header_start) else {
        return Err(truncated("header length", header_start));
    };
    let header_len = length
        .iter()
        .rev()
        .fold(0usize, |len, &b| (len << 8) | usize::from(b));
    let data_start = header_start + header_len;
    let Some(header_text) = bytes.get(header_start..data_start) else {
        return Err(truncated("header", data_start));
    };
    let bad_header = |problem: String| IoError::BadNpyHeader {
        file: file.to_path_buf(),
        problem,
    };
    check_nesting(header_text).map_err(bad_header)?;

    let header = read_header(bytes, major, header_text).map_err(|e| {
        // npyz's parse errors are multi-line diagnostics; the first line says it.
        let text = e.to_string();
        bad_header(shorten(text.lines().next().unwrap_or_default(), 200))
    })?;

    let unsupported = |descr: String| IoError::UnsupportedDtype {
        file: file.to_path_buf(),
        descr: shorten(&descr, 40),
    };
    let (type_str, size) = match header.dtype() {
        DType::Plain(ty) => {
            let float = ty.type_char() == TypeChar::Float
                && ty.endianness() != Endianness::Irrelevant
                && matches!(ty.size_field(), 4 | 8);
            if !float {
                return Err(unsupported(ty.to_string()));
            }
            let size = ty.size_field() as usize;
            (ty, size)
        }
        DType::Record(fields) => {
            return Err(unsupported(format!(
                "a structured dtype with {} fields",
                fields.len()
            )))
        }
        DType::Array(..) => return Err(unsupported("a sub-array dtype".to_string())),
    };

    // Python's tuple syntax: `(4,)`, `(3, 2)`.
    let shape = header.shape();
    let shape_text = match shape {
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
    let &[m, k] = shape else {
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
    if total - data_start.min(total) < data_len {
        return Err(truncated(
            &format!("data of shape {shape_text}"),
            data_start + data_len,
        ));
    }
    if total - data_start > data_len {
        return Err(mismatch(format!(
            "the file has {} bytes of data, but shape {shape_text} of {type_str} needs \
             {data_len}; {} bytes are left over",
            total - data_start,
            total - data_start - data_len
        )));
    }

    Ok(NpyLayout {
        m,
        k,
        size,
        big_endian: type_str.endianness() == Endianness::Big,
        fortran: header.order() == Order::Fortran,
        data_start,
        data_len,
    })
}
