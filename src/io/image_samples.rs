//! Image-plane samples from a sample file: columns `x, y, c1[, c2, c3, c4]` (positions in
//! pixel units, 1 to 4 channels), as CSV or `.npy` `m x (2 + channels)`. The generic reader
//! sees `x` as the position column and `y` as the first value column; here `y` becomes the
//! second coordinate and the other columns the channels.

use std::path::Path;

use super::{read_samples, IoError, SampleSet};
use crate::image::{ImagePlane, ImageSamples};

/// Image samples on `plane` from the sample table `table` read from `file` (module docs).
pub fn image_samples(
    table: SampleSet,
    plane: ImagePlane,
    file: &Path,
) -> Result<ImageSamples, IoError> {
    let columns = 1 + table.channels();
    if !(3..=6).contains(&columns) {
        return Err(IoError::ImageColumns {
            file: file.to_path_buf(),
            columns,
        });
    }
    let mut values = table.values;
    let ys = values.remove(0);
    ImageSamples::new(plane, table.positions, ys, values).map_err(|source| IoError::ImageSamples {
        file: file.to_path_buf(),
        source,
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

/// Reads the image-plane samples of `path` on `plane` (module docs).
pub fn read_image_samples(path: &Path, plane: ImagePlane) -> Result<ImageSamples, IoError> {
    let table = if super::is_npy(path) {
        super::npy::parse_npy_named(&super::read_bytes(path)?, path, image_column_names)?
    } else {
        read_samples(path)?
    };
    image_samples(table, plane, path)
}
