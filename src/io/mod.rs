//! Input and output of scattered samples: CSV and NumPy `.npy` files (image-plane samples
//! too: [`read_image_samples`]), and image files ([`image_file`]).
//!
//! A file holds one sample per row: the position `x` in the first column and
//! one value per channel in the others. Both readers return a [`SampleSet`]
//! or an [`IoError`] that names the file, the 1-based line/row/column and the
//! fix; they never panic, whatever the bytes. Positions are checked against a
//! [`crate::sampling::Domain`] separately, with [`validate_positions`].
//!
//! * CSV ([`read_csv`], [`parse_csv`], [`write_csv`], [`csv_string`]): a
//!   header `x,NAME[,NAME…]` then rows `x,v[,v…]`; written by hand, since the
//!   format is too small to need a CSV crate (no quoting is needed for
//!   numbers).
//! * NumPy ([`read_npy`], [`parse_npy`], [`write_npy`], [`npy_bytes`]),
//!   through the `npyz` crate: format versions 1.0, 2.0 and 3.0, dtypes
//!   `<f8`, `<f4` (and the big-endian `>f8`, `>f4`), C or Fortran order,
//!   shape `(m, 1 + channels)`; tested against files written by NumPy itself
//!   (`data/fixtures/npy/`).

use std::path::Path;

pub mod chunks;
mod csv;
mod grid_output;
pub mod image_file;
mod image_samples;
mod npy;
pub mod output;
pub mod plan_files;
mod table;

pub use self::csv::{csv_string, format_f64, parse_csv, read_csv, write_csv};
pub use self::grid_output::{GridFormat, GridWriter};
pub use self::image_samples::{
    image_column_names, image_samples, image_samples_with, read_image_samples,
    read_image_samples_with,
};
pub use self::npy::{npy_bytes, parse_npy, read_npy, write_npy};
use self::table::is_npy;
pub use self::table::{validate_positions, IoError, SampleSet};

#[cfg(test)]
mod tests;

/// Reads a sample file, `.npy` (by extension, any case) or otherwise CSV.
///
/// ```
/// use rkwave::io::{read_samples, write_samples, SampleSet};
///
/// let dir = std::env::temp_dir().join(format!("rkwave-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let set = SampleSet::new(vec![0.0, 0.5, 1.0], vec![vec![1.0, 2.0, 3.0]])?;
/// for name in ["s.csv", "s.npy"] {
///     write_samples(dir.join(name), &set)?;
///     assert_eq!(read_samples(dir.join(name))?.values, set.values);
/// }
/// assert!(read_samples(dir.join("missing.csv")).is_err()); // a clear error, not a panic
/// std::fs::remove_dir_all(&dir).unwrap();
/// # Ok::<(), rkwave::io::IoError>(())
/// ```
pub fn read_samples(path: impl AsRef<Path>) -> Result<SampleSet, IoError> {
    let path = path.as_ref();
    if is_npy(path) {
        read_npy(path)
    } else {
        read_csv(path)
    }
}

/// Writes a sample file, `.npy` (by extension, any case) or otherwise CSV.
pub fn write_samples(path: impl AsRef<Path>, set: &SampleSet) -> Result<(), IoError> {
    let path = path.as_ref();
    if is_npy(path) {
        write_npy(path, set)
    } else {
        write_csv(path, set)
    }
}
