//! The weights of a separable film filter gathered pixel by pixel, each 1D factor evaluated
//! once per sample and pixel column (or row) instead of once per sample and pixel.
//!
//! Pixel `(X, Y)` (centre `c = (X + 1/2, Y + 1/2)`) weighs sample `i` by
//! `w_i = f(x_i - c_x) f(y_i - c_y)` when `|x_i - c_x| <= r` and `|y_i - c_y| <= r`
//! ([`FilmFilter::eval_2d`], the definition of a separable film). Sample `i` of pixel
//! `(Q_x, Q_y)` reaches the pixels `|X - Q_x|, |Y - Q_y| <= R`, `R = floor(r + 1/2)`, so
//! `f(x_i - c_x)` takes `2 R + 1` values per sample and `f(y_i - c_y)` as many; the direct
//! gather evaluates `f` twice for each of the `(2 R + 1)²` pixels a sample reaches (162 times
//! for Lanczos, `R = 4`), this one `(2 R + 1) (1 + 2 R / B) + (2 R + 1)` times (`B` rows a
//! band, below).
//!
//! **Bands.** Rows of pixels are filled in bands of [`BAND_ROWS`] rows, in parallel. A band
//! `[Y_0, Y_1)` evaluates the `2 R + 1` column factors of every sample in the pixel rows
//! `[Y_0 - R, Y_1 + R)` once (`8 (2 R + 1)` bytes a sample, [`band_cache_bytes`]); each of its
//! rows `Y` then evaluates the row factor `f(y_i - c_y)` of the samples in rows `[Y - R, Y + R]`
//! once, and every pixel of the row multiplies the two cached factors.
//!
//! **The same bits.** The offsets are computed as in the direct gather (`x_i - (X + 1/2)` in
//! `f64`), the factors by the same [`FilmFilter::eval`], multiplied in the order of
//! `eval_2d` (`f(dx) f(dy)`), and handed to the caller in the direct gather's order (pixel rows
//! `Q_y`, then columns `Q_x`, then the pixel's samples in bin order), with the same samples
//! skipped (`|dx| > r` or `|dy| > r`): every sum the caller forms is the direct one's, bit for
//! bit (tests in `image::estimate::sure` and `image::splat` compare with direct loops by `==`).

use std::ops::Range;

use rayon::prelude::*;

use super::filters::{FilmFilter, FilmFilterKind};
use super::ImageSamples;

/// Rows of pixels a band fills with one cache of column factors.
pub const BAND_ROWS: usize = 32;

/// The reach `R = floor(r + 1/2)` in pixels of a film of radius `r`.
pub fn reach(radius: f64) -> usize {
    (radius + 0.5).floor() as usize
}

/// An upper bound of the bytes the column caches hold at once: one band per thread, each
/// `8 (2 R + 1)` bytes for the samples of `B + 2 R` rows, with the samples spread evenly over
/// the `height` rows (`samples (B + 2 R) / height` a band, at most all of them), plus the row
/// factors (8 bytes a sample of `2 R + 1` rows).
pub fn band_cache_bytes(height: usize, samples: f64, reach: usize, threads: usize) -> f64 {
    let k = (2 * reach + 1) as f64;
    let rows = (BAND_ROWS + 2 * reach) as f64;
    let share = |r: f64| (samples * r / height.max(1) as f64).min(samples);
    threads.max(1) as f64 * 8.0 * (k * share(rows) + share(k))
}

/// [`band_cache_bytes`] of the widest of the five films (Lanczos, `R = 4`) on this process's
/// threads: what a film gather (the splat, `auto`'s candidates) holds besides its images.
pub fn film_cache_bytes(height: usize, samples: f64) -> f64 {
    let widest = FilmFilterKind::ALL
        .iter()
        .map(|k| reach(k.build().radius()))
        .max()
        .unwrap_or(0);
    band_cache_bytes(height, samples, widest, rayon::current_num_threads())
}

/// Samples sorted by the pixel that holds them: sample indices of pixel `p` are
/// `order[start[p]..start[p + 1]]`.
pub struct PixelBins {
    /// Start offsets, `W H + 1` of them.
    pub start: Vec<usize>,
    /// Sample indices grouped by pixel.
    pub order: Vec<usize>,
}

impl PixelBins {
    /// Bins the samples by [`super::ImagePlane::pixel_of`] (counting sort, `O(m + W H)`).
    pub fn new(samples: &ImageSamples) -> Self {
        let plane = samples.plane();
        let w = plane.width();
        let cell: Vec<usize> = samples
            .xs()
            .iter()
            .zip(samples.ys())
            .map(|(&x, &y)| {
                let (px, py) = plane.pixel_of(x, y);
                py * w + px
            })
            .collect();
        let mut start = vec![0usize; plane.pixels() + 1];
        for &c in &cell {
            start[c + 1] += 1;
        }
        for p in 0..plane.pixels() {
            start[p + 1] += start[p];
        }
        let mut next = start.clone();
        let mut order = vec![0usize; cell.len()];
        for (i, &c) in cell.iter().enumerate() {
            order[next[c]] = i;
            next[c] += 1;
        }
        Self { start, order }
    }

