//! Per-pixel statistics of the samples in one pass, and the pooled noise level.
//!
//! For pixel `P = [X, X + 1) x [Y, Y + 1)` (a sample belongs to the pixel
//! [`ImagePlane::pixel_of`] gives) and channel `c`, with `n_P` samples `v_1 .. v_n` in it:
//!
//! * the box estimate `m_{P,c} = (1 / n_P) sum_i v_i` (the box film);
//! * the variance of that mean `s²_{P,c} / n_P`, with `s²_{P,c} = sum_i (v_i - m)² / (n_P - 1)`
//!   the unbiased spread of the samples (defined for `n_P >= 2`);
//! * the range `[min_i v_i, max_i v_i]`.
//!
//! The mean and the sum of squared deviations are accumulated by Welford's update
//! (`m_k = m_{k-1} + (v_k - m_{k-1}) / k`, `M_k = M_{k-1} + (v_k - m_{k-1}) (v_k - m_k)`),
//! one pass without the cancellation of `sum v² - n m²`.
//!
//! **Pooled noise level.** `sigma_c = sqrt(median_P s²_{P,c} / n_P)` over the pixels with
//! `n_P >= 2`: the typical standard error of a pixel's mean. The median, not the mean, so that
//! the pixels whose spread is signal (texture past Nyquist, an edge crossing the pixel) do not
//! raise it; on a scene without Monte Carlo noise it is near zero, and shrinkage by it changes
//! nothing (`docs/measurements/real-renders.md`, "Prototype: noise-aware pixel estimates").

use crate::image::{ImagePlane, ImageSamples};

/// Count, mean, variance of the mean and range of the samples of every pixel and channel;
/// arrays per channel in row-major pixel order (`Y * W + X`).
#[derive(Debug, Clone, PartialEq)]
pub struct PixelStatistics {
    /// The image plane.
    pub plane: ImagePlane,
    /// Samples per pixel `n_P`.
    pub count: Vec<usize>,
    /// `mean[c][P]`: the box estimate (0 where `n_P = 0`).
    pub mean: Vec<Vec<f64>>,
    /// `mean_variance[c][P] = s²_{P,c} / n_P` (NaN where `n_P < 2`: no spread is known).
    pub mean_variance: Vec<Vec<f64>>,
    /// `min[c][P]`: the smallest sample value (+inf where `n_P = 0`).
    pub min: Vec<Vec<f64>>,
    /// `max[c][P]`: the largest sample value (-inf where `n_P = 0`).
    pub max: Vec<Vec<f64>>,
}

impl PixelStatistics {
    /// The statistics of `samples`, in one pass over them.
    pub fn new(samples: &ImageSamples) -> Self {
        Self::of(
            samples.plane(),
            samples.xs(),
            samples.ys(),
            samples.values(),
        )
    }

    /// The statistics of the samples at `(xs[i], ys[i])` with `values[c][i]` on `plane`
    /// (positions in the plane, values finite: as [`ImageSamples`] checks them).
    pub fn of(plane: ImagePlane, xs: &[f64], ys: &[f64], values: &[Vec<f64>]) -> Self {
        let (pixels, channels) = (plane.pixels(), values.len());
        let mut count = vec![0usize; pixels];
        let mut mean = vec![vec![0.0; pixels]; channels];
        let mut m2 = vec![vec![0.0; pixels]; channels];
        let mut min = vec![vec![f64::INFINITY; pixels]; channels];
        let mut max = vec![vec![f64::NEG_INFINITY; pixels]; channels];
        for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
            let (px, py) = plane.pixel_of(x, y);
            let p = py * plane.width() + px;
            count[p] += 1;
            let k = count[p] as f64;
            for c in 0..channels {
                let v = values[c][i];
                let delta = v - mean[c][p];
                mean[c][p] += delta / k;
                m2[c][p] += delta * (v - mean[c][p]);
                min[c][p] = min[c][p].min(v);
                max[c][p] = max[c][p].max(v);
            }
        }
        let mean_variance = m2
            .iter()
            .map(|m2c| {
                m2c.iter()
                    .zip(&count)
                    .map(|(&s, &n)| {
                        if n >= 2 {
                            s / (n - 1) as f64 / n as f64
                        } else {
                            f64::NAN
                        }
                    })
                    .collect()
            })
            .collect();
        Self {
            plane,
            count,
            mean,
            mean_variance,
            min,
            max,
        }
    }

    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.mean.len()
    }

    /// Pixels without any sample.
    pub fn empty_pixels(&self) -> usize {
        self.count.iter().filter(|&&n| n == 0).count()
    }

    /// Pixels with at least two samples (those whose spread is known).
    pub fn pixels_with_spread(&self) -> usize {
        self.count.iter().filter(|&&n| n >= 2).count()
    }

    /// The pooled noise level `sigma_c = sqrt(median_P s²_{P,c} / n_P)` per channel, over the
    /// pixels with at least two samples; `None` when no pixel has two.
    pub fn noise_level(&self) -> Option<Vec<f64>> {
        if self.pixels_with_spread() == 0 {
            return None;
        }
        Some(
            self.mean_variance
                .iter()
                .map(|var| {
                    let mut known: Vec<f64> = var.iter().copied().filter(|v| !v.is_nan()).collect();
                    median(&mut known).sqrt()
                })
                .collect(),
        )
    }
}

