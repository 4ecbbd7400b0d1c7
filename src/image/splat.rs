//! Weighted splatting: the film-filter reconstruction renderers use (Mitsuba 3's image block;
//! pbrt-v4's filter importance sampling converges to the same image).
//!
//! Pixel `(X, Y)` with centre `c = (X + 1/2, Y + 1/2)` gets
//!
//! `I(X, Y) = sum_i w(x_i - c_x, y_i - c_y) f_i / sum_i w(x_i - c_x, y_i - c_y)`
//!
//! over the samples within the filter's radius (`|dx|, |dy| <= r`), with the separable weight
//! `w(dx, dy) = f(dx) f(dy)` of a [`FilmFilter`].
//!
//! **Near-zero denominators.** Filters with negative lobes (Mitchell, Lanczos) can make
//! `sum w` vanish or change sign. When `|sum w| <= 1e-3 sum |w|` the pixel uses the
//! absolute weights instead, `sum |w_i| f_i / sum |w_i|` (a positive, bounded average of the
//! same samples). When no sample lies within the radius at all (`sum |w| = 0`: a hole, or
//! fewer samples than pixels with the box), the pixel takes the mean of the samples in the
//! nearest non-empty ring of pixels around it. Both counts are reported in
//! [`SplatReport`]; a noise-free 4 spp stratified image has none.
//!
//! Samples are binned by pixel once (a counting sort), then rows of pixels are filled in
//! parallel, each pixel visiting the `(2 floor(r + 1/2) + 1)^2` pixels around it, with each
//! sample's 1D filter factors evaluated once per pixel column and row
//! ([`super::film_weights`]: the same weights, bit for bit).

use serde::Serialize;

use super::film_weights::map_rows;
pub use super::film_weights::PixelBins;
use super::filters::FilmFilter;
use super::{ImageSamples, PixelImage};

/// Relative size of `|sum w|` against `sum |w|` below which a pixel falls back to absolute
/// weights.
pub const CANCELLATION_RATIO: f64 = 1e-3;

/// What the weighted average had to do besides the plain formula.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct SplatReport {
    /// Pixels whose weights nearly cancelled (`|sum w| <= 1e-3 sum |w|`), averaged with
    /// `|w|` instead.
    pub cancelled_pixels: usize,
    /// Pixels with no sample within the radius, filled with the mean of the nearest non-empty
    /// ring of pixels.
    pub empty_pixels: usize,
}

/// The weighted-splatting image of `samples` with the film filter `filter`, and what it had to
/// fall back on (see the module docs).
pub fn splat(samples: &ImageSamples, filter: &dyn FilmFilter) -> (PixelImage, SplatReport) {
    let plane = samples.plane();
    let w = plane.width();
    let channels = samples.channels();
    let bins = PixelBins::new(samples);

    // Per row: interleaved pixel values (X * channels + c) and the two fallback counts; the
    // weights from each sample's 1D factors, evaluated once (`film_weights`).
    let rows: Vec<(Vec<f64>, usize, usize)> = map_rows(samples, &bins, filter, |weights| {
        let py = weights.row();
        let mut out = vec![0.0; w * channels];
        let (mut cancelled, mut empty) = (0, 0);
        let mut num = vec![0.0; channels];
        let mut num_abs = vec![0.0; channels];
        for px in 0..w {
            num.iter_mut().for_each(|v| *v = 0.0);
            num_abs.iter_mut().for_each(|v| *v = 0.0);
            let (mut den, mut den_abs) = (0.0, 0.0);
            weights.pixel(px, |i, _, wt| {
                den += wt;
                den_abs += wt.abs();
                for ((n, na), values) in
                    num.iter_mut().zip(num_abs.iter_mut()).zip(samples.values())
                {
                    *n += wt * values[i];
                    *na += wt.abs() * values[i];
                }
            });
            let px_out = &mut out[px * channels..(px + 1) * channels];
            if den_abs == 0.0 {
                empty += 1;
                nearest_ring_mean(samples, &bins, px, py, px_out);
            } else if den.abs() <= CANCELLATION_RATIO * den_abs {
                cancelled += 1;
                for (o, n) in px_out.iter_mut().zip(&num_abs) {
                    *o = n / den_abs;
                }
            } else {
                for (o, n) in px_out.iter_mut().zip(&num) {
                    *o = n / den;
                }
            }
        }
        (out, cancelled, empty)
    });

    let mut image = PixelImage::zeros(plane, channels);
    let mut report = SplatReport::default();
    for (py, (row, cancelled, empty)) in rows.into_iter().enumerate() {
        report.cancelled_pixels += cancelled;
        report.empty_pixels += empty;
        for px in 0..w {
            for c in 0..channels {
                image.channels[c][py * w + px] = row[px * channels + c];
            }
        }
    }
    (image, report)
}

