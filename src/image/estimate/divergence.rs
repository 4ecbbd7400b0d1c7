//! The divergence of a pixel estimate in the box pixels, by one random probe.
//!
//! SURE ([`super::gate`]) needs, for an estimate `x = f(m)` of the box pixels `m` (the mean
//! of each pixel's samples), the derivative `d_P = dx_P / dm_P` of each pixel in its own mean.
//! Where `f` is a black box (`auto`: films, SureShrink and a gate, each pixel from another
//! candidate) it is measured: shift every sample of pixel `P` by `eps_c b_{P,c}` with
//! independent signs `b_{P,c} = +-1`. That moves `m_{P,c}` by exactly `eps_c b_{P,c}` and
//! leaves every spread inside a pixel (the noise estimates, the strata's differences)
//! unchanged, so for a smooth `f`
//!
//! `d^_{P,c} = b_{P,c} (f_{P,c}(m + eps b) - f_{P,c}(m)) / eps_c
//!          = d_{P,c} + sum_{Q != P} b_{P,c} b_{Q,c} df_{P,c} / dm_{Q,c} + O(eps)`,
//!
//! unbiased for `d_{P,c}` over the signs (the cross terms have mean zero; Ramani, Blu and
//! Unser's Monte Carlo SURE, per pixel). Their spread (about the root sum of squares of a
//! pixel's weights on its neighbours, 0.1-0.3 for the films) is averaged away by the window
//! sums SURE is used in. `eps_c` = [`PROBE_STEP`] times the median `|m_{P,c}|` (at least
//! [`PROBE_FLOOR`]): small against the pixels, large enough that the data-dependent choices
//! inside `f` (a gate's window decision, a SURE-chosen threshold, piecewise constant in the
//! data) flip for few probes (measured: [`PROBE_STEP`]); the result is then a difference
//! quotient over that step, not a derivative. A choice that flips is a jump; a probe outside
//! `[PROBE_LOW, PROBE_HIGH]` (the divergences of `auto`'s candidates lie in `[0, 1]`, plus
//! the cross terms) is such a jump and is clamped there, and counted.

use super::statistics::{median, PixelStatistics};
use crate::image::adaptive::mix64;
use crate::image::{ImageSamples, PixelImage};

/// The probe's step relative to the median box pixel of a channel (`|m_{P,c}|`, at least
/// [`PROBE_FLOOR`]). Chosen on the plan's samples of cornell at 8 spp (tuning half), probing
/// `auto` (docs/measurements/plan-quality.md): the share of jumps falls with the step (11 %,
/// 3.5 %, 1.7 %, 0.5 % of the probes at `1e-3`, `1e-2`, `3e-2`, `1e-1`; SureShrink's
/// SURE-chosen thresholds and the gate's window choices are piecewise constant in the data)
/// while the mean divergence stays 0.25-0.28 up to `3e-2` and rises to 0.35 at `1e-1`
/// (the step no longer small against the dark pixels).
pub const PROBE_STEP: f64 = 3e-2;

/// The least typical size of a channel for the probe's step.
pub const PROBE_FLOOR: f64 = 1e-3;

/// The least divergence a probe keeps (below: a jump, clamped).
pub const PROBE_LOW: f64 = -1.0;

/// The largest divergence a probe keeps (above: a jump, clamped).
pub const PROBE_HIGH: f64 = 2.0;

/// The probed divergence per channel and pixel, and the probes clamped as jumps.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbedDivergence {
    /// `d^_{P,c}` (module docs), per channel and pixel.
    pub divergence: Vec<Vec<f64>>,
    /// Pixel-channels whose probe fell outside `[PROBE_LOW, PROBE_HIGH]` (clamped).
    pub jumps: usize,
}

/// The sign `b_{P,c}` of pixel `p`, channel `c` (a hash of both and `seed`).
fn sign(seed: u64, p: usize, c: usize) -> f64 {
    if mix64(seed ^ mix64((p as u64) << 8 | c as u64)) & 1 == 0 {
        1.0
    } else {
        -1.0
    }
}

