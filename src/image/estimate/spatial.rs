//! The box pixels' noise seen across pixels: a check of the strata's noise estimate against
//! the errors the box pixels actually show, which lowers it where it says more noise than the
//! pixels carry (texture inside the pixels, a sampler that stratifies more than the model
//! knows).
//!
//! **Why.** `v_P` ([`super::noise`]) models the variance of the box pixel `m_P` from the
//! differences of its own strata. Deterministic variation inside a stratum (texture past
//! Nyquist) enters those differences as if it were noise, and a sampler that stratifies more
//! than the jittered grid (Mitsuba's correlated multi-jitter, whose Latin hypercube integrates
//! sub-pixel texture nearly as a lattice does, and which stratifies the light and BSDF
//! dimensions too) makes the box's real error smaller than any within-pixel model says: on the
//! suite's grazing plane `sum v_P / sum (m_P - mu_P)²` is 4-5. An overstated `v_P` makes SURE
//! favour smoothing (`(x - m)² - v + 2 v div` falls with `v` wherever `div < 1`), so the gate
//! smooths texture away.
//!
//! **The check.** The box errors `e_P = m_P - mu_P` of different pixels are independent (each
//! pixel's own samples), with variances `V_P`. A contrast `D = sum_Q a_Q m_Q` over a few
//! neighbouring pixels whose weights cancel every function linear in the pixel position has
//! `E D² = sum_Q a_Q² V_Q + (sum_Q a_Q mu_Q)²`: the actual noise plus a non-negative signal
//! term. Three contrasts, each blind to another class of signal:
//!
//! 1. the 2 x 2 block `m_{x,y} - m_{x+1,y} - m_{x,y+1} + m_{x+1,y+1}` (`sum a² = 4`; cancels
//!    planes and every edge along a row or a column of pixels);
//! 2. the second difference along `x`, `m_{x-1,y} - 2 m_{x,y} + m_{x+1,y}` (`1, 4, 1`; cancels
//!    variation along `y`);
//! 3. the same along `y`.
//!
//! Over the gate's window `W` around each pixel, per contrast `e`,
//! `k_e = sum_{D in W} sum_c D_c² / sum_{D in W} sum_c sum_Q a_Q² v_{Q,c}`: the noise the box
//! pixels show over the noise the strata model says (channels pooled: render noise is strongly
//! correlated across them), plus signal. `k = min_e k_e` ([`noise_ratios`]), and the model is
//! capped at [`SPATIAL_MARGIN`] times what the pixels show: `v'_P = f_W v_P`,
//! `f_W = min(1, SPATIAL_MARGIN k)` ([`spatial_factors`]). So the check only ever *lowers* the
//! box's estimated risk; a lower `v` raises every smoothing candidate's SURE against the box's
//! (the difference `(x - m)² - 2 v (1 - div)` grows as `v` falls), so the gate can only move
//! toward the box. Where the pixels carry signal the contrasts do not cancel (texture near
//! Nyquist, corners), `k` is large and `v_P` stays.
//!
//! **The margin.** On pure noise with a correct model `E k_e = 1`; the minimum of three ratios
//! over some 80 overlapping contrasts a window and channel is a little below 1, and the suite's noisy
//! scenes show `k` of 0.6-0.9 (their renders stratify the light and BSDF dimensions, so the box
//! errs less than the strata say): scaling by `k` itself (margin 1) lowered the noise there and
//! lost up to 1.5 dB (fog). With the margin 2 only a model that says more than twice the noise
//! the pixels show is lowered (the suite's grazing plane: median `k` 0.14-0.2 at 8 and 16 spp).
//! Chosen on the suite's tuning half against 1, 1/0.6, 1/0.7 and 1/0.3
//! (`docs/measurements/estimators.md`).
//!
//! What it cannot see: texture well below a pixel whose box integrals vary across pixels as
//! much as noise would, and noise correlated across pixels (a renderer's pixel-shared
//! sampling), which lowers the contrasts' variance below `sum a² V`.

use serde::Serialize;

use super::sure::window_sum;

/// What the cross-pixel check did.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SpatialCheck {
    /// Half the side of the window the ratios are summed over.
    pub half: usize,
    /// [`SPATIAL_MARGIN`].
    pub margin: f64,
    /// Pixels whose `v_P` the check lowered (`f_W < 1`).
    pub lowered_pixels: usize,
    /// The median factor `f_W` over the pixels.
    pub median_factor: f64,
    /// `sum_P v'_P / sum_P v_P` over the image and channels (1: unchanged).
    pub total_factor: f64,
}

