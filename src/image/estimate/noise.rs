//! The noise of a pixel's mean, estimated from the samples themselves and robust to the
//! pixel's own signal variation.
//!
//! A renderer stratifies the samples of a pixel: `n_P = g_x g_y` samples, one in each cell of a
//! `g_x x g_y` grid, at a uniform position within its cell (jittered), and a multi-jittered
//! sampler (Mitsuba's default, Kensler's correlated multi-jitter) puts them in addition one in
//! each of the `n_P` columns `[k / n, (k + 1) / n)` and one in each of the `n_P` rows (a Latin
//! hypercube). The box estimate `m_P = (1 / n_P) sum_i v_i` is then an unbiased estimate of the
//! pixel integral with a variance much smaller than `s² / n_P` (`s²` the spread of one sample)
//! wherever the signal varies smoothly at the scale of the strata: the strata remove the
//! variation *between* them (a gradient, an edge crossing the pixel, texture coarser than a
//! stratum), which is signal of the pixel integral, not noise. What is left is the variation
//! *within* a stratum: Monte Carlo noise and texture finer than a stratum.
//!
//! **Three difference estimates**, each with expectation `s²` for independent samples of
//! equal variance (pure noise) and each blind to a class of signal variation between strata:
//!
//! 1. *Second differences of the 2D strata.* The samples are put in their grid (sorted by `y`
//!    into `g_y` rows of `g_x`, each row sorted by `x`; `g_x >= g_y`, `g_x g_y = n_P` as square
//!    as `n_P` allows). For each 2 x 2 block of adjacent cells `a b / c d`,
//!    `D = (v_a - v_b) - (v_c - v_d)` cancels every function linear over the block at the
//!    cells' centres and every step between two rows or two columns of cells, so
//!    `E[D²] = sum_{k in block} Var_k` and `D² / 4` estimates `s²`. With a single row
//!    (`g_y = 1`) the pairs `(v_a - v_b)² / 2`. Blocks are disjoint, `K_P` of them;
//!    `s²_grid = (1 / K_P) sum_blocks D² / |block|`.
//! 2. *Successive differences in `x`.* Sorted by `x`, `x_(1) < ... < x_(n)`, a Latin
//!    hypercube puts consecutive samples in adjacent columns of width `1 / n`:
//!    `s²_x = sum_i (v_(i+1) - v_(i))² / (2 (n - 1))`. A signal varying along `x` only
//!    contributes `f'(x)² (x_(i+1) - x_(i))²` with spacing `<= 2 / n`, an edge across `x`
//!    one difference among `n - 1`: the variation the columns stratify away.
//! 3. *Successive differences in `y`*, the same with the rows: `s²_y`.
//!
//! Each is the stratified variance plus a non-negative bias, the squared signal variation
//! its differences do not cancel. The pixel takes the estimate of least sum over channels,
//! `s²_P = s²_{e*}`, `e* = argmin_e sum_c s²_{e,c}`, and `sigma²_P = s²_P / n_P` (variance of
//! the mean). The least of three is biased low for pure noise (the minimum of three estimates
//! of one `s²`, each a sum of a few squared differences): by 28-44 % at 4 to 16 samples a pixel
//! (measured by `tests/estimators_noise.rs` against the exact variance), which makes the risk
//! gate (`gate.rs`) keep the box a little more often; the bias of the single estimates
//! on textured and edged pixels, which made the gate smooth away signal, is what it removes
//! (docs/measurements/estimators.md). The per-pixel choice is counted in the report.
//!
//! **Bias on pure noise, measured per image.** How far the least of three falls short of `s²`
//! on pure noise depends on how the three orderings of a pixel's samples share differences,
//! hence on the sample positions (sampler and count). For i.i.d. values `z_i ~ N(0, 1)` at the
//! image's own positions, every single estimate has expectation 1 and
//! `c = E s²_{e*}(z)` is the least of three's; one draw per pixel gives
//! `c ≈ sum_P s²_{e*,P}(z) / sum_P s²_{grid,P}(z)` (a ratio estimate: the denominator's
//! expectation is the number of pixels, and the numerator's noise largely cancels against it;
//! relative error about `sqrt(2 / (K N))` over `N` pixels). One channel: render noise is
//! strongly correlated across colour channels, and the choice `e*` by the channel sum is then
//! that of one channel. Reported as `pure_noise_ratio` (`tests/estimators_noise.rs` checks it
//! against the measured bias); `mean_variance` stays the uncalibrated least of three:
//! dividing it by `c` raised the risk estimate on texture as much as on noise and lost up to
//! 2 dB on the suite's texture scenes (docs/measurements/estimators.md).
//!
//! **Counts.** That bias depends on the count: at `n_P = 2` the three orderings give the same
//! pair (`c_2 = 1` exactly), from 3 samples up the least of three falls to about 0.5-0.7 of
//! `s²` (the plan's pixels, prefixes of each pixel's own (0, 2)-sequence). Where the counts
//! are uneven (the adaptive plan, and most of all its pixel share, which raises a third to a
//! half of the pixels to 3-8 samples beside pixels at 2) the pixels of a window or of a Haar
//! coefficient then carry different biases, and SURE's comparisons (SureShrink's threshold
//! per level, the gate's window sums) mix them: on the suite's `cornell` at 4 spp with the
//! share, SureShrink killed 34 % of the coefficients where it killed 81 % at main's counts,
//! and `auto` fell 3.9 dB while the box gained 1.6 (docs/measurements/plan-quality.md, "The
//! final image on the pixel share's uneven counts"). So every count is brought to the bias of
//! the most common count `ref` ([`PixelNoise::equalise_counts`], when `auto` is asked to by
//! [`super::ShrinkParams::equalise_counts`]; off by default):
//! `v_P <- v_P c_ref / c_{n_P}`, `c_n` the pure-noise ratio of the pixels holding `n` samples
//! (simulated as above, per count, at least [`MIN_CLASS_DRAWS`] pixel draws a count). The
//! level stays the most common count's (the uncalibrated bias the gate's and the check's
//! parameters were chosen with), and with one count (the uniform path) nothing moves.
//!
//! **Global level.** `sigma_c = sqrt(median_P sigma²_{grid,P,c} / q_K)` (the 2D strata's
//! differences alone, `sigma²_{grid,P} = s²_grid / n_P`) over the pixels with two samples or
//! more, `q_K` the median of `chi²_K / K` (`K` the most common count of 2 x 2
//! blocks; reported, not used by `auto`): for Gaussian noise `sigma²_{grid,P} ~ sigma² chi²_K / K`,
//! and the median ignores the pixels whose differences see an edge or texture.
//! `q_1 = 0.4549`, `q_2 = ln 2`, `q_3 = 0.7887`, `q_4 = 0.8392` (the chi-square medians),
//! Wilson–Hilferty `(1 - 2 / (9K))³` beyond.

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
    /// The 2D strata's second differences alone as the variance of the mean,
    /// `s²_{grid,P,c} / n_P` (NaN where `n_P < 2`): the estimate before the three were
    /// compared, kept for the tests and the report.
    pub grid_variance: Vec<Vec<f64>>,
    /// The difference estimate each pixel took (`None` where `n_P < 2`).
    pub estimator: Vec<Option<StrataDifference>>,
    /// `c = E s²_{e*} / s²` on pure noise at these positions ([`pure_noise_ratio`]): the
    /// factor by which `mean_variance` is expected to fall short of the noise where the
    /// pixels hold noise only (reported; not applied, docs/measurements/estimators.md).
    pub pure_noise_ratio: Option<f64>,
}

