//! A robust estimate of the pixel integral for heavy-tailed samples (fireflies, caustics):
//! the samples' upper tail cut at a threshold from the neighbourhood, and the cut energy put
//! back as the window's average, so that the bias of the cut is estimated and corrected
//! rather than left as a silent clamp. It is one candidate of the risk gate ([`super::gate`]),
//! which takes it only where its SURE over the window is below the box's and the others'.
//!
//! **Threshold.** Per pixel `P` and channel `c`, from the samples of the 3 x 3 pixels around
//! `P` (its own included), `tau_P = med + kappa 1.4826 MAD` (median and median absolute
//! deviation: the scale of a Gaussian's bulk, unmoved by a few fireflies), `kappa` =
//! [`KAPPA`]. Only the upper tail is cut (radiance is bounded below by 0; a dark outlier is
//! not the heavy tail of a light-transport estimator).
//!
//! **The cut mean and its bias.** With `n_P` samples `v_i` in `P`, the cut mean
//! `c_P = (1 / n_P) sum_i min(v_i, tau_P)` has bias `-e_P`, `e_P = E (v - tau_P)_+` the
//! expected excess of one sample over the threshold. One pixel's own excess
//! `(1 / n_P) sum_i (v_i - tau_P)_+` is the firefly itself (its variance is what the cut
//! removes); the excess of the samples of the `(2 h + 1)²` window `W(P)` around `P`,
//!
//! `b_P = sum_{Q in W(P)} sum_{i in Q} (v_i - tau_Q)_+ / sum_{Q in W(P)} n_Q`,
//!
//! estimates `e_P` from `|W| n` samples where the tail is locally stationary (the same
//! distribution of excess in the window). The robust estimate is the cut mean with its
//! estimated bias added back:
//!
//! `r_P = c_P + b_P`.
//!
//! **Its bias.** `E r_P - mu_P = E b_P - e_P`: zero where the excess is stationary over the
//! window (each sample's excess has the same expectation, so `E b_P = e_P`), and in general
//! between `min_{Q in W} e_Q - e_P` and `max_{Q in W} e_Q - e_P`, so at most the window's
//! largest expected excess per sample, `|E r_P - mu_P| <= max_{Q in W(P)} e_Q`. The report
//! gives `b_P` (the cut mean's estimated bias, averaged over pixels, relative to the mean
//! radiance) and the largest `b_P`, the estimate of that bound. Summed over the pixels whose
//! windows lie inside the image, `sum_P r_P = sum_P m_P` exactly (each sample's excess is
//! counted once per window it lies in, `(2 h + 1)²` windows of `(2 h + 1)² n` samples at a
//! constant `n`): the energy cut is moved within the window, not lost.
//!
//! **Divergence** (for SURE): shifting every sample of `P` by `delta` moves the `n_P - k_P`
//! samples below the threshold (`k_P` cut) and adds `k_P delta` to the window's excess, so
//! `d r_P / d m_P = (n_P - k_P) / n_P + k_P / N_W(P)`, `N_W` the samples of the window (the
//! threshold's own small move with the pixel's samples neglected).

use rayon::prelude::*;
use serde::Serialize;

use super::statistics::median;
use super::sure::window_sum;
use crate::image::splat::PixelBins;
use crate::image::{ImageSamples, PixelImage};

/// `kappa` of the threshold `med + kappa 1.4826 MAD`: a sample this many robust standard
/// deviations above the neighbourhood's median is cut (chosen on the suite's tuning half:
/// docs/measurements/estimators.md).
pub const KAPPA: f64 = 6.0;

/// Half the side of the window over which the cut energy is put back, `(2 h + 1)²` pixels
/// (the gate's window).
pub const ROBUST_HALF: usize = super::gate::GATE_HALF;

/// What the robust estimate cut and put back.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobustReport {
    /// `kappa` of the threshold.
    pub kappa: f64,
    /// The window's side over which the cut energy is put back.
    pub window: usize,
    /// Samples cut (any channel).
    pub cut_samples: usize,
    /// Pixels with a cut sample.
    pub cut_pixels: usize,
    /// Per channel: the cut excess as a fraction of the samples' total.
    pub cut_fraction: Vec<f64>,
    /// Per channel: the cut mean's estimated bias `b_P` averaged over pixels, relative to the
    /// mean of the box pixels (what the correction adds back).
    pub mean_bias: Vec<f64>,
    /// Per channel: the largest `b_P`, the estimate of the bound
    /// `|E r_P - mu_P| <= max_{Q in W(P)} e_Q` on the robust estimate's bias.
    pub bias_bound: Vec<f64>,
    /// Pixels the gate gave the robust estimate (with or without its projection onto the
    /// pixel's range).
    pub gated_pixels: usize,
}

