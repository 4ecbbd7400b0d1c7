//! The clamp of a reconstruction to the range of each pixel's own samples, and to the range of
//! the samples in its 3x3 neighbourhood ([`clamp_to_local_range`], the last step of `auto` and
//! of the plan's outputs).
//!
//! `I'(P, c) = min(max(I(P, c), min_i v_{i,c}), max_i v_{i,c})` over the samples `i` in pixel
//! `P`: the Euclidean projection of the image onto the box `prod_P [min_P, max_P]` (pixels
//! without samples are left as they are). A pixel integral of a function whose samples in the
//! pixel all lie in `[a, b]` is not known to lie there (the samples may miss a peak), but a
//! least-squares fit that leaves that range next to a bright edge is ringing, not resolving:
//! the clamp removes the overshoot of the fit beside an emitter and never
//! moves a value that is inside its pixel's range.

use super::statistics::PixelStatistics;
use crate::image::{ImagePlane, PixelImage};

/// Clamps every pixel of `image` with samples to the range of its samples, in place; returns
/// the number of values (pixels x channels) that moved.
pub fn clamp_to_sample_range(image: &mut PixelImage, stats: &PixelStatistics) -> usize {
    let mut moved = 0;
    for (c, channel) in image.channels.iter_mut().enumerate() {
        for (p, v) in channel.iter_mut().enumerate() {
            if stats.count[p] == 0 {
                continue;
            }
            let clamped = v.clamp(stats.min[c][p], stats.max[c][p]);
            if clamped != *v {
                *v = clamped;
                moved += 1;
            }
        }
    }
    moved
}

/// Moves of the range clamp at most this large are applied but not counted in
/// `ResidualCorrection::clamped` (the fit's rounding in regions of constant value, where
/// every sample has the same value and the fit is within ulps of it).
pub const CLAMP_COUNT_TOLERANCE: f64 = 1e-9;

/// Clamps every channel of `pixels` (per channel, `W H` row-major on `plane`) to the range
/// `[lo_P, hi_P]` of `values` over the samples at `(xs[i], ys[i])` in the pixel and its eight
/// neighbours (pixels with none keep their value). Returns the pixels moved by more than
/// [`CLAMP_COUNT_TOLERANCE`] in some channel and the largest move.
pub fn clamp_to_local_range(
    pixels: &mut [Vec<f64>],
    plane: ImagePlane,
    xs: &[f64],
    ys: &[f64],
    values: &[Vec<f64>],
) -> (usize, f64) {
    let (w, h) = (plane.width(), plane.height());
    // the range of each pixel's own samples, then of its 3x3 neighbourhood
    let mut own = vec![(f64::INFINITY, f64::NEG_INFINITY); w * h * values.len()];
    for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
        let (px, py) = plane.pixel_of(x, y);
        for (c, v) in values.iter().enumerate() {
            let r = &mut own[(py * w + px) * values.len() + c];
            *r = (r.0.min(v[i]), r.1.max(v[i]));
        }
    }
    let (mut clamped, mut largest) = (0, 0.0f64);
    for py in 0..h {
        for px in 0..w {
            let p = py * w + px;
            let mut moved = false;
            for (c, channel) in pixels.iter_mut().enumerate() {
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for qy in py.saturating_sub(1)..(py + 2).min(h) {
                    for qx in px.saturating_sub(1)..(px + 2).min(w) {
                        let r = own[(qy * w + qx) * values.len() + c];
                        (lo, hi) = (lo.min(r.0), hi.max(r.1));
                    }
                }
                if lo > hi {
                    continue;
                }
                let v = channel[p].clamp(lo, hi);
                let d = (v - channel[p]).abs();
                moved |= d > CLAMP_COUNT_TOLERANCE;
                largest = largest.max(d);
                channel[p] = v;
            }
            clamped += usize::from(moved);
        }
    }
    (clamped, largest)
}