/// The three difference estimates of a pixel's per-sample variance (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum StrataDifference {
    /// Second differences of 2 x 2 blocks of the 2D strata (pairs in a single row).
    Grid,
    /// Successive differences of the samples sorted by `x` (the Latin hypercube's columns).
    Columns,
    /// Successive differences of the samples sorted by `y` (its rows).
    Rows,
}

impl StrataDifference {
    /// All three, in the order of the report.
    pub const ALL: [StrataDifference; 3] = [
        StrataDifference::Grid,
        StrataDifference::Columns,
        StrataDifference::Rows,
    ];

    /// The name in the report.
    pub fn name(self) -> &'static str {
        match self {
            StrataDifference::Grid => "grid",
            StrataDifference::Columns => "columns",
            StrataDifference::Rows => "rows",
        }
    }
}

/// Pixels whose noise came from one difference estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct DifferenceCount {
    /// The estimate.
    pub estimator: StrataDifference,
    /// Its pixels.
    pub pixels: usize,
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
        let mut estimator = vec![None; pixels];
        let mut grid_variance = vec![vec![f64::NAN; pixels]; channels];
        let mut work = DifferenceWork::new(channels);
        let v = samples.values();
        let (xs, ys) = (samples.xs(), samples.ys());
        for p in 0..pixels {
            let idx = bins.in_pixel(p);
            let n = idx.len();
            count[p] = n;
            if n < 2 {
                continue;
            }
            let k = work.estimate(idx, xs, ys, v);
            blocks[p] = k;
            let (best, s) = work.least();
            estimator[p] = Some(best);
            for (gv, g) in grid_variance.iter_mut().zip(&work.grid) {
                gv[p] = g / n as f64;
            }
            for (mv, s) in mean_variance.iter_mut().zip(s) {
                mv[p] = s / n as f64;
            }
        }
        let with_blocks: Vec<usize> = (0..pixels).filter(|&p| blocks[p] > 0).collect();
        if with_blocks.is_empty() {
            return None;
        }
        let pure_noise_ratio = pure_noise_ratio(samples, bins);
        let typical_blocks = mode(with_blocks.iter().map(|&p| blocks[p]));
        let typical_count = median(
            &mut with_blocks
                .iter()
                .map(|&p| count[p] as f64)
                .collect::<Vec<_>>(),
        );
        let q = chi_square_median_ratio(typical_blocks);
        // from the grid's differences alone, whose chi-square law `q` describes
        let sigma: Vec<f64> = grid_variance
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
            grid_variance,
            estimator,
            pure_noise_ratio,
        })
    }

    /// Pixels whose own noise is estimated (two samples or more).
    pub fn pixels_with_blocks(&self) -> usize {
        self.estimator.iter().filter(|e| e.is_some()).count()
    }

    /// Pixels per difference estimate.
    pub fn estimator_counts(&self) -> Vec<DifferenceCount> {
        StrataDifference::ALL
            .into_iter()
            .map(|e| DifferenceCount {
                estimator: e,
                pixels: self.estimator.iter().filter(|&&x| x == Some(e)).count(),
            })
            .collect()
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

/// Scratch space for one pixel's three difference estimates (per channel).
struct DifferenceWork {
    order: Vec<usize>,
    grid: Vec<f64>,
    columns: Vec<f64>,
    rows: Vec<f64>,
}

impl DifferenceWork {
    fn new(channels: usize) -> Self {
        Self {
            order: Vec::new(),
            grid: vec![0.0; channels],
            columns: vec![0.0; channels],
            rows: vec![0.0; channels],
        }
    }

    /// The three estimates `s²_grid`, `s²_x`, `s²_y` of the pixel whose samples are `idx`
    /// (at least two) with values `v[c][i]`; returns the number of 2 x 2 blocks `K_P`.
    fn estimate(&mut self, idx: &[usize], xs: &[f64], ys: &[f64], v: &[Vec<f64>]) -> usize {
        let n = idx.len();
        let order = &mut self.order;
        // 2. and 3.: successive differences along x, then along y
        for (sum, coord) in [(&mut self.columns, xs), (&mut self.rows, ys)] {
            order.clear();
            order.extend_from_slice(idx);
            order.sort_by(|&a, &b| coord[a].total_cmp(&coord[b]));
            for (s, vc) in sum.iter_mut().zip(v) {
                *s = order
                    .windows(2)
                    .map(|w| (vc[w[1]] - vc[w[0]]).powi(2))
                    .sum::<f64>()
                    / (2.0 * (n - 1) as f64);
            }
        }
        // 1.: second differences of 2 x 2 blocks of the grid (pairs in a single row)
        let (gx, gy) = strata_grid(n);
        order.clear();
        order.extend_from_slice(idx);
        order.sort_by(|&a, &b| ys[a].total_cmp(&ys[b]));
        for row in order.chunks_mut(gx) {
            row.sort_by(|&a, &b| xs[a].total_cmp(&xs[b]));
        }
        let grid = &mut self.grid;
        grid.iter_mut().for_each(|s| *s = 0.0);
        let mut k = 0usize;
        if gy == 1 {
            for pair in order.chunks_exact(2) {
                for (s, vc) in grid.iter_mut().zip(v) {
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
                    for (s, vc) in grid.iter_mut().zip(v) {
                        let dd = (vc[a] - vc[b]) - (vc[c] - vc[d]);
                        *s += dd * dd / 4.0;
                    }
                    k += 1;
                }
            }
        }
        grid.iter_mut().for_each(|s| *s /= k as f64);
        k
    }

    /// The estimate of least sum over channels (ties to the grid) and its values.
    fn least(&self) -> (StrataDifference, &[f64]) {
        let total = |s: &[f64]| s.iter().sum::<f64>();
        let mut best = (StrataDifference::Grid, self.grid.as_slice());
        for (e, s) in [
            (StrataDifference::Columns, self.columns.as_slice()),
            (StrataDifference::Rows, self.rows.as_slice()),
        ] {
            if total(s) < total(best.1) {
                best = (e, s);
            }
        }
        best
    }
}

/// The expectation of the least of three on pure noise relative to the noise,
/// `c = E s²_{e*} / s²`, for the positions of `samples` (module docs, "Bias on pure noise"):
/// every sample given an i.i.d. standard normal value (one channel; a fixed seed, so the same
/// samples give the same `c`), then `c = sum_P s²_{e*,P}(z) / sum_P s²_{grid,P}(z)` over the
/// pixels with two samples or more. `None` when there is none.
pub fn pure_noise_ratio(samples: &ImageSamples, bins: &PixelBins) -> Option<f64> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(PURE_NOISE_SEED);
    let mut normal = || {
        // Box–Muller
        let u: f64 = rng.random::<f64>().max(1e-300);
        let t: f64 = rng.random();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * t).cos()
    };
    let z = vec![(0..samples.len()).map(|_| normal()).collect::<Vec<f64>>()];
    let mut work = DifferenceWork::new(1);
    let (mut least, mut grid) = (0.0, 0.0);
    for p in 0..samples.plane().pixels() {
        let idx = bins.in_pixel(p);
        if idx.len() < 2 {
            continue;
        }
        work.estimate(idx, samples.xs(), samples.ys(), &z);
        least += work.least().1[0];
        grid += work.grid[0];
    }
    (grid > 0.0).then(|| least / grid)
}

