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
//! correlation of neighbouring coefficients), a spread the test's quantile accounts for
//! (*Test* below: `F(ch, d)` instead of `chi^2_ch`). The cost is `k` more right-hand sides: free
//! for the direct solve (one factorization), but under PCG a probe of white noise takes 8-15
//! iterations where the warm-started image channels take 2-3, so the renderer's plan fits
//! one probe and the in-process default four (`RENDERER_PROBES`;
//! docs/measurements/plan-speed.md, "The noise test's probes"), stopping at its own relative
//! residual (`FitParams::probe_tolerance`, `5e-2` in the renderer plan against the image's
//! `1e-2`): a probe fitted loosely misses some of `G^{-1}`'s slow directions, so `v_C` and
//! the probe residuals' median are estimated a little low and high; the suite's mean quality
//! was not lower (docs/measurements/plan-speed.md, "The rounds' fits: PCG's iterations").
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
//! *Test.* Under noise alone a function's coefficients over the `ch` channels are
//! `c_a ~ N(0, sigma^2 g_a I_ch)` (`g_a = [G^{-1}]_aa`), so `|c_a|^2 / (sigma^2 g_a) ~ chi^2_ch`.
//! The variance is not known but estimated by the probes: `v_C` is a mean of `d = 3 k n_C`
//! squares (`n_C` the cells pooled, [`Significance::variance`]), each `g chi^2_1` and
//! independent of `c_a` (the probes are drawn apart from the samples' noise), so with the
//! pooled functions' `g` equal to `g_a` and uncorrelated, `d v_C / g_a ~ chi^2_d` and
//!
//! ```text
//! T_a = |c_a|^2 / (ch sigma^2 v_C) = (chi^2_ch / ch) / (chi^2_d / d) ~ F(ch, d)
//! ```
//!
//! (`sigma` from a median over `m k` values, relative spread below 1 %, taken as known). A
//! slot is deepened only if a function of its parent is *significant*:
//! `|c_a|^2 > sigma^2 v_P q_d`, `q_d = ch F^{-1}_{ch, d}(1 - alpha / n)` the `ch`-scaled upper
//! quantile of `F(ch, d)` exceeded with probability `alpha / n` (`n = 3 x` the slots tested,
//! Bonferroni): noise alone marks a slot in a round with probability at most about `alpha`
//! (the false-alarm rate), whatever the image size, the channels *and the probes*. As
//! `d -> infinity`, `ch F(ch, d) -> chi^2_ch` ([`chi_square_quantile`], the quantile used
//! before, which ignored the spread of `v_C`: with one probe, `d = 27` inside the image and
//! `ch = 3`, its rate at the Bonferroni level was several times `alpha`). Where `v_C` is the
//! cell's own estimate (the `max` in [`Significance::variance`]), it is at least the pooled
//! one, so the pooled `d` keeps the rate at most `alpha / n`: conservative. `F`'s tail is
//! `P(F > x) = I_y(d / 2, ch / 2)`, `y = d / (d + ch x)` (the regularized incomplete beta,
//! [`f_upper_tail`]), inverted by bisection on `ln y` ([`f_upper_quantile`]). Correlated
//! neighbours or unequal `g` within the pool lower the effective `d` (a higher rate);
//! `tests/significance_probes.rs` measures the rate of the plan's own fit on noise alone.
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
    /// The `chi^2_ch` quantile at the test's level: the limit of the quantiles `q_d` for
    /// many probe terms `d` (reported; the test uses `q_d`).
    pub quantile: f64,
    /// `q_d = ch F^{-1}_{ch, d}(1 - alpha / n)` for `d = 3 k n_C` probe terms, indexed by the
    /// cells pooled `n_C - 1` (`1..=9`); empty without probes.
    quantiles: Vec<f64>,
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
        let probes = coefficients.len() - channels;
        let level = false_alarm / (3 * slots.max(1)) as f64;
        Self {
            level: NoiseLevel { sigma, probes },
            false_alarm,
            quantile: chi_square_quantile(channels, level),
            quantiles: pooled_quantiles(channels, probes, level),
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
        self.pooled_variance(tree, cell).0
    }

    /// [`Significance::variance`] and the cells pooled `n_C` (`1..=9`; 0 without probes).
    fn pooled_variance(&self, tree: &QuadTree, cell: Cell) -> (f64, usize) {
        if self.probe_coefficients.is_empty() {
            return (0.0, 0);
        }
        let own = self.mean_square(tree, std::iter::once(cell));
        let (mut sum, mut terms, mut cells) = (0.0, 0usize, 0usize);
        for q in tree.neighbourhood(cell) {
            if q != cell && !tree.is_active(q) {
                continue;
            }
            cells += 1;
            for c in &self.probe_coefficients {
                for a in tree.cell_functions(q) {
                    sum += c[a] * c[a];
                    terms += 1;
                }
            }
        }
        // the cell's own estimate guards cells whose variance differs from their
        // neighbours' (boundary functions)
        (own.max(sum / terms as f64), cells)
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

    /// The least significant magnitude of a coefficient of `cell`: `sigma sqrt(v_C q_d)`,
    /// `d = 3 k n_C` the probe terms of `v_C`.
    pub fn threshold(&self, tree: &QuadTree, cell: Cell) -> f64 {
        let (v, cells) = self.pooled_variance(tree, cell);
        match cells.checked_sub(1).and_then(|i| self.quantiles.get(i)) {
            Some(q) => self.level.sigma * (v * q).sqrt(),
            None => 0.0,
        }
    }

    /// The threshold of [`Significance::threshold`] at the level `p` for one function
    /// instead of the round's `alpha / n`: noise alone exceeds it with probability `p`
    /// (under the test's model), so over many functions the fraction of false alarms
    /// estimates the test's true rate.
    pub fn threshold_at(&self, tree: &QuadTree, cell: Cell, p: f64) -> f64 {
        let (v, cells) = self.pooled_variance(tree, cell);
        if cells == 0 {
            return 0.0;
        }
        let d = (3 * self.level.probes * cells) as f64;
        let ch = self.channels as f64;
        self.level.sigma * (v * ch * f_upper_quantile(ch, d, p)).sqrt()
    }
}

