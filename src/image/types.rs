//! The image plane's data: a validated resolution ([`ImagePlane`]), validated scattered
//! samples on it ([`ImageSamples`]), a grid of pixel values ([`PixelImage`]), and why the
//! first two could not be built ([`ImageError`]).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The fix a refusal of non-finite samples names: drop and count them
/// (`NonFinitePolicy::Drop` of `image::nonfinite`), spelled as each front end spells it.
const DROP_FIX: crate::error::fix::Fix = crate::error::fix::Fix::DropNonfinite;

/// The largest accepted side of an image, in pixels (`2^16`).
///
/// Larger sides are rejected as absurd: a `65536 x 65536` RGB image of `f64` is already
/// 100 GB.
pub const MAX_SIDE: usize = 1 << 16;

/// The largest number of channels a sample may carry (RGBA).
pub const MAX_CHANNELS: usize = 4;

/// Why an [`ImagePlane`] or [`ImageSamples`] could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ImageError {
    /// The width or the height is zero.
    #[error(
        "invalid image resolution {width} x {height}: both sides must be at least 1 pixel; \
         give a resolution such as 256 x 256"
    )]
    EmptyResolution {
        /// The width as given.
        width: usize,
        /// The height as given.
        height: usize,
    },
    /// The width or the height exceeds [`MAX_SIDE`].
    #[error(
        "invalid image resolution {width} x {height}: each side must be at most {max} pixels; \
         render tiles of at most that size"
    )]
    AbsurdResolution {
        /// The width as given.
        width: usize,
        /// The height as given.
        height: usize,
        /// The largest accepted side, [`MAX_SIDE`].
        max: usize,
    },
    /// A resolution string is not of the form `WxH`.
    #[error(
        "cannot read an image resolution from `{input}`: expected `WxH` with two positive \
         integers, for example `512x512` or `640x480`"
    )]
    ParseResolution {
        /// The text that failed to parse.
        input: String,
    },
    /// The position arrays have different lengths.
    #[error(
        "image samples have {xs} x positions but {ys} y positions; give one (x, y) pair per sample"
    )]
    PositionLengths {
        /// Number of x positions.
        xs: usize,
        /// Number of y positions.
        ys: usize,
    },
    /// The number of channels is 0 or more than [`MAX_CHANNELS`].
    #[error(
        "image samples have {channels} channels: between 1 and {max} are supported \
         (grey, grey + alpha, RGB, RGBA)"
    )]
    ChannelCount {
        /// Number of channels given.
        channels: usize,
        /// The largest accepted number, [`MAX_CHANNELS`].
        max: usize,
    },
    /// A channel has a different number of values than there are positions.
    #[error(
        "image samples: channel {channel} has {len} values but there are {samples} positions; \
         give one value per sample in every channel"
    )]
    ChannelLength {
        /// The channel at fault (from 0).
        channel: usize,
        /// Its number of values.
        len: usize,
        /// The number of sample positions.
        samples: usize,
    },
    /// A sample position lies outside `[0, W] x [0, H]` or is not finite.
    #[error(
        "image sample {index} at (x, y) = ({x}, {y}) lies outside the image [0, {width}] x \
         [0, {height}]; positions are in pixel units: drop the sample or give a larger resolution"
    )]
    OutsideImage {
        /// Index of the sample at fault.
        index: usize,
        /// Its x position.
        x: f64,
        /// Its y position.
        y: f64,
        /// Image width.
        width: usize,
        /// Image height.
        height: usize,
    },
    /// A sample value is NaN or infinite.
    #[error(
        "image sample {index} has the value {value} in channel {channel}: values must be finite; \
         remove or clamp non-finite samples"
    )]
    NonFiniteValue {
        /// Index of the sample at fault.
        index: usize,
        /// The channel at fault.
        channel: usize,
        /// The value as given.
        value: f64,
    },
    /// Samples whose value is NaN or infinite in some channel, refused as a whole
    /// (`NonFinitePolicy::Refuse` of `image::nonfinite`).
    #[error(
        "{count} samples have a value that is not finite (NaN or Inf); the first is row {row} \
         at (x, y) = ({x}, {y}), channel {channel}: {value}; fix the renderer, or drop \
         and count them with {fix}",
        fix = DROP_FIX
    )]
    NonFiniteSamples {
        /// How many samples are non-finite.
        count: usize,
        /// The first one's 1-based row.
        row: usize,
        /// Its x position.
        x: f64,
        /// Its y position.
        y: f64,
        /// Its first non-finite channel (from 0).
        channel: usize,
        /// That value.
        value: f64,
    },
}

