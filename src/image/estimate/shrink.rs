//! Soft wavelet shrinkage of a noisy image, averaged over shifts (cycle spinning).
//!
//! For an image `y = f + e` with independent noise `e` of standard deviation `sigma` in every
//! pixel, an orthonormal transform `W` keeps the noise white: every coefficient of `W e` has
//! standard deviation `sigma`. Soft thresholding of the detail coefficients,
//!
//! `eta_t(d) = sign(d) max(|d| - t, 0)`,  `x^ = W^T eta_t(W y)`,
//!
//! at Donoho and Johnstone's universal threshold `t = k sigma sqrt(2 ln N)` (`N` pixels,
//! `k = 1`) removes, with probability tending to 1, every coefficient that is noise alone, and
//! leaves the approximation coefficient untouched. One orthonormal Haar transform
//! ([`super::haar`]) snaps edges to its dyadic grid; the average of the estimates over the
//! offsets `(o_x, o_y) in {0 .. S - 1}²` (Coifman and Donoho's cycle spinning, `S = 4`: 16
//! transforms) removes most of that. The offsets shift the partition, not the image: no value
//! wraps around from one border to the other (the blocks at the borders are truncated, see
//! [`super::haar`]).
//!
//! Properties the tests check: `t = 0` is the identity to round-off; a constant image is
//! unchanged (its details are zero); each channel is shrunk with its own `sigma_c`.

use super::haar::{Haar2d, HaarCoefficients};
use super::spin::{add_into, for_each_shift_in_order};

/// Parameters of the shrinkage.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ShrinkParams {
    /// Offsets per axis `S` (`S²` transforms averaged): more remove more of the blocking of one
    /// Haar grid and cost `S²` transforms; 1 is one plain transform.
    pub shifts: usize,
    /// `k` in `t = k sigma sqrt(2 ln N)`: smaller keeps more detail and more noise (the
    /// prototype found 0.7 better at 16 spp and worse at 4 spp than 1).
    pub threshold_factor: f64,
    /// `auto` only: every sample count's noise `v_P` brought to the least of three's pure-noise
    /// bias at the most common count before shrinking (`PixelNoise::equalise_counts` in the noise
    /// module), for samples of uneven per-pixel counts (the plan's pixel share). Off by
    /// default: on the plan's own counts it moved seven tuning rows by 0.11-0.30 dB
    /// (docs/measurements/plan-quality.md, "The final image on the pixel share's uneven counts").
    pub equalise_counts: bool,
}

impl Default for ShrinkParams {
    fn default() -> Self {
        Self {
            shifts: 4,
            threshold_factor: 1.0,
            equalise_counts: false,
        }
    }
}

/// The universal threshold `k sigma sqrt(2 ln N)` for an image of `pixels` pixels.
pub fn universal_threshold(sigma: f64, pixels: usize, factor: f64) -> f64 {
    factor * sigma * (2.0 * (pixels.max(1) as f64).ln()).sqrt()
}

/// `sign(d) max(|d| - t, 0)`.
pub fn soft(d: f64, t: f64) -> f64 {
    d.signum() * (d.abs() - t).max(0.0)
}

/// The cycle-spun soft shrinkage at threshold `t` of one channel `image` (`width x height`,
/// row-major), over `shifts²` offsets.
pub fn shrink_channel(
    image: &[f64],
    width: usize,
    height: usize,
    t: f64,
    shifts: usize,
) -> Vec<f64> {
    shrink_spun(image, width, height, t, shifts, false).0
}

/// [`shrink_channel`] and its divergence, the derivative of each output pixel in its own
/// input pixel, `d x^_P / d y_P = (1 / S²) sum_shifts sum_k W²_{kP} 1{|d_k| > t}` (1 for
/// every coefficient at `t = 0`, the identity; soft
/// thresholding is piecewise linear with slope `1{|d| > t}`, the approximation is kept, and
/// cycle spinning averages; [`Haar2d::inverse_squared`]). Each lies in `[0, 1]` (the `W²_{kP}`
/// of one shift sum to 1 over `k`, the rows of an orthonormal matrix). The image is
/// [`shrink_channel`]'s bit for bit.
pub fn shrink_channel_with_divergence(
    image: &[f64],
    width: usize,
    height: usize,
    t: f64,
    shifts: usize,
) -> (Vec<f64>, Vec<f64>) {
    let (image, divergence) = shrink_spun(image, width, height, t, shifts, true);
    (image, divergence.expect("asked for"))
}