impl SpatialCheck {
    /// The check in words.
    pub fn describe(&self) -> String {
        format!(
            "the strata's noise checked against the box pixels' own differences across pixels \
             over {side} x {side} windows (least of 2x2 blocks, second differences along x and \
             along y), capped at {} times what they show (never raised): lowered on {} pixels, median \
             factor {:.2}, total {:.2}",
            self.margin,
            self.lowered_pixels,
            self.median_factor,
            self.total_factor,
            side = 2 * self.half + 1,
        )
    }
}

/// The margin: `v_P` is capped at this many times the noise the box pixels show across
/// pixels (module docs).
pub const SPATIAL_MARGIN: f64 = 2.0;

/// The factors `f_W = min(1, SPATIAL_MARGIN k_W)` per pixel (module docs) for box pixels `mean`
/// with modelled variances `variance` (per channel, row-major `width x height`), over windows of
/// half side `half`.
pub fn spatial_factors(
    mean: &[Vec<f64>],
    variance: &[Vec<f64>],
    width: usize,
    height: usize,
    half: usize,
) -> Vec<f64> {
    noise_ratios(mean, variance, width, height, half)
        .into_iter()
        .map(|k| (SPATIAL_MARGIN * k).min(1.0))
        .collect()
}

/// `k_W = min_e k_e` per pixel (module docs): the noise the box pixels `mean` show across
/// pixels over the noise `variance` models, summed over the window of half side `half` around
/// each pixel and over channels; infinite where the model is 0 for every contrast of the
/// window.
pub fn noise_ratios(
    mean: &[Vec<f64>],
    variance: &[Vec<f64>],
    width: usize,
    height: usize,
    half: usize,
) -> Vec<f64> {
    let pixels = width * height;
    let at = |x: usize, y: usize| y * width + x;
    // per contrast: squared contrasts and their modelled expectations, at the contrast's pixel
    let mut observed = [vec![0.0; pixels], vec![0.0; pixels], vec![0.0; pixels]];
    let mut modelled = [vec![0.0; pixels], vec![0.0; pixels], vec![0.0; pixels]];
    for (m, v) in mean.iter().zip(variance) {
        for y in 0..height {
            for x in 0..width {
                let p = at(x, y);
                if x + 1 < width && y + 1 < height {
                    let q = [p, at(x + 1, y), at(x, y + 1), at(x + 1, y + 1)];
                    let d = m[q[0]] - m[q[1]] - m[q[2]] + m[q[3]];
                    observed[0][p] += d * d;
                    modelled[0][p] += q.iter().map(|&i| v[i]).sum::<f64>();
                }
                if x >= 1 && x + 1 < width {
                    let (l, r) = (at(x - 1, y), at(x + 1, y));
                    let d = m[l] - 2.0 * m[p] + m[r];
                    observed[1][p] += d * d;
                    modelled[1][p] += v[l] + 4.0 * v[p] + v[r];
                }
                if y >= 1 && y + 1 < height {
                    let (u, b) = (at(x, y - 1), at(x, y + 1));
                    let d = m[u] - 2.0 * m[p] + m[b];
                    observed[2][p] += d * d;
                    modelled[2][p] += v[u] + 4.0 * v[p] + v[b];
                }
            }
        }
    }
    let ratios: Vec<(Vec<f64>, Vec<f64>)> = observed
        .iter()
        .zip(&modelled)
        .map(|(o, e)| {
            (
                window_sum(o, width, height, half),
                window_sum(e, width, height, half),
            )
        })
        .collect();
    (0..pixels)
        .map(|p| {
            ratios
                .iter()
                .filter(|(_, e)| e[p] > 0.0)
                .map(|(o, e)| o[p] / e[p])
                .fold(f64::INFINITY, f64::min)
        })
        .collect()
}

/// Scales `variance` (per channel and pixel) by `factors` and reports what changed.
pub fn apply_factors(variance: &mut [Vec<f64>], factors: &[f64], half: usize) -> SpatialCheck {
    let before: f64 = variance.iter().flatten().filter(|x| x.is_finite()).sum();
    for v in variance.iter_mut() {
        for (x, f) in v.iter_mut().zip(factors) {
            *x *= f;
        }
    }
    let after: f64 = variance.iter().flatten().filter(|x| x.is_finite()).sum();
    let mut sorted = factors.to_vec();
    SpatialCheck {
        half,
        margin: SPATIAL_MARGIN,
        lowered_pixels: factors.iter().filter(|&&f| f < 1.0).count(),
        median_factor: if sorted.is_empty() {
            1.0
        } else {
            super::statistics::median(&mut sorted)
        },
        total_factor: if before > 0.0 { after / before } else { 1.0 },
    }
}
