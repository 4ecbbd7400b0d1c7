//! The nugget of each pixel's sample variogram: the part of the samples' spread that does not
//! shrink as two samples come closer (Monte Carlo noise), separated from the part that does
//! (deterministic sub-pixel variation: an edge, a glyph's stroke), and the strata's noise
//! checked against it.
//!
//! **Why.** `v_P` ([`super::noise`]) takes differences of adjacent strata as noise. On
//! deterministic texture (the suite's text, noise-free glyphs) those differences are signal:
//! an edge between two strata counts its whole jump, while the box's real error is the
//! jitter of the few strata the edge crosses (less still under a multi-jittered sampler).
//! SURE's noise credit `2 v_P (1 - div)` then favours smoothing where it brightens dark
//! pixels beside bright ones (`docs/measurements/estimators.md`).
//!
//! **The variogram.** For two samples `i, j` of one pixel at distance `d_ij` (pixel units),
//! the semivariance `g_ij = (v_i - v_j)² / 2` has expectation `gamma(d_ij) = s² + T(d_ij)`: the
//! noise `s²` (independent per sample) at every distance, plus the signal's variation over
//! `d`, `T(d) = E (f(x_i) - f(x_j))² / 2`, with `T(0) = 0` for a piecewise-continuous `f`: an
//! edge crosses a pair with a probability proportional to `d` (`T` linear), a gradient gives
//! `T ∝ d²`. The least-squares line `g_ij = a + b d_ij` over the pixel's `n (n - 1) / 2` pairs
//! extrapolates to `d = 0`: its intercept `a_P` (the *nugget*) estimates `s²`, unbiased on pure
//! noise (every `g_ij` has expectation `s²`, so the line is flat at `s²` in expectation), and
//! about 0 on a noise-free edge. Texture finer than the closest pairs stays in it (it is
//! noise at the scale the samples resolve). It needs three samples and two distinct
//! distances; otherwise the pixel has no nugget (NaN).
//!
//! **The check.** `a_P / n_P` is noisy (a few pairs, two parameters, possibly negative), so it
//! enters only pooled over the gate's window `W` and channels, as a ratio to the model:
//! `k_W = sum_{Q in W} sum_c a_{Q,c} / n_Q / sum_{Q in W} sum_c v_{Q,c}` over the window's
//! pixels with a nugget, and the model is capped at `NUGGET_MARGIN` times it,
//! `f_W = clamp(NUGGET_MARGIN k_W, 0, 1)` ([`nugget_factors`]). Like the check across pixels
//! ([`super::spatial`]) it only ever *lowers* `v_P`, which raises every smoothing candidate's
//! SURE against the box's, so the gate can only move toward the box. On pure noise
//! `E k_W = 1 / c >= 1` (`c` the least of three's shortfall, [`super::noise`]): nothing
//! changes there.

use super::sure::window_sum;
use crate::image::splat::PixelBins;
use crate::image::ImageSamples;

/// The margin: `v_P` is capped at this many times the nugget pooled over the window.
pub const NUGGET_MARGIN: f64 = 1.0;

/// `a_{P,c} / n_P`, the nugget of pixel `P`'s sample variogram per channel as the variance of
/// its mean (NaN where the pixel has fewer than three samples or one distance only).
pub fn nugget_variances(samples: &ImageSamples, bins: &PixelBins) -> Vec<Vec<f64>> {
    let pixels = samples.plane().pixels();
    let channels = samples.channels();
    let (xs, ys, v) = (samples.xs(), samples.ys(), samples.values());
    let mut out = vec![vec![f64::NAN; pixels]; channels];
    let mut pairs: Vec<(usize, usize, f64)> = Vec::new();
    for p in 0..pixels {
        let idx = bins.in_pixel(p);
        let n = idx.len();
        if n < 3 {
            continue;
        }
        pairs.clear();
        for (k, &i) in idx.iter().enumerate() {
            for &j in &idx[k + 1..] {
                pairs.push((i, j, (xs[i] - xs[j]).hypot(ys[i] - ys[j])));
            }
        }
        let m = pairs.len() as f64;
        let d_mean = pairs.iter().map(|q| q.2).sum::<f64>() / m;
        let sdd: f64 = pairs.iter().map(|q| (q.2 - d_mean).powi(2)).sum();
        if sdd <= 1e-12 * (d_mean * d_mean).max(1e-300) * m {
            continue;
        }
        for (c, vc) in v.iter().enumerate() {
            let g = |&(i, j, _): &(usize, usize, f64)| (vc[i] - vc[j]).powi(2) / 2.0;
            let g_mean = pairs.iter().map(g).sum::<f64>() / m;
            let sdg: f64 = pairs.iter().map(|q| (q.2 - d_mean) * (g(q) - g_mean)).sum();
            let slope = sdg / sdd;
            out[c][p] = (g_mean - slope * d_mean) / n as f64;
        }
    }
    out
}

/// The factors `f_W = clamp(margin k_W, 0, 1)` per pixel (module docs) for nuggets `nugget`
/// and modelled variances `variance` (per channel, row-major `width x height`), over windows of
/// half side `half`; 1 where the window has no pixel with a nugget or the model is 0 there.
pub fn nugget_factors(
    nugget: &[Vec<f64>],
    variance: &[Vec<f64>],
    width: usize,
    height: usize,
    half: usize,
    margin: f64,
) -> Vec<f64> {
    let pixels = width * height;
    let mut a = vec![0.0; pixels];
    let mut model = vec![0.0; pixels];
    for (nc, vc) in nugget.iter().zip(variance) {
        for p in 0..pixels {
            if nc[p].is_finite() && vc[p].is_finite() {
                a[p] += nc[p];
                model[p] += vc[p];
            }
        }
    }
    let a = window_sum(&a, width, height, half);
    let model = window_sum(&model, width, height, half);
    a.iter()
        .zip(&model)
        .map(|(&a, &e)| {
            if e > 0.0 {
                (margin * a / e).clamp(0.0, 1.0)
            } else {
                1.0
            }
        })
        .collect()
}
