//! Noise in the indicator: which detail coefficients stand out of the
//! noise of Monte Carlo samples.
//!
//! Sample values are `f_i = L(x_i, y_i) + n_i` with noise `n_i` of deviation `sigma` (unknown
//! to the refiner: a renderer's estimates carry whatever noise its paths give). The tree fit
//! `c = G^{-1} K^T f` (`G = K^T K`) then carries `Cov(c) = sigma^2 G^{-1}`: at two samples per
//! function least squares is close to interpolation and `[G^{-1}]_{aa}` is far above the
//! `A / n` of an orthonormal, well-sampled function (an earlier model, `sigma sqrt(2 A / n)`,
//! was too small: a smooth noisy scene went to half-pixel depth).
//!
//! *Probes.* Both unknowns come from the same factorization, by fitting `k` probe channels
//! `e ~ N(0, I)` beside the image's channels (extra right-hand sides; `Cov(K^T e) = G`):
//!
//! * `c_e = G^{-1} K^T e` has `Cov(c_e) = G^{-1}`, so `v_C = mean_{a in C, e} c_{e,a}^2` (the
//!   three functions of a cell and the `k` probes, `3k` degrees of freedom) estimates the
//!   variance per unit noise of the cell's coefficients (a Hutchinson-type estimate of the
//!   diagonal of `G^{-1}`, pooled per cell);
//! * the residuals `r = f - K c` have `Var r_i = sigma^2 (1 - h_ii)` (`h` the leverage) and the
//!   probes' residuals `r_e` have `Var = 1 - h_ii`, so
//!   `sigma^2 = median(r^2) / median(r_e^2)` (pooled over channels and probes). The medians
//!   keep the estimate from the residuals of unresolved edges as long as they are fewer than
//!   half the samples; without noise the estimate is the approximation error's level.
//!
//! *How many probes.* `sigma` is a median over every sample's probe residual (`m k` values):
//! its relative spread is about `1.2 / sqrt(m k)`, below 1 % at one probe and `m >= 10^4`.
//! `v_C` is a mean of `27 k` squares at most (fewer at the image's border and where the
//! neighbours are inactive), each `G^{-1}_aa chi^2_1`: unbiased for any `k`, with a relative
//! spread of about `sqrt(2 / (27 k))` (27 % at `k = 1`, 14 % at `k = 4`, ignoring the
//! correlation of neighbouring coefficients). The cost is `k` more right-hand sides: free
//! for the direct solve (one factorization), but under PCG a probe of white noise takes 8-15
//! iterations where the warm-started image channels take 2-3, so the renderer's plan fits
//! one probe and the in-process default four (`RENDERER_PROBES`;
//! docs/measurements/plan-speed.md, "The noise test's probes").
//!
//! The probes are deterministic: seeded by the seed and each position's bits, so a renderer
//! returning the samples in any order gets the same test (the file protocol and the
//! in-process loop agree). They do not depend on the round: a sample keeps its probe values,
//! so a round's probe fit continues the previous round's like the image channels' fit does
//! (started from zero every round, the probes were the rounds' whole solve cost:
//! docs/measurements/plan-speed.md, "512² at 8 spp"). Within a round the
//! values are independent standard normal deviates all the same, which is all the test
//! needs; across rounds an unchanged cell sees nearly the same test instead of a fresh draw,
//! so a false alarm is not re-drawn every round.
//!
//! *Test.* Under noise alone, `|c_a|^2 / (sigma^2 v_C)` (`|c|` the norm over `ch` channels) is
//! about `chi^2_ch`. A slot is deepened only if a function of its parent is *significant*:
//! `|c_a|^2 > sigma^2 v_P q`, `q` the `chi^2_ch` quantile exceeded with probability
//! `alpha / n` (`n = 3 x` the slots tested, Bonferroni): noise alone marks a slot in a round
//! with probability at most about `alpha` (the false-alarm rate), whatever the image size and
//! the channels. `q` by Wilson–Hilferty, `q = ch (1 - 2/(9 ch) + z sqrt(2/(9 ch)))^3`, `z`
//! the normal quantile (Abramowitz–Stegun 26.2.23, error below `4.5e-4`); for `ch = 1` in
//! the far tail it is above the exact quantile: conservative.
//!
//! Tried: `|c_a| > kappa sigma sqrt(ch v_P)` with a fixed `kappa = 3`, and `v` from the cell
//! alone. With one channel that is `P(chi^2_1 > 9) = 2.7e-3` per function, a few false
//! alarms per round, enough to deepen a noisy smooth scene (docs/measurements/image-plane.md, "The
//! noise test").