    /// The sample indices in pixel `p = Y W + X`.
    pub fn in_pixel(&self, p: usize) -> &[usize] {
        &self.order[self.start[p]..self.start[p + 1]]
    }
}

/// One row of pixels with its cached factors: [`Self::pixel`] visits a pixel's weights.
pub struct RowWeights<'a> {
    samples: &'a ImageSamples,
    bins: &'a PixelBins,
    radius: f64,
    reach: usize,
    width: usize,
    height: usize,
    py: usize,
    /// Position in `bins.order` of the band's first cached sample.
    base: usize,
    /// `2 R + 1` column factors a cached sample, `f(x_i - (Q_x - R + k + 1/2))`.
    fx: &'a [f64],
    /// The row factor `f(y_i - (Y + 1/2))` a cached sample (those of rows `Y - R..=Y + R`).
    fy: &'a [f64],
}

impl RowWeights<'_> {
    /// The row `Y`.
    pub fn row(&self) -> usize {
        self.py
    }

    /// Calls `visit(i, q, w_i)` for every sample `i` (in pixel `q`) within the radius of
    /// pixel `(px, Y)`, in the direct gather's order (module docs).
    #[inline]
    pub fn pixel(&self, px: usize, mut visit: impl FnMut(usize, usize, f64)) {
        self.pixel_slots(px, |_, i, q, wt| visit(i, q, wt));
    }

    /// [`Self::pixel`], with each sample's position `pos` in `bins.order` (`order[pos] = i`)
    /// first: `visit(pos, i, q, w_i)`, for data the caller laid out in bin order.
    #[inline]
    pub fn pixel_slots(&self, px: usize, mut visit: impl FnMut(usize, usize, usize, f64)) {
        let (r, reach, w) = (self.radius, self.reach, self.width);
        let k = 2 * reach + 1;
        let (cx, cy) = (px as f64 + 0.5, self.py as f64 + 0.5);
        let (xs, ys) = (self.samples.xs(), self.samples.ys());
        for qy in self.py.saturating_sub(reach)..=(self.py + reach).min(self.height - 1) {
            for qx in px.saturating_sub(reach)..=(px + reach).min(w - 1) {
                let q = qy * w + qx;
                let column = px + reach - qx;
                let (start, end) = (self.bins.start[q], self.bins.start[q + 1]);
                for (pos, &i) in (start..end).zip(&self.bins.order[start..end]) {
                    let (dx, dy) = (xs[i] - cx, ys[i] - cy);
                    if dx.abs() > r || dy.abs() > r {
                        continue;
                    }
                    let slot = pos - self.base;
                    visit(pos, i, q, self.fx[slot * k + column] * self.fy[slot]);
                }
            }
        }
    }
}

/// `row(weights)` for every row of pixels `Y = 0..height`, in order, the rows filled in
/// parallel bands (module docs).
pub fn map_rows<T: Send>(
    samples: &ImageSamples,
    bins: &PixelBins,
    filter: &dyn FilmFilter,
    row: impl Fn(&RowWeights) -> T + Sync,
) -> Vec<T> {
    let plane = samples.plane();
    let (w, h) = (plane.width(), plane.height());
    let reach = reach(filter.radius());
    let k = 2 * reach + 1;
    let bands: Vec<Range<usize>> = (0..h)
        .step_by(BAND_ROWS)
        .map(|y0| y0..(y0 + BAND_ROWS).min(h))
        .collect();
    let (xs, ys) = (samples.xs(), samples.ys());
    let first_of_row = |y: usize| bins.start[y * w];
    bands
        .into_par_iter()
        .flat_map_iter(|band| {
            let (s0, s1) = (band.start.saturating_sub(reach), (band.end + reach).min(h));
            let base = first_of_row(s0);
            let end = first_of_row(s1);
            let mut fx = vec![0.0; (end - base) * k];
            for q in s0 * w..s1 * w {
                let qx = q % w;
                let (start, stop) = (bins.start[q], bins.start[q + 1]);
                for (pos, &i) in (start..stop).zip(&bins.order[start..stop]) {
                    let slot = &mut fx[(pos - base) * k..(pos - base + 1) * k];
                    for (column, f) in slot.iter_mut().enumerate() {
                        // Pixel column `X = Q_x - R + column`; columns off the image stay 0
                        // (never read).
                        if let Some(px) = (qx + column).checked_sub(reach).filter(|&x| x < w) {
                            *f = filter.eval(xs[i] - (px as f64 + 0.5));
                        }
                    }
                }
            }
            let mut fy = vec![0.0; end - base];
            let mut out = Vec::with_capacity(band.len());
            for py in band {
                let (r0, r1) = (py.saturating_sub(reach), (py + reach + 1).min(h));
                let cy = py as f64 + 0.5;
                for pos in first_of_row(r0)..first_of_row(r1) {
                    fy[pos - base] = filter.eval(ys[bins.order[pos]] - cy);
                }
                out.push(row(&RowWeights {
                    samples,
                    bins,
                    radius: filter.radius(),
                    reach,
                    width: w,
                    height: h,
                    py,
                    base,
                    fx: &fx,
                    fy: &fy,
                }));
            }
            out
        })
        .collect()
}