/// The cycle-spun soft shrinkage, and its divergence when `divergence` is set.
fn shrink_spun(
    image: &[f64],
    width: usize,
    height: usize,
    t: f64,
    shifts: usize,
    divergence: bool,
) -> (Vec<f64>, Option<Vec<f64>>) {
    let shifts = shifts.max(1);
    let mut sum = vec![0.0; image.len()];
    let mut div = vec![0.0; image.len()];
    // The offsets in parallel, summed in the serial order (`super::spin`).
    let one_shift = |ox: usize, oy: usize| {
        let haar = Haar2d::new(width, height, ox, oy);
        let mut c = haar.forward(image);
        let shift_divergence = divergence.then(|| {
            let mut keep = HaarCoefficients {
                approximation: vec![1.0; c.approximation.len()],
                levels: c.levels.clone(),
            };
            for (bands, kbands) in c.levels.iter().zip(&mut keep.levels) {
                for (d, g) in bands.values().zip(kbands.values_mut()) {
                    *g = f64::from(u8::from(d.abs() > t || t == 0.0));
                }
            }
            haar.inverse_squared(&keep)
        });
        for bands in &mut c.levels {
            bands.values_mut().for_each(|d| *d = soft(*d, t));
        }
        (haar.inverse(&c), shift_divergence)
    };
    for_each_shift_in_order(shifts, one_shift, |(shrunk, shift_divergence)| {
        if let Some(d) = shift_divergence {
            add_into(&mut div, &d);
        }
        add_into(&mut sum, &shrunk);
    });
    let n = (shifts * shifts) as f64;
    sum.iter_mut().for_each(|s| *s /= n);
    div.iter_mut().for_each(|s| *s /= n);
    (sum, divergence.then_some(div))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The divergence of the cycle-spun soft shrinkage at a fixed threshold equals the
    /// finite-difference derivative of each shrunk pixel in its own input (soft thresholding is
    /// piecewise linear, so a step of `1e-7` stays within one piece for these values), lies in
    /// `[0, 1]`, and the image is [`shrink_channel`]'s bit for bit. Tolerance as in
    /// `sureshrink`'s test: round-off `~1e-16 / 1e-7 = 1e-9` in the quotient, `1e-6` far above
    /// it and far below the smallest `W²` weight `1 / (W H)`.
    #[test]
    fn the_divergence_is_the_derivative_of_each_pixel_in_its_own_input() {
        let (w, h, t) = (9, 6, 0.2);
        let image: Vec<f64> = (0..w * h)
            .map(|i| ((i * 7919) % 13) as f64 / 13.0 + if i % 5 == 0 { 1.0 } else { 0.0 })
            .collect();
        let (base, div) = shrink_channel_with_divergence(&image, w, h, t, 2);
        let plain = shrink_channel(&image, w, h, t, 2);
        assert!(base
            .iter()
            .zip(&plain)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        assert!(
            div.iter().any(|&d| d < 0.9),
            "the threshold kills something"
        );
        let eps = 1e-7;
        for p in 0..w * h {
            let mut moved = image.clone();
            moved[p] += eps;
            let fd = (shrink_channel(&moved, w, h, t, 2)[p] - base[p]) / eps;
            assert!((fd - div[p]).abs() <= 1e-6, "pixel {p}: {fd} {}", div[p]);
            assert!((-1e-12..=1.0 + 1e-12).contains(&div[p]));
        }
        // no threshold: nothing moves, divergence 1
        let (same, one) = shrink_channel_with_divergence(&image, w, h, 0.0, 2);
        assert!(same.iter().zip(&image).all(|(a, b)| (a - b).abs() <= 1e-12));
        assert!(one.iter().all(|d| (d - 1.0).abs() <= 1e-12));
    }
}
