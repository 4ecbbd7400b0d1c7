//! Heteroscedastic SureShrink of the box pixels, cycle-spun, with its exact divergence.
//!
//! **Model.** The box pixels `m_P` are independent (disjoint samples) with variances `v_P`
//! (estimated per pixel from the strata, [`super::noise`]; no global level). An orthonormal
//! Haar transform `W` ([`super::haar`]) gives coefficients `d_k = sum_P W_{kP} m_P` with
//! variances `s²_k = sum_P W²_{kP} v_P` ([`Haar2d::forward_squared`]): exact, not a global
//! median, so a textured pixel with a large `v_P` raises only the thresholds of the coefficients
//! that see it.
//!
//! **Threshold (SureShrink, Donoho and Johnstone 1995).** Per level and channel, every detail
//! coefficient is soft-thresholded at `t_k = lambda s_k`. For `d_k ~ N(theta_k, s²_k)`, Stein's
//! unbiased estimate of the risk of `eta_t(d_k)` is
//!
//! `SURE_k(lambda) = s²_k - 2 s²_k 1{|d_k| <= lambda s_k} + min(d²_k, lambda² s²_k)`,
//!
//! and `lambda` minimises the level's sum over `{0} ∪ {|d_k| / s_k}` (the sum is increasing in
//! `lambda` between those points), capped at the universal `sqrt(2 ln n)` of the level's `n`
//! coefficients. `lambda = 0` (no shrinkage) is a candidate, so a level whose SURE says
//! shrinking costs more than it removes is kept as it is. Coefficients with `s_k = 0` (no
//! noise) are kept and left out of the choice.
//!
//! **Divergence.** Soft thresholding is piecewise linear: `d eta_t(d) / d d = 1{|d| > t}`. So
//! the derivative of the output pixel `x^_P` with respect to its own input `m_P` is
//! `sum_k W²_{kP} g_k`, `g_k = 1` for the kept coefficients (and the approximation), 0 for the
//! killed ones ([`Haar2d::inverse_squared`]); the threshold's own dependence on the data is
//! neglected, as SureShrink does. Cycle spinning averages the `S²` shifted estimates; the
//! divergence of the average is the average of the divergences, and the per-pixel SURE
//! `(x^_P - m_P)² - v_P + 2 v_P div_P` of the average is what the gate (`gate.rs`) compares with the
//! box's `v_P`.

use super::haar::{Haar2d, HaarCoefficients};
use super::spin::{add_into, for_each_shift_in_order};

/// The shrunk channel and what the shrinkage did.
#[derive(Debug, Clone, PartialEq)]
pub struct SureShrunk {
    /// The cycle-spun shrunk pixels.
    pub image: Vec<f64>,
    /// `d x^_P / d m_P` per pixel (in `[0, 1]`).
    pub divergence: Vec<f64>,
    /// The chosen `lambda` per shift and level (finest level first), flattened.
    pub lambdas: Vec<f64>,
    /// The fraction of detail coefficients (over all shifts) set to zero.
    pub killed_fraction: f64,
}

/// The `lambda` of least summed SURE for coefficients `d` with standard deviations `s`
/// (module docs), capped at `cap`; coefficients with `s = 0` are left out.
pub fn sure_lambda(d: &[f64], s: &[f64], cap: f64) -> f64 {
    let mut z: Vec<(f64, f64, f64)> = d
        .iter()
        .zip(s)
        .filter(|(_, &sk)| sk > 0.0 && sk.is_finite())
        .map(|(&dk, &sk)| ((dk / sk).abs(), dk * dk, sk * sk))
        .collect();
    if z.is_empty() {
        return 0.0;
    }
    z.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = z.iter().map(|c| c.2).sum();
    // lambda = 0: every coefficient kept, risk sum s² (SURE of the identity).
    let (mut best, mut best_risk) = (0.0, total);
    let (mut killed_var, mut killed_d2) = (0.0, 0.0);
    for &(zk, d2, s2) in &z {
        if zk > cap {
            break;
        }
        killed_var += s2;
        killed_d2 += d2;
        // at lambda = zk the coefficients up to this one are killed (ties killed too: soft
        // thresholding at |d| = t gives 0)
        let risk = total - 2.0 * killed_var + killed_d2 + zk * zk * (total - killed_var);
        if risk < best_risk {
            (best, best_risk) = (zk, risk);
        }
    }
    best
}

/// Heteroscedastic cycle-spun SureShrink of one channel `image` (`width x height`, row-major)
/// whose pixels are independent with variances `variance` (module docs), over `shifts²`
/// offsets of the Haar partition.
pub fn sure_shrink_channel(
    image: &[f64],
    variance: &[f64],
    width: usize,
    height: usize,
    shifts: usize,
) -> SureShrunk {
    shrink_with(image, variance, (width, height), shifts, None)
}