/// Mean of the samples in the nearest non-empty Chebyshev ring of pixels around `(px, py)`
/// (ring 0 is the pixel itself); zero when there are no samples at all.
fn nearest_ring_mean(
    samples: &ImageSamples,
    bins: &PixelBins,
    px: usize,
    py: usize,
    out: &mut [f64],
) {
    let plane = samples.plane();
    let (w, h) = (plane.width() as isize, plane.height() as isize);
    let max_ring = w.max(h);
    out.iter_mut().for_each(|v| *v = 0.0);
    for ring in 0..=max_ring {
        let mut count = 0usize;
        for qy in (py as isize - ring).max(0)..=(py as isize + ring).min(h - 1) {
            for qx in (px as isize - ring).max(0)..=(px as isize + ring).min(w - 1) {
                let on_ring = (qy - py as isize).abs() == ring || (qx - px as isize).abs() == ring;
                if !on_ring {
                    continue;
                }
                for &i in bins.in_pixel((qy * w + qx) as usize) {
                    count += 1;
                    for (c, o) in out.iter_mut().enumerate() {
                        *o += samples.values()[c][i];
                    }
                }
            }
        }
        if count > 0 {
            out.iter_mut().for_each(|v| *v /= count as f64);
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::filters::FilmFilterKind;
    use crate::image::ImagePlane;

    fn grid_samples(
        plane: ImagePlane,
        per_side: usize,
        f: impl Fn(f64, f64) -> f64,
    ) -> ImageSamples {
        let (mut xs, mut ys, mut vs) = (vec![], vec![], vec![]);
        for py in 0..plane.height() * per_side {
            for px in 0..plane.width() * per_side {
                let x = (px as f64 + 0.5) / per_side as f64;
                let y = (py as f64 + 0.5) / per_side as f64;
                xs.push(x);
                ys.push(y);
                vs.push(f(x, y));
            }
        }
        ImageSamples::new(plane, xs, ys, vec![vs]).unwrap()
    }

    #[test]
    fn constants_are_reproduced_by_every_filter() {
        let plane = ImagePlane::new(7, 5).unwrap();
        let s = grid_samples(plane, 2, |_, _| 0.375);
        for kind in FilmFilterKind::ALL {
            let (img, report) = splat(&s, kind.build().as_ref());
            // A weighted average of equal values is that value up to rounding of the sums.
            assert!(
                img.channels[0].iter().all(|v| (v - 0.375).abs() < 1e-14),
                "{kind}"
            );
            assert_eq!(report, SplatReport::default(), "{kind}");
        }
    }

    #[test]
    fn box_filter_is_the_pixel_mean_and_linear_functions_survive_symmetric_filters() {
        let plane = ImagePlane::new(6, 4).unwrap();
        // Box with 2 x 2 samples per pixel: the mean of the four samples of the pixel.
        let s = grid_samples(plane, 2, |x, y| x * x + 3.0 * y);
        let (img, _) = splat(&s, FilmFilterKind::Box.build().as_ref());
        let (x0, y0) = (2.0, 1.0);
        let mean = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
            .iter()
            .map(|(a, b)| (x0 + a) * (x0 + a) + 3.0 * (y0 + b))
            .sum::<f64>()
            / 4.0;
        assert!((img.get(0, 2, 1) - mean).abs() < 1e-13);
        // Symmetric filters on a sample grid symmetric about the pixel centre within the
        // radius (pixel (5, 5) of 12 x 10: the window [1.5, 9.5]^2 of Lanczos lies inside)
        // reproduce linear functions: the first moment of the weights vanishes.
        let plane = ImagePlane::new(12, 10).unwrap();
        let s = grid_samples(plane, 2, |x, y| 2.0 * x - y);
        for kind in FilmFilterKind::ALL {
            let (img, _) = splat(&s, kind.build().as_ref());
            let v = img.get(0, 5, 5);
            assert!((v - (2.0 * 5.5 - 5.5)).abs() < 1e-12, "{kind}: {v}");
        }
    }

    #[test]
    fn empty_pixels_take_the_nearest_samples_and_are_counted() {
        let plane = ImagePlane::new(8, 8).unwrap();
        let s =
            ImageSamples::new(plane, vec![0.5, 0.6], vec![0.5, 0.4], vec![vec![1.0, 3.0]]).unwrap();
        let (img, report) = splat(&s, FilmFilterKind::Box.build().as_ref());
        assert_eq!(report.empty_pixels, 63);
        assert!(img.channels[0].iter().all(|&v| v == 2.0));
    }
}
