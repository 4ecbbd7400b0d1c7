//! Raster figures drawn pixel by pixel (images side by side, depth maps): the font they
//! label with and their PNG encoding in memory (written through [`crate::io::output`]).

use std::sync::Once;

use plotters::prelude::*;
use plotters::style::register_font;

use super::PlotError;

/// Registers the embedded DejaVu Sans as `sans-serif` for raster labels (once a process).
pub fn fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let _ = register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular());
    });
}

/// The PNG encoding of an 8-bit RGB canvas of `width x height` pixels (row-major, 3 bytes a
/// pixel); `label` names the figure in errors.
pub fn encode_png(
    canvas: Vec<u8>,
    width: usize,
    height: usize,
    label: &str,
) -> Result<Vec<u8>, PlotError> {
    let buf = image::RgbImage::from_raw(width as u32, height as u32, canvas).ok_or_else(|| {
        PlotError::Draw {
            path: label.to_string(),
            message: format!("canvas size does not match {width} x {height}"),
        }
    })?;
    let mut png = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut png, image::ImageFormat::Png)
        .map_err(|source| PlotError::Write {
            path: label.to_string(),
            source,
        })?;
    Ok(png.into_inner())
}