/// The seed of [`pure_noise_ratio`]'s simulated noise.
const PURE_NOISE_SEED: u64 = 0x5eed_ca1b;

/// The least of three's pure-noise ratio at one sample count, and the factor its pixels'
/// noise took ([`PixelNoise::equalise_counts`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct CountClass {
    /// The sample count `n`.
    pub count: usize,
    /// Pixels with `n` samples.
    pub pixels: usize,
    /// `c_n = sum s²_{e*}(z) / sum s²_grid(z)` over the simulated draws at this count.
    pub ratio: f64,
    /// `c_ref / c_n`, the factor of these pixels' `v_P` (1 at the reference count).
    pub factor: f64,
}

/// What [`PixelNoise::equalise_counts`] did: the reference count and every count class.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CountCalibration {
    /// The most common count of the pixels with two samples or more, whose bias every other
    /// count is brought to.
    pub reference_count: usize,
    /// Per count present (two samples or more), ascending.
    pub classes: Vec<CountClass>,
}

impl CountCalibration {
    /// Pixels whose noise moved (a factor other than 1).
    pub fn moved_pixels(&self) -> usize {
        self.classes
            .iter()
            .filter(|c| c.factor != 1.0)
            .map(|c| c.pixels)
            .sum()
    }

    /// In words.
    pub fn describe(&self) -> String {
        if self.classes.len() <= 1 {
            return format!(
                "every pixel with two samples or more holds {} (no count equalisation)",
                self.reference_count
            );
        }
        let classes = self
            .classes
            .iter()
            .map(|c| format!("{} x{} ({} px)", c.count, fmt_factor(c.factor), c.pixels))
            .collect::<Vec<_>>()
            .join(", ");
        format!(
            "the noise of pixels of other counts brought to the least of three's pure-noise bias \
             at the most common count {} (factor per count: {classes}; {} pixels moved)",
            self.reference_count,
            self.moved_pixels()
        )
    }
}

