//! Writing pixel images: PNG (8-bit, sRGB-encoded), OpenEXR (linear `f32` RGB) and NumPy
//! `.npy` (linear `f64`, shape `(H, W, channels)`, C order).
//!
//! The format follows the file extension ([`ImageFormat::from_path`]). PNG and EXR are RGB:
//! a one- or two-channel image is written as grey (its first channel in R, G and B), a
//! four-channel one drops the fourth (alpha). PNG encodes `255 srgb(clamp(v, 0, 1))` rounded;
//! EXR and `.npy` keep the values as they are. PNG and EXR need the `images` feature; `.npy`
//! is always available.

use std::path::{Path, PathBuf};

use thiserror::Error;

use crate::image::PixelImage;

/// An image file format.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// 8-bit sRGB PNG.
    Png,
    /// Linear `f32` OpenEXR.
    Exr,
    /// Linear `f64` NumPy array `(H, W, C)`.
    Npy,
}

/// Why an image could not be written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ImageFileError {
    /// The extension is not `.png`, `.exr` or `.npy`.
    #[error(
        "cannot tell the image format of `{}`: the file name must end in .png (8-bit sRGB), \
         .exr (linear float) or .npy (linear float array)",
        .file.display()
    )]
    UnknownFormat {
        /// The file.
        file: PathBuf,
    },
    /// The file could not be written.
    #[error("cannot write `{}`: {message}", .file.display())]
    Write {
        /// The file.
        file: PathBuf,
        /// The cause.
        message: String,
    },
    /// The output must not be written (it exists, or its folder refuses new files).
    #[error(transparent)]
    Output(#[from] crate::io::output::OutputError),
}

impl ImageFormat {
    /// The format named by the extension of `path` (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self, ImageFileError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(Self::Png),
            Some("exr") => Ok(Self::Exr),
            Some("npy") => Ok(Self::Npy),
            _ => Err(ImageFileError::UnknownFormat {
                file: path.to_path_buf(),
            }),
        }
    }
}

/// The RGB triple of pixel `p` (grey for one or two channels).
fn rgb_at(image: &PixelImage, p: usize) -> [f64; 3] {
    if image.channel_count() < 3 {
        [image.channels[0][p]; 3]
    } else {
        [0, 1, 2].map(|c| image.channels[c][p])
    }
}

/// 8-bit sRGB encoding of linear RGB, row-major, 3 bytes per pixel.
pub fn srgb8(image: &PixelImage) -> Vec<u8> {
    let mut out = Vec::with_capacity(3 * image.plane.pixels());
    for p in 0..image.plane.pixels() {
        for v in rgb_at(image, p) {
            out.push((255.0 * crate::image::scene::linear_to_srgb(v)).round() as u8);
        }
    }
    out
}

/// The `.npy` bytes of an image: version 1.0, `<f8`, shape `(H, W, C)`.
pub fn image_npy_bytes(image: &PixelImage) -> Vec<u8> {
    let (w, h, c) = (
        image.plane.width(),
        image.plane.height(),
        image.channel_count(),
    );
    let mut header =
        format!("{{'descr': '<f8', 'fortran_order': False, 'shape': ({h}, {w}, {c}), }}");
    let unpadded = 6 + 4 + header.len() + 1;
    header.extend(std::iter::repeat_n(' ', (64 - unpadded % 64) % 64));
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for p in 0..w * h {
        for ch in &image.channels {
            out.extend_from_slice(&ch[p].to_le_bytes());
        }
    }
    out
}

/// Writes `image` to `path` in the format of its extension, encoded in memory and moved into
/// place through [`crate::io::output::write_new`]: atomically, and an existing file is replaced
/// only with `overwrite`.
pub fn write_image(path: &Path, image: &PixelImage, overwrite: bool) -> Result<(), ImageFileError> {
    let err = |message: String| ImageFileError::Write {
        file: path.to_path_buf(),
        message,
    };
    let bytes = match ImageFormat::from_path(path)? {
        ImageFormat::Npy => image_npy_bytes(image),
        ImageFormat::Png => png_bytes(image).map_err(err)?,
        ImageFormat::Exr => exr_bytes(image).map_err(err)?,
    };
    Ok(crate::io::output::write_new(path, &bytes, overwrite)?)
}