impl RobustReport {
    /// In words.
    pub fn describe(&self) -> String {
        let pct = |v: &[f64]| {
            v.iter()
                .map(|x| format!("{:.2}%", 100.0 * x))
                .collect::<Vec<_>>()
                .join(", ")
        };
        format!(
            "robust candidate (samples above med + {} x 1.4826 MAD of their 3x3 neighbourhood \
             cut, the cut energy put back as the {w} x {w} window's average): {} samples in {} \
             pixels cut, {} of the energy per channel; the cut mean's estimated bias {} of the \
             mean radiance per channel, largest {} (the bound on the robust estimate's bias \
             where the tail is not stationary over the window); taken by the gate in {} pixels",
            self.kappa,
            self.cut_samples,
            self.cut_pixels,
            pct(&self.cut_fraction),
            pct(&self.mean_bias),
            super::list(&self.bias_bound),
            self.gated_pixels,
            w = self.window,
        )
    }
}

/// The threshold `tau_P = med + kappa 1.4826 MAD` of every pixel (row-major) from the values
/// of the samples of its 3 x 3 neighbourhood (module docs), `None` where the neighbourhood
/// holds none. The rows in parallel: each pixel's threshold is its own neighbourhood's alone.
fn cut_thresholds(
    bins: &PixelBins,
    values: &[f64],
    (w, h): (usize, usize),
    kappa: f64,
) -> Vec<Option<f64>> {
    let rows: Vec<Vec<Option<f64>>> = (0..h)
        .into_par_iter()
        .map_init(Vec::new, |neighbourhood: &mut Vec<f64>, py| {
            (0..w)
                .map(|px| {
                    neighbourhood.clear();
                    for qy in py.saturating_sub(1)..(py + 2).min(h) {
                        for qx in px.saturating_sub(1)..(px + 2).min(w) {
                            neighbourhood
                                .extend(bins.in_pixel(qy * w + qx).iter().map(|&i| values[i]));
                        }
                    }
                    if neighbourhood.is_empty() {
                        return None;
                    }
                    let med = median(neighbourhood);
                    neighbourhood.iter_mut().for_each(|v| *v = (*v - med).abs());
                    let mad = median(neighbourhood);
                    Some(med + kappa * 1.4826 * mad)
                })
                .collect()
        })
        .collect();
    rows.concat()
}

/// The robust estimate: its pixels, their divergence per channel and the report (with
/// `gated_pixels` 0; the caller fills it).
pub fn robust_estimate(
    samples: &ImageSamples,
    bins: &PixelBins,
    kappa: f64,
    half: usize,
) -> (PixelImage, Vec<Vec<f64>>, RobustReport) {
    let plane = samples.plane();
    let (w, h) = (plane.width(), plane.height());
    let pixels = plane.pixels();
    let channels = samples.channels();
    let count: Vec<f64> = (0..pixels).map(|p| bins.in_pixel(p).len() as f64).collect();
    let window_count = window_sum(&count, w, h, half);
    let mut image = PixelImage::zeros(plane, channels);
    let mut divergence = vec![vec![1.0; pixels]; channels];
    let mut cut_any = vec![false; samples.len()];
    let (mut cut_fraction, mut mean_bias, mut bias_bound) = (vec![], vec![], vec![]);
    for (c, values) in samples.values().iter().enumerate() {
        let mut cut_sum = vec![0.0; pixels];
        let mut excess = vec![0.0; pixels];
        let mut cut_count = vec![0.0; pixels];
        let thresholds = cut_thresholds(bins, values, (w, h), kappa);
        for (p, tau) in thresholds.into_iter().enumerate() {
            let Some(tau) = tau else { continue };
            for &i in bins.in_pixel(p) {
                let v = values[i];
                if v > tau {
                    cut_sum[p] += tau;
                    excess[p] += v - tau;
                    cut_count[p] += 1.0;
                    cut_any[i] = true;
                } else {
                    cut_sum[p] += v;
                }
            }
        }
        let window_excess = window_sum(&excess, w, h, half);
        let total: f64 = values.iter().sum();
        let mut bias_sum = 0.0;
        let mut largest = 0.0f64;
        for p in 0..pixels {
            if count[p] == 0.0 {
                continue;
            }
            let b = window_excess[p] / window_count[p];
            image.channels[c][p] = cut_sum[p] / count[p] + b;
            divergence[c][p] =
                (count[p] - cut_count[p]) / count[p] + cut_count[p] / window_count[p];
            bias_sum += b;
            largest = largest.max(b);
        }
        let mean_radiance = total / samples.len().max(1) as f64;
        cut_fraction.push(if total > 0.0 {
            excess.iter().sum::<f64>() / total
        } else {
            0.0
        });
        mean_bias.push(if mean_radiance > 0.0 {
            bias_sum / pixels as f64 / mean_radiance
        } else {
            0.0
        });
        bias_bound.push(largest);
    }
    let cut_pixels = (0..pixels)
        .filter(|&p| bins.in_pixel(p).iter().any(|&i| cut_any[i]))
        .count();
    let report = RobustReport {
        kappa,
        window: 2 * half + 1,
        cut_samples: cut_any.iter().filter(|&&b| b).count(),
        cut_pixels,
        cut_fraction,
        mean_bias,
        bias_bound,
        gated_pixels: 0,
    };
    (image, divergence, report)
}