fn fmt_factor(f: f64) -> String {
    format!("{f:.2}")
}

/// Simulated pixels per count class at least (the draws repeat the positions of a rare
/// count's pixels with fresh noise, up to [`MAX_DRAWS`] times).
pub const MIN_CLASS_DRAWS: usize = 512;

/// The most draws of one pixel's positions in [`PixelNoise::equalise_counts`].
pub const MAX_DRAWS: usize = 64;

impl PixelNoise {
    /// Brings the noise of every count to the bias of the most common count (module docs,
    /// "Counts"): `v_P <- v_P c_ref / c_{n_P}`, `c_n` the least of three's expectation on pure
    /// noise at the positions of the pixels holding `n` samples (simulated, fixed seed),
    /// `ref` the most common count. With one count (the uniform path) nothing moves.
    pub fn equalise_counts(
        &mut self,
        samples: &ImageSamples,
        bins: &PixelBins,
    ) -> CountCalibration {
        let ratios = count_ratios(samples, bins);
        let with_blocks: Vec<usize> = (0..self.count.len())
            .filter(|&p| self.estimator[p].is_some())
            .collect();
        let reference_count = mode(with_blocks.iter().map(|&p| self.count[p]));
        let reference = ratios
            .iter()
            .find(|r| r.0 == reference_count)
            .map_or(f64::NAN, |r| r.2);
        let classes: Vec<CountClass> = ratios
            .iter()
            .map(|&(count, pixels, ratio)| CountClass {
                count,
                pixels,
                ratio,
                factor: if count == reference_count {
                    1.0
                } else if ratio > 0.0 && reference > 0.0 {
                    reference / ratio
                } else {
                    1.0
                },
            })
            .collect();
        for &p in &with_blocks {
            let n = self.count[p];
            if let Some(class) = classes.iter().find(|c| c.count == n) {
                if class.factor != 1.0 {
                    for mv in self.mean_variance.iter_mut() {
                        mv[p] *= class.factor;
                    }
                }
            }
        }
        CountCalibration {
            reference_count,
            classes,
        }
    }
}