/// Random samples and the direct gather, shared by the tests of the gathers' users.
#[cfg(test)]
pub(crate) mod test_support {
    use rand::{Rng, SeedableRng};

    use super::super::filters::FilmFilter;
    use super::super::{ImagePlane, ImageSamples};
    use super::PixelBins;

    /// `m` uniform positions on a `width x height` plane plus the border's corners and edge
    /// midpoints (`x = 0`, `x = W`, ...), two channels of uniform values in `[-1, 1]`.
    pub fn random_samples(width: usize, height: usize, m: usize, seed: u64) -> ImageSamples {
        let plane = ImagePlane::new(width, height).unwrap();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        let (w, h) = (width as f64, height as f64);
        let mut xs: Vec<f64> = (0..m).map(|_| rng.random_range(0.0..=w)).collect();
        let mut ys: Vec<f64> = (0..m).map(|_| rng.random_range(0.0..=h)).collect();
        for (x, y) in [
            (0.0, 0.0),
            (w, h),
            (0.0, h),
            (w, 0.0),
            (w / 2.0, 0.0),
            (0.0, h / 2.0),
        ] {
            xs.push(x);
            ys.push(y);
        }
        let values = (0..2)
            .map(|_| (0..xs.len()).map(|_| rng.random_range(-1.0..1.0)).collect())
            .collect();
        ImageSamples::new(plane, xs, ys, values).unwrap()
    }

    /// The direct gather of pixel `(px, py)`: `visit(i, q, f(dx) f(dy))` by `eval_2d` for
    /// every sample within the radius, pixel rows, then columns, then bin order.
    pub fn direct_pixel(
        samples: &ImageSamples,
        bins: &PixelBins,
        filter: &dyn FilmFilter,
        (px, py): (usize, usize),
        mut visit: impl FnMut(usize, usize, f64),
    ) {
        let (w, h) = (samples.plane().width(), samples.plane().height());
        let r = filter.radius();
        let reach = (r + 0.5).floor() as isize;
        let (cx, cy) = (px as f64 + 0.5, py as f64 + 0.5);
        for qy in (py as isize - reach).max(0)..=(py as isize + reach).min(h as isize - 1) {
            for qx in (px as isize - reach).max(0)..=(px as isize + reach).min(w as isize - 1) {
                let q = qy as usize * w + qx as usize;
                for &i in bins.in_pixel(q) {
                    let (dx, dy) = (samples.xs()[i] - cx, samples.ys()[i] - cy);
                    if dx.abs() <= r && dy.abs() <= r {
                        visit(i, q, filter.eval_2d(dx, dy));
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::test_support::{direct_pixel, random_samples};
    use super::*;
    use crate::image::filters::FilmFilterKind;

    /// Every pixel sees the same samples, in the same order, with the same weights (`==` on
    /// `f64`) as the direct gather: all five films (the box narrower than a pixel, the others
    /// wider), planes taller than one band and smaller than the reach, samples on the border.
    #[test]
    fn cached_factors_give_the_direct_weights_bit_for_bit() {
        for (width, height, m, seed) in [(37, 2 * BAND_ROWS + 5, 6000, 1), (3, 2, 40, 2)] {
            let samples = random_samples(width, height, m, seed);
            let bins = PixelBins::new(&samples);
            for kind in FilmFilterKind::ALL {
                let filter = kind.build();
                let rows = map_rows(&samples, &bins, filter.as_ref(), |weights| {
                    (0..width)
                        .map(|px| {
                            let mut seen = vec![];
                            weights.pixel(px, |i, q, wt| seen.push((i, q, wt)));
                            seen
                        })
                        .collect::<Vec<_>>()
                });
                assert_eq!(rows.len(), height);
                let mut visits = 0;
                for (py, row) in rows.iter().enumerate() {
                    for (px, seen) in row.iter().enumerate() {
                        let mut direct = vec![];
                        direct_pixel(&samples, &bins, filter.as_ref(), (px, py), |i, q, wt| {
                            direct.push((i, q, wt))
                        });
                        assert_eq!(seen, &direct, "{kind} pixel ({px}, {py})");
                        visits += seen.len();
                    }
                }
                // Each sample is seen by about (2r)² pixels: the comparison is not vacuous.
                assert!(visits >= samples.len(), "{kind}: {visits} visits");
            }
        }
    }

    #[test]
    fn the_cache_bound_covers_one_band_per_thread() {
        // 512 rows, 1M samples, Lanczos (R = 4), 2 threads: 40 rows of 2048 samples with 9
        // factors, plus 9 rows of row factors, twice.
        let bytes = band_cache_bytes(512, 1_048_576.0, 4, 2);
        let expected = 2.0 * 8.0 * (9.0 * 40.0 * 2048.0 + 9.0 * 2048.0);
        assert_eq!(bytes, expected);
        // A plane lower than a band holds all samples, never more.
        assert_eq!(
            band_cache_bytes(4, 100.0, 4, 1),
            8.0 * (9.0 * 100.0 + 100.0)
        );
    }
}