/// The divergence of `estimate` at `samples`, whose value there is `image` (module docs);
/// the error is `estimate`'s on the shifted samples.
pub fn probe_divergence<F>(
    samples: &ImageSamples,
    image: &PixelImage,
    estimate: F,
    seed: u64,
) -> Result<ProbedDivergence, String>
where
    F: Fn(&ImageSamples) -> Result<PixelImage, String>,
{
    let plane = samples.plane();
    let stats = PixelStatistics::new(samples);
    let eps: Vec<f64> = stats
        .mean
        .iter()
        .map(|m| {
            let mut size: Vec<f64> = m
                .iter()
                .filter(|x| x.is_finite())
                .map(|x| x.abs())
                .collect();
            let typical = if size.is_empty() {
                0.0
            } else {
                median(&mut size)
            };
            PROBE_STEP * typical.max(PROBE_FLOOR)
        })
        .collect();
    let pixel: Vec<usize> = samples
        .xs()
        .iter()
        .zip(samples.ys())
        .map(|(&x, &y)| {
            let (px, py) = plane.pixel_of(x, y);
            py * plane.width() + px
        })
        .collect();
    let values: Vec<Vec<f64>> = samples
        .values()
        .iter()
        .enumerate()
        .map(|(c, v)| {
            v.iter()
                .zip(&pixel)
                .map(|(&x, &p)| x + eps[c] * sign(seed, p, c))
                .collect()
        })
        .collect();
    let shifted = ImageSamples::new(plane, samples.xs().to_vec(), samples.ys().to_vec(), values)
        .map_err(|e| e.to_string())?;
    let moved = estimate(&shifted)?;
    let mut jumps = 0;
    let divergence = (0..image.channels.len())
        .map(|c| {
            (0..plane.pixels())
                .map(|p| {
                    let d =
                        sign(seed, p, c) * (moved.channels[c][p] - image.channels[c][p]) / eps[c];
                    if (PROBE_LOW..=PROBE_HIGH).contains(&d) {
                        d
                    } else {
                        jumps += 1;
                        d.clamp(PROBE_LOW, PROBE_HIGH)
                    }
                })
                .collect()
        })
        .collect();
    Ok(ProbedDivergence { divergence, jumps })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::ImagePlane;

    /// The box pixels have divergence 1 in every pixel (no cross terms), a 3-tap average
    /// along `x` of the box pixels its own weight 1/3 on average over pixels (the cross terms
    /// average out), within the rounding of the step and the signs' spread.
    #[test]
    fn the_box_has_divergence_one_and_an_average_its_weight() {
        let plane = ImagePlane::new(32, 16).unwrap();
        let (mut xs, mut ys, mut v) = (vec![], vec![], vec![]);
        for p in 0..plane.pixels() {
            for k in 0..3 {
                xs.push((p % 32) as f64 + 0.2 + 0.3 * k as f64);
                ys.push((p / 32) as f64 + 0.5);
                v.push(((p * 7 + k * 3) % 11) as f64 * 0.1);
            }
        }
        let samples = ImageSamples::new(plane, xs, ys, vec![v]).unwrap();
        let boxed = |s: &ImageSamples| -> Result<PixelImage, String> {
            Ok(PixelImage {
                plane,
                channels: PixelStatistics::new(s).mean,
            })
        };
        let image = boxed(&samples).unwrap();
        let d = probe_divergence(&samples, &image, boxed, 5).unwrap();
        assert_eq!(d.jumps, 0);
        assert!(d.divergence[0].iter().all(|x| (x - 1.0).abs() < 1e-6));
        let average = |s: &ImageSamples| -> Result<PixelImage, String> {
            let m = &PixelStatistics::new(s).mean[0];
            let out = (0..plane.pixels())
                .map(|p| {
                    let (x, y) = (p % 32, p / 32);
                    let l = y * 32 + x.saturating_sub(1);
                    let r = y * 32 + (x + 1).min(31);
                    (m[l] + m[p] + m[r]) / 3.0
                })
                .collect();
            Ok(PixelImage {
                plane,
                channels: vec![out],
            })
        };
        let image = average(&samples).unwrap();
        let d = probe_divergence(&samples, &image, average, 5).unwrap();
        // interior pixels: 1/3 plus two cross terms of +-1/3, mean 1/3, spread sqrt(2)/3 over
        // 420 pixels: the mean is 1/3 within 5 standard errors (0.11)
        let interior: Vec<f64> = (0..plane.pixels())
            .filter(|p| p % 32 != 0 && p % 32 != 31)
            .map(|p| d.divergence[0][p])
            .collect();
        let mean = interior.iter().sum::<f64>() / interior.len() as f64;
        assert!((mean - 1.0 / 3.0).abs() < 0.11, "{mean}");
        for x in &interior {
            // 1/3 + (+-1/3) + (+-1/3): one of -1/3, 1/3, 1
            assert!(
                [-1.0 / 3.0, 1.0 / 3.0, 1.0]
                    .iter()
                    .any(|t| (x - t).abs() < 1e-6),
                "{x}"
            );
        }
    }
}
