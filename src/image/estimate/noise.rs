//! The noise of a pixel's mean, estimated from the samples themselves and robust to the
//! pixel's own signal variation.
//!
//! A renderer stratifies the samples of a pixel: `n_P = g_x g_y` samples, one in each cell of a
//! `g_x x g_y` grid, at a uniform position within its cell (jittered or multi-jittered). The box
//! estimate `m_P = (1 / n_P) sum_i v_i` is then an unbiased estimate of the pixel integral with
//! variance `Var(m_P) = (1 / n_P²) sum_k Var_k(v)`, `Var_k` the variance of a sample within cell
//! `k` (Monte Carlo noise plus the signal's variation inside the cell). The plain spread of the
//! samples `s²_P` also counts the signal's variation *between* cells (a gradient, an edge
//! crossing the pixel), which the stratification has already removed from `m_P`.
//!
//! **Second differences of adjacent strata.** The samples are put in their grid (sorted by `y`
//! into `g_y` rows of `g_x`, each row sorted by `x`; `g_x >= g_y`, `g_x g_y = n_P` as square as
//! `n_P` allows). For each 2 x 2 block of adjacent cells `a b / c d`,
//!
//! `D = (v_a - v_b) - (v_c - v_d)`,
//!
//! a difference of two pairs, cancels every function linear over the block at the cells'
//! centres; what is left is the samples' deviations from their cells' means, so for independent
//! samples `E[D²] = sum_{k in block} Var_k`, i.e. `D² / 4` estimates the per-sample variance
//! `s²` of the block. With a single row (`g_y = 1`) the pairs alone are used:
//! `E[(v_a - v_b)²] = Var_a + Var_b` (plus the signal's step across the pair), `(v_a - v_b)² / 2`.
//! The blocks of a pixel are disjoint, `K_P` of them; the per-pixel estimate is
//!
//! `s²_P = (1 / K_P) sum_blocks D² / |block|`, `sigma²_P = s²_P / n_P` (variance of the mean).
//!
//! **Global level.** `sigma_c = sqrt(median_P sigma²_{P,c} / q_K)` over the pixels with a block,
//! `q_K` the median of `chi²_K / K` (`K` the most common block count): for Gaussian noise
//! `sigma²_P ~ sigma² chi²_K / K`, and the median, which ignores the pixels whose blocks see an
//! edge or texture, is unbiased after that division. `q_1 = 0.4549`, `q_2 = ln 2`,
//! `q_3 = 0.7887`, `q_4 = 0.8392` (the chi-square medians), Wilson–Hilferty
//! `(1 - 2 / (9K))³` beyond.

use super::statistics::median;
use crate::image::splat::PixelBins;
use crate::image::{ImagePlane, ImageSamples};

/// Per-pixel noise of the pixel mean and the global median level, per channel; arrays in
/// row-major pixel order (`Y * W + X`).
#[derive(Debug, Clone, PartialEq)]
pub struct PixelNoise {
    /// The image plane.
    pub plane: ImagePlane,
    /// Samples per pixel `n_P`.
    pub count: Vec<usize>,
    /// Blocks (2 x 2 groups of strata, or pairs in a single row) per pixel `K_P`.
    pub blocks: Vec<usize>,
    /// `mean_variance[c][P] = sigma²_{P,c}`, the estimated variance of the pixel's mean (NaN where
    /// `K_P = 0`).
    pub mean_variance: Vec<Vec<f64>>,
    /// The global level of a pixel mean's noise `sigma_c` per channel.
    pub sigma: Vec<f64>,
    /// The global per-sample noise `s_c = sigma_c sqrt(n)` with `n` the median `n_P`.
    pub sample_sigma: Vec<f64>,
    /// The most common block count `K` whose chi-square median corrects the global level.
    pub typical_blocks: usize,
}

/// The grid `(g_x, g_y)` of `n` strata: `g_x g_y = n`, `g_x >= g_y`, as square as possible.
pub fn strata_grid(n: usize) -> (usize, usize) {
    let mut gy = (n as f64).sqrt().floor() as usize;
    while gy > 1 && n % gy != 0 {
        gy -= 1;
    }
    let gy = gy.max(1);
    (n / gy, gy)
}

/// The median of `chi²_K / K`.
pub fn chi_square_median_ratio(k: usize) -> f64 {
    match k {
        0 => f64::NAN,
        1 => 0.454_936_4,
        2 => std::f64::consts::LN_2,
        3 => 0.788_682_2,
        4 => 0.839_173_2,
        _ => (1.0 - 2.0 / (9.0 * k as f64)).powi(3),
    }
}