/// The median of a non-empty list (the mean of the two middle values for an even count, as
/// numpy's `median`), in the order `f64::total_cmp`.
///
/// By selection, not a sort (`O(n)`; `values` is left permuted, not sorted): the `k`-th
/// smallest value of a total order is one value whatever the algorithm, and the lower middle
/// `v_(n/2 - 1)` of an even count is the largest of the `n / 2` values selection leaves
/// below `v_(n/2)`, so the result is the sorted list's bit for bit.
pub(super) fn median(values: &mut [f64]) -> f64 {
    let n = values.len();
    let (below, &mut upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    if n % 2 == 1 {
        upper
    } else {
        let lower = below
            .iter()
            .copied()
            .max_by(f64::total_cmp)
            .expect("an even, non-empty list has a value below its middle");
        0.5 * (lower + upper)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_pixels_by_hand() {
        let plane = ImagePlane::new(2, 1).unwrap();
        // Pixel 0: 1, 2, 3 (mean 2, s² 1, variance of the mean 1/3); pixel 1: 5 alone.
        let samples = ImageSamples::new(
            plane,
            vec![0.1, 0.5, 0.9, 1.5],
            vec![0.5; 4],
            vec![vec![1.0, 2.0, 3.0, 5.0]],
        )
        .unwrap();
        let s = PixelStatistics::new(&samples);
        assert_eq!(s.count, vec![3, 1]);
        assert_eq!(s.mean[0], vec![2.0, 5.0]);
        // Exact: every operation of Welford's update on these integers is exact in binary.
        assert!((s.mean_variance[0][0] - 1.0 / 3.0).abs() <= f64::EPSILON);
        assert!(s.mean_variance[0][1].is_nan());
        assert_eq!((s.min[0][0], s.max[0][0]), (1.0, 3.0));
        assert_eq!(s.noise_level(), Some(vec![(s.mean_variance[0][0]).sqrt()]));
    }

    #[test]
    fn median_is_numpys() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&mut [4.0, 1.0, 2.0, 3.0]), 2.5);
    }

    /// The selection gives the sorted list's middle bit for bit (`to_bits` equality, no
    /// tolerance): odd and even counts, ties, signed zeros, lists of one and two.
    #[test]
    fn median_by_selection_is_the_sorted_median_bit_for_bit() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as f64 / (1u64 << 31) as f64
        };
        for n in 1..60 {
            for coarse in [false, true] {
                let values: Vec<f64> = (0..n)
                    .map(|k| {
                        let x = next() - 0.5;
                        match (coarse, k % 7) {
                            (_, 3) => -0.0,
                            (_, 5) => 0.0,
                            (true, _) => (4.0 * x).round(),
                            (false, _) => x,
                        }
                    })
                    .collect();
                let mut sorted = values.clone();
                sorted.sort_by(f64::total_cmp);
                let expected = if n % 2 == 1 {
                    sorted[n / 2]
                } else {
                    0.5 * (sorted[n / 2 - 1] + sorted[n / 2])
                };
                let got = median(&mut values.clone());
                assert_eq!(got.to_bits(), expected.to_bits(), "{values:?}");
            }
        }
    }
}
