//! The clamp of a reconstruction to the range of each pixel's own samples.
//!
//! `I'(P, c) = min(max(I(P, c), min_i v_{i,c}), max_i v_{i,c})` over the samples `i` in pixel
//! `P`: the Euclidean projection of the image onto the box `prod_P [min_P, max_P]` (pixels
//! without samples are left as they are). A pixel integral of a function whose samples in the
//! pixel all lie in `[a, b]` is not known to lie there (the samples may miss a peak), but a
//! least-squares fit that leaves that range next to a bright edge is ringing, not resolving:
//! the clamp removes the overshoot of the fit beside an emitter and never
//! moves a value that is inside its pixel's range.

use super::statistics::PixelStatistics;
use crate::image::PixelImage;

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