use rayon::prelude::*;
use serde::Serialize;

use super::pcg::{multilevel_values, SingleScaleRows};
use super::position_normal;
use crate::adaptive::{Cell, QuadTree};

/// The noise seen by one fit.
#[derive(Clone, Debug, Default, Serialize)]
pub struct NoiseLevel {
    /// Estimated noise deviation of a sample value, `sqrt(median(r^2) / median(r_e^2))`.
    pub sigma: f64,
    /// Probe channels fitted.
    pub probes: usize,
}

/// Per-cell coefficient variance (per unit noise variance) and the noise level of one fit.
#[derive(Clone, Debug)]
pub struct Significance {
    /// The estimated noise.
    pub level: NoiseLevel,
    /// The false-alarm rate `alpha` per round.
    pub false_alarm: f64,
    /// The `chi^2_ch` quantile `q` of the test.
    pub quantile: f64,
    /// Image channels.
    pub channels: usize,
    /// Per probe, the coefficients in the full Mallat layout.
    probe_coefficients: Vec<Vec<f64>>,
}

/// `k` probe channels at the positions: standard normal deviates seeded by `seed` and each
/// position (the same in every round).
pub fn probe_values(seed: u64, xs: &[f64], ys: &[f64], k: usize) -> Vec<Vec<f64>> {
    let seed = seed ^ 0x5DEE_CE66_D1CE_4E5B;
    (0..k)
        .map(|e| {
            xs.par_iter()
                .zip(ys.par_iter())
                .map(|(&x, &y)| position_normal(seed, x, y, e))
                .collect()
        })
        .collect()
}