#[cfg(feature = "images")]
fn png_bytes(image: &PixelImage) -> Result<Vec<u8>, String> {
    let (w, h) = (image.plane.width() as u32, image.plane.height() as u32);
    let buf = image::RgbImage::from_raw(w, h, srgb8(image)).ok_or("buffer size")?;
    let mut out = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    Ok(out.into_inner())
}

#[cfg(feature = "images")]
fn exr_bytes(image: &PixelImage) -> Result<Vec<u8>, String> {
    let (w, h) = (image.plane.width() as u32, image.plane.height() as u32);
    let data: Vec<f32> = (0..image.plane.pixels())
        .flat_map(|p| rgb_at(image, p).map(|v| v as f32))
        .collect();
    let buf = image::Rgb32FImage::from_raw(w, h, data).ok_or("buffer size")?;
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb32F(buf)
        .write_to(&mut out, image::ImageFormat::OpenExr)
        .map_err(|e| e.to_string())?;
    Ok(out.into_inner())
}

#[cfg(not(feature = "images"))]
fn png_bytes(_image: &PixelImage) -> Result<Vec<u8>, String> {
    Err("PNG needs the `images` feature; rebuild with it or write .npy".into())
}

#[cfg(not(feature = "images"))]
fn exr_bytes(_image: &PixelImage) -> Result<Vec<u8>, String> {
    Err("OpenEXR needs the `images` feature; rebuild with it or write .npy".into())
}

#[cfg(all(test, feature = "images"))]
mod tests {
    use super::*;
    use crate::image::ImagePlane;

    #[test]
    fn png_is_srgb_and_exr_round_trips_linear_values() {
        let plane = ImagePlane::new(3, 2).unwrap();
        let v: Vec<f64> = vec![0.0, 0.5, 1.0, 0.25, 0.1, 2.0];
        let img = PixelImage {
            plane,
            channels: vec![v.clone(), v.clone(), v.clone()],
        };
        let dir = std::env::temp_dir().join(format!("rkwave-imgfile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        write_image(&dir.join("a.png"), &img, true).unwrap();
        let png = image::open(dir.join("a.png")).unwrap().into_rgb8();
        // Linear 0.5 encodes to sRGB 0.7354 -> 188; 0.1 -> 0.3492 -> 89; 2 clamps to 255.
        let reds: Vec<u8> = png.pixels().map(|p| p.0[0]).collect();
        assert_eq!(reds, vec![0, 188, 255, 137, 89, 255]);
        write_image(&dir.join("a.exr"), &img, true).unwrap();
        let exr = image::open(dir.join("a.exr")).unwrap().into_rgb32f();
        for (p, want) in exr.pixels().zip(&v) {
            assert_eq!(p.0[1], *want as f32);
        }
        let npy = image_npy_bytes(&img);
        assert_eq!(npy.len() % 8, 0);
        assert!(std::str::from_utf8(&npy[10..74])
            .unwrap()
            .contains("(2, 3, 3)"));
        assert!(write_image(&dir.join("a.jpg"), &img, true).is_err());
        // Never replaced without being asked.
        let before = std::fs::read(dir.join("a.png")).unwrap();
        assert!(write_image(&dir.join("a.png"), &img, false).is_err());
        assert_eq!(std::fs::read(dir.join("a.png")).unwrap(), before);
        std::fs::remove_dir_all(dir).unwrap();
    }
}

impl ImageFileError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ImageFileError::UnknownFormat { .. } => crate::error::ErrorKind::InvalidInput,
            ImageFileError::Write { .. } => crate::error::ErrorKind::WriteFailed,
            ImageFileError::Output(e) => e.kind(),
        }
    }
}

crate::error::classified!(ImageFileError);