/// [`sure_shrink_channel`], or at the one `lambda` given for every level (for the tests).
fn shrink_with(
    image: &[f64],
    variance: &[f64],
    (width, height): (usize, usize),
    shifts: usize,
    fixed: Option<f64>,
) -> SureShrunk {
    let shifts = shifts.max(1);
    let mut sum = vec![0.0; image.len()];
    let mut div = vec![0.0; image.len()];
    let mut lambdas = vec![];
    let (mut killed, mut details) = (0usize, 0usize);
    let variance: Vec<f64> = variance.iter().map(|v| v.max(0.0)).collect();
    // The offsets in parallel, summed in the serial order (`super::spin`).
    let one_shift = |ox: usize, oy: usize| {
        let haar = Haar2d::new(width, height, ox, oy);
        let mut c = haar.forward(image);
        let var = haar.forward_squared(&variance);
        let mut keep = HaarCoefficients {
            approximation: vec![1.0; c.approximation.len()],
            levels: var.levels.clone(),
        };
        let mut shift_lambdas = vec![];
        let (mut shift_killed, mut shift_details) = (0usize, 0usize);
        for ((bands, vbands), kbands) in c.levels.iter_mut().zip(&var.levels).zip(&mut keep.levels)
        {
            let d: Vec<f64> = bands.values().copied().collect();
            let s: Vec<f64> = vbands.values().map(|v| v.max(0.0).sqrt()).collect();
            let cap = (2.0 * (d.len().max(2) as f64).ln()).sqrt();
            let lambda = fixed.unwrap_or_else(|| sure_lambda(&d, &s, cap));
            shift_lambdas.push(lambda);
            for ((dk, sk), gk) in bands.values_mut().zip(&s).zip(kbands.values_mut()) {
                let t = lambda * sk;
                let kept = dk.abs() > t || t == 0.0;
                *dk = if kept {
                    dk.signum() * (dk.abs() - t)
                } else {
                    0.0
                };
                *gk = f64::from(u8::from(kept));
                shift_killed += usize::from(!kept);
                shift_details += 1;
            }
        }
        (
            haar.inverse(&c),
            haar.inverse_squared(&keep),
            shift_lambdas,
            shift_killed,
            shift_details,
        )
    };
    for_each_shift_in_order(
        shifts,
        one_shift,
        |(shrunk, shift_divergence, shift_lambdas, shift_killed, shift_details)| {
            add_into(&mut sum, &shrunk);
            add_into(&mut div, &shift_divergence);
            lambdas.extend(shift_lambdas);
            killed += shift_killed;
            details += shift_details;
        },
    );
    let n = (shifts * shifts) as f64;
    sum.iter_mut().for_each(|s| *s /= n);
    div.iter_mut().for_each(|s| *s /= n);
    SureShrunk {
        image: sum,
        divergence: div,
        lambdas,
        killed_fraction: killed as f64 / details.max(1) as f64,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chosen lambda's SURE is the least over a fine grid of lambdas (the sum is piecewise
    /// increasing between the candidates, so the grid cannot beat them).
    #[test]
    fn the_lambda_minimises_the_summed_sure_over_a_grid() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let d: Vec<f64> = (0..200)
            .map(|k| next() * if k % 10 == 0 { 20.0 } else { 2.0 })
            .collect();
        let s: Vec<f64> = (0..200).map(|_| 0.5 + next().abs()).collect();
        let sure = |lambda: f64| -> f64 {
            d.iter()
                .zip(&s)
                .map(|(&dk, &sk)| {
                    let killed = dk.abs() <= lambda * sk;
                    sk * sk - 2.0 * sk * sk * f64::from(u8::from(killed))
                        + (dk * dk).min(lambda * lambda * sk * sk)
                })
                .sum()
        };
        let cap = 3.0;
        let lambda = sure_lambda(&d, &s, cap);
        assert!(lambda <= cap);
        let best = sure(lambda);
        for i in 0..=3000 {
            let l = cap * i as f64 / 3000.0;
            assert!(best <= sure(l) + 1e-9 * best.abs(), "{lambda} {l}");
        }
    }

    /// The squared transform's divergence equals the finite-difference derivative of the
    /// shrunk pixel with respect to its own input (soft thresholding is piecewise linear, so a
    /// tiny step stays within one piece), for every pixel of an odd-sized image. Tolerance:
    /// the step `1e-7` on values of order 1 leaves a round-off of about `1e-16 / 1e-7 = 1e-9`
    /// in the quotient; `1e-6` is far above it and far below the `W²` weights (at least
    /// `1 / (W H)`).
    #[test]
    fn the_divergence_is_the_derivative_of_each_pixel_in_its_own_input() {
        let (w, h) = (9, 6);
        let image: Vec<f64> = (0..w * h)
            .map(|i| ((i * 7919) % 13) as f64 / 13.0 + if i % 5 == 0 { 1.0 } else { 0.0 })
            .collect();
        let variance: Vec<f64> = (0..w * h).map(|i| 0.01 + 0.002 * (i % 4) as f64).collect();
        // a fixed lambda (the data-chosen one sits on a kink |d_k| = t_k by construction)
        let base = shrink_with(&image, &variance, (w, h), 2, Some(1.3));
        assert!(base.killed_fraction > 0.1 && base.killed_fraction < 0.9);
        let eps = 1e-7;
        for p in 0..w * h {
            let mut moved = image.clone();
            moved[p] += eps;
            let other = shrink_with(&moved, &variance, (w, h), 2, Some(1.3));
            let fd = (other.image[p] - base.image[p]) / eps;
            assert!(
                (fd - base.divergence[p]).abs() <= 1e-6,
                "pixel {p}: {fd} {}",
                base.divergence[p]
            );
            assert!((-1e-12..=1.0 + 1e-12).contains(&base.divergence[p]));
        }
    }

    /// No noise: every coefficient kept, the image unchanged to round-off, divergence 1.
    #[test]
    fn without_noise_nothing_moves() {
        let (w, h) = (7, 5);
        let image: Vec<f64> = (0..w * h).map(|i| (i as f64).sin()).collect();
        let out = sure_shrink_channel(&image, &vec![0.0; w * h], w, h, 4);
        for (a, b) in image.iter().zip(&out.image) {
            assert!((a - b).abs() <= 1e-12);
        }
        for d in &out.divergence {
            assert!((d - 1.0).abs() <= 1e-12);
        }
    }
}