/// `q_d = ch F^{-1}_{ch, d}(1 - p)` for `d = 3 k n_C`, `n_C = 1..=9` (empty for `k = 0`).
fn pooled_quantiles(channels: usize, probes: usize, p: f64) -> Vec<f64> {
    if probes == 0 {
        return Vec::new();
    }
    let ch = channels.max(1) as f64;
    (1..=9)
        .map(|cells| ch * f_upper_quantile(ch, (3 * probes * cells) as f64, p))
        .collect()
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

/// `ln Gamma(x)` for `x >= 1/2` (Lanczos, `g = 7`, nine terms: relative error near `1e-15`).
fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    let x = x - 1.0;
    let a = C[1..]
        .iter()
        .enumerate()
        .fold(C[0], |a, (i, c)| a + c / (x + (i + 1) as f64));
    let t = x + G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The continued fraction of the incomplete beta function (modified Lentz; Numerical
/// Recipes 6.4), converging fast for `x < (a + 1) / (a + b + 2)`.
fn beta_continued_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..=500 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 / guard(1.0 + aa * d);
        c = guard(1.0 + aa / c);
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 / guard(1.0 + aa * d);
        c = guard(1.0 + aa / c);
        let step = d * c;
        h *= step;
        if (step - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// The regularized incomplete beta function `I_x(a, b) = B(x; a, b) / B(a, b)`, `a, b >=
/// 1/2`, `0 <= x <= 1`: `x^a (1 - x)^b / (a B(a, b))` times the continued fraction, or
/// `1 - I_{1-x}(b, a)` where that converges faster (relative accuracy in the lower tail).
pub fn incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let ln_front = a * x.ln() + b * (-x).ln_1p() - (ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b));
    if x < (a + 1.0) / (a + b + 2.0) {
        ln_front.exp() * beta_continued_fraction(a, b, x) / a
    } else {
        1.0 - ln_front.exp() * beta_continued_fraction(b, a, 1.0 - x) / b
    }
}

/// `P(F > x)` for `F ~ F(d1, d2)` (Fisher's F with `d1` and `d2` degrees of freedom, `>= 1`):
/// `I_y(d2 / 2, d1 / 2)`, `y = d2 / (d2 + d1 x)`.
pub fn f_upper_tail(d1: f64, d2: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    incomplete_beta(d2 / 2.0, d1 / 2.0, d2 / (d2 + d1 * x))
}

/// The upper quantile `x` of `F(d1, d2)` with `P(F > x) = p` (`0 < p < 1`; `p >= 1` gives 0,
/// `p <= 0` infinity): `I_y(d2 / 2, d1 / 2) = p` solved for `y` by bisection on `ln y`
/// (`I_y` increases with `y`; 160 halvings of `[-745, 0]`, to the last bits of `y`), then
/// `x = d2 (1 - y) / (d1 y)`.
pub fn f_upper_quantile(d1: f64, d2: f64, p: f64) -> f64 {
    if p >= 1.0 {
        return 0.0;
    }
    if p <= 0.0 {
        return f64::INFINITY;
    }
    let (a, b) = (d2 / 2.0, d1 / 2.0);
    let (mut lo, mut hi) = (-745.0_f64, 0.0_f64);
    for _ in 0..160 {
        let mid = 0.5 * (lo + hi);
        if incomplete_beta(a, b, mid.exp()) < p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let y = (0.5 * (lo + hi)).exp();
    d2 * (1.0 - y) / (d1 * y)
}