/// The image rectangle `[0, W] x [0, H]` in pixel units, `1 <= W, H <=` [`MAX_SIDE`].
///
/// Fields are private so every plane is valid; build one with [`ImagePlane::new`] or parse
/// `"WxH"`. It serialises as `{"width": .., "height": ..}` and deserialisation validates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "RawPlane")]
pub struct ImagePlane {
    width: usize,
    height: usize,
}

#[derive(Deserialize)]
struct RawPlane {
    width: usize,
    height: usize,
}

impl TryFrom<RawPlane> for ImagePlane {
    type Error = ImageError;
    fn try_from(raw: RawPlane) -> Result<Self, ImageError> {
        ImagePlane::new(raw.width, raw.height)
    }
}

impl ImagePlane {
    /// The plane `[0, width] x [0, height]`; both sides in `1..=MAX_SIDE`.
    pub fn new(width: usize, height: usize) -> Result<Self, ImageError> {
        if width == 0 || height == 0 {
            return Err(ImageError::EmptyResolution { width, height });
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(ImageError::AbsurdResolution {
                width,
                height,
                max: MAX_SIDE,
            });
        }
        Ok(Self { width, height })
    }

    /// Width `W` in pixels.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height `H` in pixels.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of pixels `W H`.
    pub fn pixels(&self) -> usize {
        self.width * self.height
    }

    /// Whether `(x, y)` lies in the closed rectangle `[0, W] x [0, H]` (false for NaN).
    pub fn contains(&self, x: f64, y: f64) -> bool {
        (0.0..=self.width as f64).contains(&x) && (0.0..=self.height as f64).contains(&y)
    }

    /// The pixel `(X, Y)` holding `(x, y)`: `X = floor(x)` clamped to `W - 1` (so the right
    /// and top edges belong to the last pixel), likewise `Y`.
    pub fn pixel_of(&self, x: f64, y: f64) -> (usize, usize) {
        let px = (x.max(0.0).floor() as usize).min(self.width - 1);
        let py = (y.max(0.0).floor() as usize).min(self.height - 1);
        (px, py)
    }
}

impl std::fmt::Display for ImagePlane {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

impl std::str::FromStr for ImagePlane {
    type Err = ImageError;
    /// Parses `WxH` (also `W*H` or `W,H`), for example `512x512`.
    fn from_str(s: &str) -> Result<Self, ImageError> {
        let bad = || ImageError::ParseResolution {
            input: s.to_string(),
        };
        let t = s.trim();
        let (w, h) = t.split_once(['x', 'X', '*', ',']).ok_or_else(bad)?;
        let w: usize = w.trim().parse().map_err(|_| bad())?;
        let h: usize = h.trim().parse().map_err(|_| bad())?;
        ImagePlane::new(w, h)
    }
}

/// Scattered samples `(x_i, y_i, f_i)` on an [`ImagePlane`], values stored per channel:
/// `values[c][i]` is channel `c` of sample `i`.
///
/// Every sample lies in `[0, W] x [0, H]`, every value is finite and every channel has one
/// value per position (checked by [`ImageSamples::new`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageSamples {
    plane: ImagePlane,
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
}

impl ImageSamples {
    /// Validated samples on `plane`: positions inside the rectangle, finite values, 1 to
    /// [`MAX_CHANNELS`] channels each as long as the positions.
    pub fn new(
        plane: ImagePlane,
        xs: Vec<f64>,
        ys: Vec<f64>,
        values: Vec<Vec<f64>>,
    ) -> Result<Self, ImageError> {
        if xs.len() != ys.len() {
            return Err(ImageError::PositionLengths {
                xs: xs.len(),
                ys: ys.len(),
            });
        }
        if values.is_empty() || values.len() > MAX_CHANNELS {
            return Err(ImageError::ChannelCount {
                channels: values.len(),
                max: MAX_CHANNELS,
            });
        }
        for (channel, v) in values.iter().enumerate() {
            if v.len() != xs.len() {
                return Err(ImageError::ChannelLength {
                    channel,
                    len: v.len(),
                    samples: xs.len(),
                });
            }
        }
        for (index, (&x, &y)) in xs.iter().zip(&ys).enumerate() {
            if !plane.contains(x, y) {
                return Err(ImageError::OutsideImage {
                    index,
                    x,
                    y,
                    width: plane.width,
                    height: plane.height,
                });
            }
        }
        for (channel, v) in values.iter().enumerate() {
            if let Some((index, &value)) = v.iter().enumerate().find(|(_, f)| !f.is_finite()) {
                return Err(ImageError::NonFiniteValue {
                    index,
                    channel,
                    value,
                });
            }
        }
        Ok(Self {
            plane,
            xs,
            ys,
            values,
        })
    }