/// Residuals `f - K c` of every channel at the samples (full-layout coefficients, zero off
/// the tree). `K c = E S c` ([`super::pcg`]): the 2D synthesis `S` of each channel to the
/// single-scale coefficients of `V_Jx (x) V_Jy`, then the single-scale rows `E`, `(2p - 1)^2`
/// terms a sample instead of the multilevel evaluator's terms of every level (the same values
/// up to rounding, and most of the noise test's cost at 512² went to the multilevel
/// evaluator before this: docs/measurements/plan-speed.md, "512² at 8 spp").
pub(crate) fn residuals(
    tree: &QuadTree,
    coefficients: &[&[f64]],
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> Vec<Vec<f64>> {
    let rows = SingleScaleRows::new(tree.basis(), xs, ys);
    residuals_with(tree, &rows, coefficients, values)
}

/// [`residuals`] with the samples' single-scale rows given.
fn residuals_with(
    tree: &QuadTree,
    rows: &SingleScaleRows,
    coefficients: &[&[f64]],
    values: &[&[f64]],
) -> Vec<Vec<f64>> {
    let basis = tree.basis();
    let fit = multilevel_values(basis, rows, coefficients);
    let k = coefficients.len();
    (0..k)
        .into_par_iter()
        .map(|c| {
            values[c]
                .iter()
                .enumerate()
                .map(|(i, f)| f - fit[i * k + c])
                .collect()
        })
        .collect()
}

/// The median of the squares.
fn median_sq(values: impl Iterator<Item = f64>) -> f64 {
    let mut sq: Vec<f64> = values.map(|v| v * v).collect();
    if sq.is_empty() {
        return 0.0;
    }
    let mid = sq.len() / 2;
    *sq.select_nth_unstable_by(mid, f64::total_cmp).1
}

impl Significance {
    /// The test from a fit of `channels` image channels followed by probe channels
    /// (`coefficients` and `values` hold both, image first; probes from [`probe_values`]) at
    /// the samples whose single-scale rows are `rows`, at the false-alarm rate `false_alarm`
    /// over `slots` tested slots.
    pub fn new(
        tree: &QuadTree,
        coefficients: &[Vec<f64>],
        rows: &SingleScaleRows,
        values: &[&[f64]],
        channels: usize,
        false_alarm: f64,
        slots: usize,
    ) -> Self {
        let coef: Vec<&[f64]> = coefficients.iter().map(|c| c.as_slice()).collect();
        let r = residuals_with(tree, rows, &coef, values);
        let signal = median_sq(r[..channels].iter().flatten().copied());
        let probe = median_sq(r[channels..].iter().flatten().copied());
        let sigma = if probe > 0.0 {
            (signal / probe).sqrt()
        } else {
            0.0
        };
        Self {
            level: NoiseLevel {
                sigma,
                probes: coefficients.len() - channels,
            },
            false_alarm,
            quantile: chi_square_quantile(channels, false_alarm / (3 * slots.max(1)) as f64),
            channels,
            probe_coefficients: coefficients[channels..].to_vec(),
        }
    }

    /// `v_C`: the mean square of the probes' coefficients over the three functions of the
    /// active cells within one cell of `cell` (`|dk| <= 1` per axis, the cell itself
    /// included), the variance per unit noise variance of a coefficient of the cell. Pooling
    /// the neighbours gives up to `27 k` degrees of freedom (the variance changes slowly
    /// with the local sample density): the cell alone (`3k` degrees of freedom) underestimates
    /// the variance often enough to let noise deepen scattered cells of a flat background.
    pub fn variance(&self, tree: &QuadTree, cell: Cell) -> f64 {
        if self.probe_coefficients.is_empty() {
            return 0.0;
        }
        let own = self.mean_square(tree, std::iter::once(cell));
        let (mut sum, mut terms) = (0.0, 0usize);
        for q in tree.neighbourhood(cell) {
            if q != cell && !tree.is_active(q) {
                continue;
            }
            for c in &self.probe_coefficients {
                for a in tree.cell_functions(q) {
                    sum += c[a] * c[a];
                    terms += 1;
                }
            }
        }
        // the cell's own estimate guards cells whose variance differs from their
        // neighbours' (boundary functions)
        own.max(sum / terms as f64)
    }

    /// The mean square of the probes' coefficients over the functions of `cells`.
    fn mean_square(&self, tree: &QuadTree, cells: impl Iterator<Item = Cell>) -> f64 {
        let (mut sum, mut terms) = (0.0, 0usize);
        for q in cells {
            for c in &self.probe_coefficients {
                for a in tree.cell_functions(q) {
                    sum += c[a] * c[a];
                    terms += 1;
                }
            }
        }
        sum / terms.max(1) as f64
    }

    /// Per probe, the coefficients in the full Mallat layout (the next round's PCG start).
    pub fn probe_coefficients(&self) -> &[Vec<f64>] {
        &self.probe_coefficients
    }

    /// The least significant magnitude of a coefficient of `cell`: `sigma sqrt(v_C q)`.
    pub fn threshold(&self, tree: &QuadTree, cell: Cell) -> f64 {
        self.level.sigma * (self.variance(tree, cell) * self.quantile).sqrt()
    }
}

/// The upper normal quantile `z` with `P(N > z) = p`, `0 < p <= 1/2` (Abramowitz–Stegun
/// 26.2.23, absolute error below `4.5e-4`).
pub fn normal_upper_quantile(p: f64) -> f64 {
    let p = p.clamp(1e-300, 0.5);
    let t = (-2.0 * p.ln()).sqrt();
    t - (2.515517 + 0.802853 * t + 0.010328 * t * t)
        / (1.0 + 1.432788 * t + 0.189269 * t * t + 0.001308 * t * t * t)
}

/// The upper `chi^2_k` quantile exceeded with probability `p` (Wilson–Hilferty).
pub fn chi_square_quantile(k: usize, p: f64) -> f64 {
    let k = k.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    let z = normal_upper_quantile(p);
    k * (1.0 - a + z * a.sqrt()).max(0.0).powi(3)
}