impl PixelNoise {
    /// The noise of `samples`, binned by `bins`; `None` when no pixel has two samples.
    pub fn new(samples: &ImageSamples, bins: &PixelBins) -> Option<Self> {
        let plane = samples.plane();
        let channels = samples.channels();
        let pixels = plane.pixels();
        let mut count = vec![0usize; pixels];
        let mut blocks = vec![0usize; pixels];
        let mut mean_variance = vec![vec![f64::NAN; pixels]; channels];
        let mut order: Vec<usize> = Vec::new();
        let mut sum = vec![0.0; channels];
        for p in 0..pixels {
            let idx = bins.in_pixel(p);
            let n = idx.len();
            count[p] = n;
            if n < 2 {
                continue;
            }
            let (gx, gy) = strata_grid(n);
            order.clear();
            order.extend_from_slice(idx);
            order.sort_by(|&a, &b| samples.ys()[a].total_cmp(&samples.ys()[b]));
            for row in order.chunks_mut(gx) {
                row.sort_by(|&a, &b| samples.xs()[a].total_cmp(&samples.xs()[b]));
            }
            sum.iter_mut().for_each(|s| *s = 0.0);
            let mut k = 0usize;
            let v = samples.values();
            if gy == 1 {
                for pair in order.chunks_exact(2) {
                    for (s, vc) in sum.iter_mut().zip(v) {
                        let d = vc[pair[0]] - vc[pair[1]];
                        *s += d * d / 2.0;
                    }
                    k += 1;
                }
            } else {
                for r in (0..gy - 1).step_by(2) {
                    for col in (0..gx - 1).step_by(2) {
                        let (a, b) = (order[r * gx + col], order[r * gx + col + 1]);
                        let (c, d) = (order[(r + 1) * gx + col], order[(r + 1) * gx + col + 1]);
                        for (s, vc) in sum.iter_mut().zip(v) {
                            let dd = (vc[a] - vc[b]) - (vc[c] - vc[d]);
                            *s += dd * dd / 4.0;
                        }
                        k += 1;
                    }
                }
            }
            blocks[p] = k;
            for (mv, s) in mean_variance.iter_mut().zip(&sum) {
                mv[p] = s / k as f64 / n as f64;
            }
        }
        let with_blocks: Vec<usize> = (0..pixels).filter(|&p| blocks[p] > 0).collect();
        if with_blocks.is_empty() {
            return None;
        }
        let typical_blocks = mode(with_blocks.iter().map(|&p| blocks[p]));
        let typical_count = median(
            &mut with_blocks
                .iter()
                .map(|&p| count[p] as f64)
                .collect::<Vec<_>>(),
        );
        let q = chi_square_median_ratio(typical_blocks);
        let sigma: Vec<f64> = mean_variance
            .iter()
            .map(|mv| {
                (median(&mut with_blocks.iter().map(|&p| mv[p]).collect::<Vec<_>>()) / q).sqrt()
            })
            .collect();
        let sample_sigma = sigma.iter().map(|s| s * typical_count.sqrt()).collect();
        Some(Self {
            plane,
            count,
            blocks,
            mean_variance,
            sigma,
            sample_sigma,
            typical_blocks,
        })
    }

    /// Pixels with at least one block (whose own noise is estimated).
    pub fn pixels_with_blocks(&self) -> usize {
        self.blocks.iter().filter(|&&k| k > 0).count()
    }

    /// The variance of one sample of pixel `p` in channel `c`: `n_P sigma²_{P,c}`, or the global
    /// `s_c²` where the pixel has no block.
    pub fn sample_variance(&self, c: usize, p: usize) -> f64 {
        let v = self.mean_variance[c][p];
        if v.is_nan() {
            self.sample_sigma[c] * self.sample_sigma[c]
        } else {
            v * self.count[p] as f64
        }
    }

    /// The variance of pixel `p`'s mean in channel `c` (the global level where `n_P < 2`, and
    /// for `n_P = 0` the per-sample level).
    pub fn pixel_variance(&self, c: usize, p: usize) -> f64 {
        self.sample_variance(c, p) / self.count[p].max(1) as f64
    }
}

/// The most frequent value (the smallest among ties).
fn mode(values: impl Iterator<Item = usize>) -> usize {
    let mut counts = std::collections::BTreeMap::new();
    for v in values {
        *counts.entry(v).or_insert(0usize) += 1;
    }
    let best = counts.values().copied().max().unwrap_or(0);
    counts
        .into_iter()
        .find(|&(_, n)| n == best)
        .map_or(0, |(v, _)| v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grids_are_as_square_as_the_count_allows() {
        assert_eq!(strata_grid(4), (2, 2));
        assert_eq!(strata_grid(8), (4, 2));
        assert_eq!(strata_grid(16), (4, 4));
        assert_eq!(strata_grid(2), (2, 1));
        assert_eq!(strata_grid(7), (7, 1));
        assert_eq!(strata_grid(9), (3, 3));
    }

    #[test]
    fn chi_square_medians_continue_smoothly() {
        // Wilson–Hilferty at K = 4 (0.8424) is within 0.4 % of the exact median (0.8392), and
        // its error falls as K grows, so the switch at K = 5 costs less than that.
        assert!((chi_square_median_ratio(4) - (1.0 - 2.0 / 36.0f64).powi(3)).abs() < 4e-3);
        assert!(chi_square_median_ratio(5) > chi_square_median_ratio(4));
    }

    #[test]
    fn second_differences_cancel_a_plane_at_the_cell_centres() {
        // 2 x 2 samples at the cell centres of a linear function: D = 0 exactly.
        let plane = ImagePlane::new(1, 1).unwrap();
        let (xs, ys) = (vec![0.25, 0.75, 0.25, 0.75], vec![0.25, 0.25, 0.75, 0.75]);
        let vs: Vec<f64> = xs.iter().zip(&ys).map(|(x, y)| 3.0 * x - 5.0 * y).collect();
        let s = ImageSamples::new(plane, xs, ys, vec![vs]).unwrap();
        let noise = PixelNoise::new(&s, &PixelBins::new(&s)).unwrap();
        assert_eq!(noise.blocks, vec![1]);
        assert!(noise.mean_variance[0][0].abs() < 1e-28);
    }
}
