//! Image-plane samples from a sample file: columns `x, y, c1[, c2, c3, c4]` (positions in
//! pixel units, 1 to 4 channels), as CSV or `.npy` `m x (2 + channels)`. The generic reader
//! sees `x` as the position column and `y` as the first value column; here `y` becomes the
//! second coordinate and the other columns the channels.
//!
//! The positions must be finite; a channel value that is NaN or infinite (a renderer's
//! non-finite radiance) is read as it is and handled by the caller's
//! [`NonFinitePolicy`] ([`crate::image::nonfinite`]): refused with the count and the first
//! row, or dropped and counted.

use std::path::Path;

use super::table::{IoError, SampleSet};
use crate::image::{split_finite, DroppedSamples, ImagePlane, ImageSamples, NonFinitePolicy};

/// Image samples on `plane` from the sample table `table` read from `file` (module docs),
/// non-finite values refused.
pub fn image_samples(
    table: SampleSet,
    plane: ImagePlane,
    file: &Path,
) -> Result<ImageSamples, IoError> {
    image_samples_with(table, plane, file, NonFinitePolicy::Refuse).map(|(s, _)| s)
}

/// [`image_samples`] with the samples whose value is not finite handled by `policy`: the
/// finite samples and those dropped.
pub fn image_samples_with(
    table: SampleSet,
    plane: ImagePlane,
    file: &Path,
    policy: NonFinitePolicy,
) -> Result<(ImageSamples, DroppedSamples), IoError> {
    let columns = 1 + table.channels();
    if !(3..=6).contains(&columns) {
        return Err(IoError::ImageColumns {
            file: file.to_path_buf(),
            columns,
        });
    }
    let mut values = table.values;
    let ys = values.remove(0);
    split_finite(plane, table.positions, ys, values, policy).map_err(|source| {
        IoError::ImageSamples {
            file: file.to_path_buf(),
            source,
        }
    })
}

/// The names of the columns after `x` of an image-plane array file: `y`, then the channels
/// (`value` for one, `value1`, `value2`, ... otherwise), so an error names the column a user
/// wrote, not the generic reader's `value2` for the first channel.
pub fn image_column_names(columns: usize) -> Vec<String> {
    let mut names = vec!["y".to_string()];
    names.extend(SampleSet::default_names(columns.saturating_sub(1)));
    names.truncate(columns);
    names
}

/// Reads the image-plane samples of `path` on `plane` (module docs), non-finite values refused.
pub fn read_image_samples(path: &Path, plane: ImagePlane) -> Result<ImageSamples, IoError> {
    read_image_samples_with(path, plane, NonFinitePolicy::Refuse).map(|(s, _)| s)
}

/// Reads the image-plane samples of `path` on `plane`, the samples whose value is not finite
/// handled by `policy` (module docs): the finite samples and those dropped.
pub fn read_image_samples_with(
    path: &Path,
    plane: ImagePlane,
    policy: NonFinitePolicy,
) -> Result<(ImageSamples, DroppedSamples), IoError> {
    // x and y must be finite; the channels are split by `policy`
    const POSITIONS: usize = 2;
    let bytes = super::table::read_bytes(path)?;
    let table = if super::table::is_npy(path) {
        super::npy::parse_npy_named(&bytes, path, image_column_names, POSITIONS)?
    } else {
        super::csv::parse_csv_cells(&bytes, path, POSITIONS)?
    };
    image_samples_with(table, plane, path, policy)
}