    /// The image plane the samples lie on.
    pub fn plane(&self) -> ImagePlane {
        self.plane
    }

    /// Number of samples `m`.
    pub fn len(&self) -> usize {
        self.xs.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.xs.is_empty()
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.values.len()
    }

    /// The x positions `x_i` (pixel units).
    pub fn xs(&self) -> &[f64] {
        &self.xs
    }

    /// The y positions `y_i` (pixel units).
    pub fn ys(&self) -> &[f64] {
        &self.ys
    }

    /// The values, per channel: `values()[c][i]`.
    pub fn values(&self) -> &[Vec<f64>] {
        &self.values
    }

    /// The positions and values moved out, `(xs, ys, values)` (no copy: a caller that adds
    /// samples between rounds takes them back, appends and validates again).
    pub fn into_parts(self) -> (Vec<f64>, Vec<f64>, Vec<Vec<f64>>) {
        (self.xs, self.ys, self.values)
    }

    /// Channel `c` of every sample.
    pub fn channel(&self, c: usize) -> &[f64] {
        &self.values[c]
    }
}

/// Pixel values on an [`ImagePlane`]: `channels[c][Y * W + X]` is channel `c` of pixel
/// `(X, Y)` (row `Y` from the top).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PixelImage {
    /// The resolution.
    pub plane: ImagePlane,
    /// Per channel, `W H` values in row-major order.
    pub channels: Vec<Vec<f64>>,
}

impl PixelImage {
    /// A zero image with `channels` channels.
    pub fn zeros(plane: ImagePlane, channels: usize) -> Self {
        Self {
            plane,
            channels: vec![vec![0.0; plane.pixels()]; channels],
        }
    }

    /// Channel `c` of pixel `(X, Y)`.
    pub fn get(&self, c: usize, x: usize, y: usize) -> f64 {
        self.channels[c][y * self.plane.width() + x]
    }

    /// Number of channels.
    pub fn channel_count(&self) -> usize {
        self.channels.len()
    }
}

impl ImageError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            ImageError::AbsurdResolution { .. } => crate::error::ErrorKind::ResourceLimit,
            ImageError::EmptyResolution { .. }
            | ImageError::ParseResolution { .. }
            | ImageError::PositionLengths { .. }
            | ImageError::ChannelCount { .. }
            | ImageError::ChannelLength { .. }
            | ImageError::OutsideImage { .. }
            | ImageError::NonFiniteValue { .. }
            | ImageError::NonFiniteSamples { .. } => crate::error::ErrorKind::InvalidInput,
        }
    }
}

crate::error::classified!(ImageError);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plane_rejects_zero_and_absurd_sides_naming_them() {
        assert_eq!(
            ImagePlane::new(0, 5),
            Err(ImageError::EmptyResolution {
                width: 0,
                height: 5
            })
        );
        let e = ImagePlane::new(10, MAX_SIDE + 1).unwrap_err();
        assert!(e.to_string().contains(&(MAX_SIDE + 1).to_string()));
        assert!("12x".parse::<ImagePlane>().is_err());
        assert_eq!(
            "640x480".parse::<ImagePlane>().unwrap(),
            ImagePlane::new(640, 480).unwrap()
        );
        let bad: Result<ImagePlane, _> = serde_json::from_str(r#"{"width":0,"height":3}"#);
        assert!(bad.is_err());
    }

    #[test]
    fn samples_are_validated() {
        let plane = ImagePlane::new(4, 3).unwrap();
        let ok = ImageSamples::new(plane, vec![0.0, 4.0], vec![3.0, 1.5], vec![vec![1.0, 2.0]]);
        assert_eq!(ok.unwrap().len(), 2);
        let out = ImageSamples::new(plane, vec![4.5], vec![1.0], vec![vec![1.0]]).unwrap_err();
        assert!(matches!(out, ImageError::OutsideImage { index: 0, .. }));
        let nan = ImageSamples::new(plane, vec![1.0], vec![1.0], vec![vec![f64::NAN]]);
        assert!(matches!(nan, Err(ImageError::NonFiniteValue { .. })));
        let len = ImageSamples::new(plane, vec![1.0], vec![1.0], vec![vec![1.0], vec![]]);
        assert!(matches!(
            len,
            Err(ImageError::ChannelLength { channel: 1, .. })
        ));
        let none = ImageSamples::new(plane, vec![1.0], vec![1.0], vec![]);
        assert!(matches!(none, Err(ImageError::ChannelCount { .. })));
        assert_eq!(plane.pixel_of(4.0, 3.0), (3, 2));
    }
}