/// `(n, pixels, c_n)` per count `n >= 2` present: `c_n = sum s²_{e*}(z) / sum s²_grid(z)` over
/// the pixels holding `n` samples, each given i.i.d. standard normal values (one channel, a
/// fixed seed) in `ceil(MIN_CLASS_DRAWS / pixels)` draws (at most [`MAX_DRAWS`]). The grid's
/// estimate is unbiased on pure noise, so `c_n` estimates `E s²_{e*} / s²` at that count.
fn count_ratios(samples: &ImageSamples, bins: &PixelBins) -> Vec<(usize, usize, f64)> {
    use rand::{Rng, SeedableRng};
    use std::collections::BTreeMap;
    let pixels = samples.plane().pixels();
    let mut per_count: BTreeMap<usize, usize> = BTreeMap::new();
    for p in 0..pixels {
        let n = bins.in_pixel(p).len();
        if n >= 2 {
            *per_count.entry(n).or_insert(0) += 1;
        }
    }
    let draws_of = |n: usize| MIN_CLASS_DRAWS.div_ceil(per_count[&n]).clamp(1, MAX_DRAWS);
    let most = per_count.keys().map(|&n| draws_of(n)).max().unwrap_or(0);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(PURE_NOISE_SEED ^ 0xc0_0175);
    let mut work = DifferenceWork::new(1);
    let mut sums: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
    let mut z = vec![vec![0.0; samples.len()]];
    for draw in 0..most {
        for p in 0..pixels {
            let idx = bins.in_pixel(p);
            let n = idx.len();
            if n < 2 || draw >= draws_of(n) {
                continue;
            }
            for &i in idx {
                // Box–Muller
                let u: f64 = rng.random::<f64>().max(1e-300);
                let t: f64 = rng.random();
                z[0][i] = (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * t).cos();
            }
            work.estimate(idx, samples.xs(), samples.ys(), &z);
            let e = sums.entry(n).or_insert((0.0, 0.0));
            e.0 += work.least().1[0];
            e.1 += work.grid[0];
        }
    }
    per_count
        .iter()
        .map(|(&n, &count)| {
            let (least, grid) = sums.get(&n).copied().unwrap_or((0.0, 0.0));
            (n, count, if grid > 0.0 { least / grid } else { f64::NAN })
        })
        .collect()
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
