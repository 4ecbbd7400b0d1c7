//! The fit as a control variate, the adaptive engine's output pixels: box pixels of the tree
//! fit plus the significant mean residual of the samples in each pixel.
//!
//! For a pixel `P` (unit area) with `n_P` samples `i in P`, `f~` the tree fit and
//! `r_i = f_i - f~(x_i)` the residuals, the estimate
//!
//! `I_P = int_P f~ + (1 / n_P) sum_{i in P} r_i`
//!
//! is the box filter's estimate of `int_P f` with the fit as a control variate: where the fit
//! resolves the scene the residuals vanish and `I_P` is the fit's pixel; where it cannot
//! (detail below the depth limit: a sub-pixel line, an edge inside a finest cell fitted by two
//! samples, where least squares nearly interpolates and rings) the residual mean of the
//! stratified samples restores it as a box filter would, with the variance of the residual
//! instead of that of `f`.
//!
//! *Significance.* Under noise of deviation `sigma` the mean adds noise `sigma / sqrt(n_P)`
//! per channel, undoing the least-squares smoothing, so the mean `m_P` (one entry per channel,
//! `ch` channels) is added only where it stands out of that noise:
//!
//! `|m_P|_2 > z sigma sqrt(ch / n_P)`
//!
//! (`z` standard errors of the residual mean, `AdaptiveParams::residual_z`, 3 by default;
//! `sigma` the noise test's estimate from the same fit, `significance`; `sigma = 0`,
//! no noise test, or `z = 0`: every pixel whose mean residual is not exactly zero is corrected).
//! Pixels without a sample keep the fit's value.
//!
//! *Range clamp.* The box-filtered truth of `P` is a mean of `f` over `P`, so it lies in
//! `[inf_P f, sup_P f]`; the samples of `P` and its eight neighbours give the range
//! `[lo_P, hi_P]` of their values, which covers that interval where the neighbourhood's
//! samples see the extremes of `f` in `P`. Each channel of the corrected pixel is clamped to
//! it, `I'_P = min(max(I_P, lo_P), hi_P)`: a projection onto an interval, so wherever the
//! truth lies in `[lo_P, hi_P]`, `|I'_P - t_P| <= |I_P - t_P|` (it removes the fit's ringing
//! beside edges and sub-pixel lines). Pixels without a sample in their neighbourhood are
//! kept. Its gain on the analytic scenes, with and without noise: docs/measurements/image-plane.md,
//! "Adaptive image sampling: quality".
//!
//! *Shrinkage* ([`PixelEstimate::Shrunk`], [`PixelEstimate::BoxShrunk`]). Under Monte Carlo
//! noise the corrected pixels keep the noise of the samples where the correction is
//! significant, and the fit's own noise elsewhere. These two estimates denoise the image as
//! the uniform path's `shrunk` does ([`crate::image::estimate`]): soft shrinkage in the
//! orthonormal Haar basis, cycle-spun over 16 shifts, at the universal threshold
//! `t_c = sigma_c sqrt(2 ln N)` of the noise level of a pixel's mean from the samples' own
//! spread, `sigma_c = sqrt(median_P s²_{P,c} / n_P)` ([`PixelStatistics::noise_level`]).
//! Where the samples carry no pixel-scale noise `sigma_c` is near zero and the image is kept.
//! `Shrunk` shrinks the clamped corrected pixels; `BoxShrunk` shrinks the box pixels (the
//! mean of each pixel's samples; the clamped corrected pixel where a pixel has none).
//!
//! *Auto* ([`PixelEstimate::Auto`]). Per pixel the film filter of least SURE over the
//! window around it, on the plan's own samples, then shrinkage at the chosen films' noise: the
//! uniform path's `auto` ([`crate::image::estimate::auto`], whose module states the risk
//! estimate), run on the samples the rounds placed. SURE compares each film with the mean of
//! the pixel's own samples, so it needs a sample in every pixel and two in at least half of
//! them; otherwise the output is [`PixelEstimate::Shrunk`]'s and the reason is kept in
//! [`ResidualCorrection::auto_fallback`] and printed. SURE is unbiased for noise in the
//! values at fixed positions (Monte Carlo noise); it does not see the fit's gain as a control
//! variate against the error of the positions (texture past Nyquist), so where that gain is
//! the larger one `Shrunk` is better: docs/measurements/real-renders.md, "The plan at 4, 8
//! and 16 spp, and its final image by SURE".
//!
//! *Blend* ([`PixelEstimate::Blend`]). `shrunk` and `auto` err differently: SURE does not see
//! the fit's gain as a control variate (texture past Nyquist at low spp, where `shrunk` can
//! be ahead), and the corrected pixels keep the fit's ringing and the samples' noise where the
//! films average it (Monte Carlo noise, where `auto` is ahead). Each pixel is their
//! combination `w_P S_P + (1 - w_P) A_P` with the inverse-risk weight
//! `w_P = R^A_P / (R^S_P + R^A_P)` ([`crate::image::estimate::blend`], the least variance for
//! uncorrelated errors). Both risks are SURE against the box pixels `m_P` (the mean of the
//! pixel's own samples, unbiased with variance `v_P`, [`crate::image::estimate::noise`]),
//! relative (each channel weighted by `omega = 1 / (A² + eps)`, auto's scale) and averaged
//! over the gate's window, both with `auto`'s `v_P` (after its check across pixels): `R^A_P`
//! is `auto`'s own gate risk; for `shrunk`,
//!
//! `R^S_P = sum_c omega ((S_P - m_P)² - v_P + 2 v_P d_S)`, `d_S = d_pre d_H`,
//!
//! Stein's estimate with the divergence `d_S = dS_P / dm_P` by the chain rule through the
//! two steps of `shrunk`: the corrected, clamped pixel moves with its mean at most one for
//! one (the residual mean adds `m_P` itself, the fit's box pixel its leverage, at most 1, the
//! clamp 0 or 1), taken at that bound `d_pre = 1`; the cycle-spun soft shrinkage's own
//! derivative is exact, `d_H = (1 / S²) sum_shifts sum_k W²_{kP} 1{|d_k| > t}`
//! ([`shrink_channel_with_divergence`], in `[0, 1]`). The cross terms (the fit's box pixel of
//! a neighbour `Q` moving with `m_P`, then shrunk into `P`) and the threshold's dependence on
//! the data are neglected, as SureShrink neglects the latter. Before the session of the
//! fifteenth `d_S` was taken at its bound 1, which overstates `shrunk`'s risk by
//! `2 v_P (1 - d_H)` where the noise is shrunk (fog at 4 spp: `shrunk` alone has 0.48 of the
//! best film's relMSE, the blend with the bound 1.15, giving `shrunk` under 1 % of the
//! weight): docs/measurements/estimators.md. The risk sees the bias of the fit and of the
//! shrinkage: where the samples resolve texture the fit smooths and the shrinkage removes,
//! `(S - m)²` is large and `auto` (which keeps the box where SURE says so) takes the weight.
//! The weights lie in `[0, 1]`, so each pixel lies
//! between its two inputs. Where `auto` is not permitted the output is `shrunk`'s, said as for
//! `auto`. Its figures: docs/measurements/plan-quality.md.
//!
//! *No harm* ([`PixelEstimate::BlendGated`]). The inverse-risk weight is the least variance
//! for *uncorrelated* errors; where `shrunk` and `auto` err the same way (both smooth texture
//! past Nyquist that the plan's samples resolve) a weight of 0.1-0.2 on a `shrunk` seven
//! times worse still raises the risk above the box pixels' (grazing and text at 16 spp, the
//! blend below the mean of its own samples: docs/measurements/plan-quality.md). So after the
//! blend each pixel takes, of the box pixels `m_P` (divergence 1, risk `v_P`), `auto` and the
//! blend, the one of least relative SURE summed over the gate's `(2 h + 1)²` window at its
//! level ([`crate::image::estimate::gate::gate`], `omega = 1 / (A² + eps)`, levels from `A`;
//! ties to the box): no pixel takes a step its estimate says raises the risk over the box's.
//! The divergences: `auto`'s by one random probe of its own samples
//! ([`crate::image::estimate::divergence`]), the blend's `w_P d_S + (1 - w_P) d_A` (the
//! weights' dependence on the data, through window sums, neglected). Then the range
//! projection. What the gate chose, its estimated risk against the box's and the probe's
//! jumps are in the report ([`ResidualCorrection::final_gate`]). Measured against the
//! ungated blend: docs/measurements/plan-quality.md.
//!
//! *SURE blend* ([`PixelEstimate::BlendSure`]): `shrunk`'s weight capped ([`super::blend_sure`]).
//!
//! [`PixelEstimate`] chooses between this (the default, clamped), the correction without the
//! clamp and the fit's box pixels alone; all
//! the in-process loop (`refine_image`) and the file protocol
//! (`protocol::PlanState::reconstruct`) compute it here from the final fit and its
//! noise estimate, so the two give the same pixels bit for bit.

use serde::{Deserialize, Serialize};

use super::blend_sure::{blend_by_sure, SureBlend};
use super::final_gate::{self, FinalGate};
use super::fit::TreeFit;
use super::significance::residuals;
use super::AdaptiveError;
use crate::adaptive::QuadTree;
use crate::image::estimate::auto;
use crate::image::estimate::blend::blend_by_risks;
use crate::image::estimate::gate::GATE_HALF;
use crate::image::estimate::sure::window_mean;
use crate::image::estimate::{
    shrink_channel, shrink_channel_with_divergence, universal_threshold, FilmCount,
    PixelStatistics, ShrinkParams,
};
use crate::image::{ImagePlane, ImageSamples, PixelImage};

pub use crate::image::estimate::clamp::{clamp_to_local_range, CLAMP_COUNT_TOLERANCE};

/// Standard errors of the residual mean beyond which a pixel is corrected (the default of
/// `AdaptiveParams::residual_z`): a pixel of pure noise is corrected with probability
/// about `0.27%` (one channel, known `sigma`).
pub const RESIDUAL_Z: f64 = 3.0;

/// Which pixels the adaptive engine outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PixelEstimate {
    /// Box pixels of the fit plus the significant mean residual of each pixel's samples,
    /// clamped to the range of the sample values in the pixel and its eight neighbours (the
    /// default; this module).
    #[default]
    ResidualClamped,
    /// Box pixels of the fit plus the significant mean residual of each pixel's samples (the
    /// fit as a control variate), without the clamp.
    ResidualCorrected,
    /// Box pixels of the fit alone (smoother under noise where the correction is not
    /// significant anyway; loses what the fit cannot represent below the depth limit).
    FitOnly,
    /// [`PixelEstimate::ResidualClamped`], then shrunk at the samples' noise level (module
    /// docs, *Shrinkage*).
    Shrunk,
    /// The box pixels (the clamped corrected pixel where a pixel holds no sample), shrunk at
    /// the samples' noise level (module docs, *Shrinkage*).
    BoxShrunk,
    /// The film of least SURE per pixel on the plan's samples, then Haar shrinkage (the
    /// uniform path's `auto`, [`crate::image::estimate::auto`]); [`PixelEstimate::Shrunk`]
    /// where the samples do not permit it (module docs, *Auto*).
    Auto,
    /// [`PixelEstimate::Shrunk`] and [`PixelEstimate::Auto`] combined per pixel with
    /// inverse-risk weights ([`crate::image::estimate::blend`]); [`PixelEstimate::Shrunk`]
    /// where `auto` is not permitted (module docs, *Blend*).
    Blend,
    /// [`PixelEstimate::Blend`], then per pixel the least estimated risk of the box pixels,
    /// `auto` and the blend over the gate's window (module docs, *No harm*).
    BlendGated,
    /// [`PixelEstimate::Shrunk`] and [`PixelEstimate::Auto`] combined per pixel by the weight
    /// of least SURE of the combination over a window ([`super::blend_sure`]; module docs,
    /// *SURE blend*); [`PixelEstimate::Shrunk`] where `auto` is not permitted.
    BlendSure,
}

impl PixelEstimate {
    /// Every estimate.
    pub const ALL: [PixelEstimate; 9] = [
        PixelEstimate::ResidualClamped,
        PixelEstimate::ResidualCorrected,
        PixelEstimate::FitOnly,
        PixelEstimate::Shrunk,
        PixelEstimate::BoxShrunk,
        PixelEstimate::Auto,
        PixelEstimate::Blend,
        PixelEstimate::BlendGated,
        PixelEstimate::BlendSure,
    ];

    /// The name on the command line and in state files.
    pub fn name(self) -> &'static str {
        match self {
            PixelEstimate::ResidualClamped => "residual_clamped",
            PixelEstimate::ResidualCorrected => "residual_corrected",
            PixelEstimate::FitOnly => "fit_only",
            PixelEstimate::Shrunk => "shrunk",
            PixelEstimate::BoxShrunk => "box_shrunk",
            PixelEstimate::Auto => "auto",
            PixelEstimate::Blend => "blend",
            PixelEstimate::BlendGated => "blend_gated",
            PixelEstimate::BlendSure => "blend_sure",
        }
    }

    /// Whether the estimate shrinks at the samples' noise level ([`PixelEstimate::Auto`]
    /// shrinks too, at the chosen films' noise, or falls back to [`PixelEstimate::Shrunk`]).
    pub fn shrinks(self) -> bool {
        matches!(
            self,
            PixelEstimate::Shrunk
                | PixelEstimate::BoxShrunk
                | PixelEstimate::Auto
                | PixelEstimate::Blend
                | PixelEstimate::BlendGated
                | PixelEstimate::BlendSure
        )
    }
}

impl std::str::FromStr for PixelEstimate {
    type Err = String;
    /// An estimate by [`PixelEstimate::name`] (`-` for `_` accepted); the error names the
    /// choices.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_lowercase().replace('-', "_");
        PixelEstimate::ALL
            .into_iter()
            .find(|e| e.name() == t)
            .ok_or_else(|| {
                format!(
                    "unknown output pixels `{s}`: expected residual_clamped, residual_corrected, \
                     fit_only, shrunk, box_shrunk, auto, blend, blend_gated or blend_sure"
                )
            })
    }
}

/// What the residual correction did: every pixel corrected is counted.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ResidualCorrection {
    /// The output chosen.
    pub estimate: PixelEstimate,
    /// Standard errors of the residual mean beyond which a pixel is corrected.
    pub z: f64,
    /// The noise deviation the test used (the noise test's estimate; 0 without one).
    pub sigma: f64,
    /// Pixels holding at least one sample.
    pub sampled: usize,
    /// Pixels corrected by their mean residual (0 for [`PixelEstimate::FitOnly`]).
    pub corrected: usize,
    /// Largest correction applied, `max_P |m_P|_2` over the corrected pixels (0 if none).
    pub largest: f64,
    /// Pixels the range clamp moved by more than [`CLAMP_COUNT_TOLERANCE`] in some channel
    /// (0 without the clamp).
    pub clamped: usize,
    /// Largest move of the range clamp (0 without the clamp).
    pub largest_clamp: f64,
    /// The shrinkage's noise level per channel, `sigma_c` (shrinking estimates only; `None`
    /// there too when no pixel holds two samples: nothing is shrunk).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shrink_sigma: Option<Vec<f64>>,
    /// The shrinkage's threshold per channel, `t_c` (as `shrink_sigma`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub shrink_threshold: Option<Vec<f64>>,
    /// [`PixelEstimate::Auto`] and [`PixelEstimate::Blend`]: the pixels per film chosen by
    /// SURE (`None` when it fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub films: Option<Vec<FilmCount>>,
    /// [`PixelEstimate::Auto`] and [`PixelEstimate::Blend`]: why the samples did not permit
    /// `auto`, so that the output is [`PixelEstimate::Shrunk`]'s.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub auto_fallback: Option<String>,
    /// [`PixelEstimate::Auto`] and [`PixelEstimate::Blend`]: what `auto` did, in words (its
    /// risk gate, films, SureShrink and range projection; `None` when it fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub auto_description: Option<String>,
    /// [`PixelEstimate::Blend`]: the range projection of the blended pixels onto the samples
    /// of their 3x3 neighbourhood: pixels moved (`None` when it fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blend_clamped: Option<usize>,
    /// [`PixelEstimate::Blend`]: the mean over pixels of the weight of the `shrunk` pixel
    /// (`None` when it fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blend_weight: Option<f64>,
    /// [`PixelEstimate::Blend`]: the mean over pixels of the weight of the `auto` pixel
    /// (`None` when it fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blend_weight_auto: Option<f64>,
    /// [`PixelEstimate::Blend`]: the mean over pixels and channels of the divergence `d_S`
    /// of the `shrunk` pixel in its own pixel's mean used in `shrunk`'s risk (the bound
    /// [`SHRUNK_DIVERGENCE_BOUND`] times the shrinkage's exact divergence; `None` when it fell
    /// back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blend_shrunk_divergence: Option<f64>,
    /// [`PixelEstimate::Blend`]: the pixels where a risk is not a number, so that both pixels
    /// weigh 1/2 (`None` when it fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blend_unknown_risk: Option<usize>,
    /// [`PixelEstimate::BlendGated`]: what the final gate against the box pixels did (module
    /// docs, *No harm*; `None` when it did not run).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_gate: Option<FinalGate>,
    /// [`PixelEstimate::BlendGated`]: why the final gate did not run (the probe's `auto`
    /// failed on the shifted samples), so that the output is the blend ungated.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_gate_fallback: Option<String>,
    /// [`PixelEstimate::BlendSure`]: what its weights did (`None` when `auto` fell back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sure_blend: Option<SureBlend>,
}

impl ResidualCorrection {
    /// The final gate in words ([`PixelEstimate::BlendGated`]).
    fn final_gate_note(&self) -> String {
        if self.estimate == PixelEstimate::BlendSure {
            return self
                .sure_blend
                .as_ref()
                .map_or_else(|| "no SURE weights".to_string(), SureBlend::describe);
        }
        match (&self.final_gate, &self.final_gate_fallback) {
            (Some(gate), _) => gate.describe(),
            (None, Some(reason)) => {
                format!("no final gate (the probe of auto's divergence failed: {reason})")
            }
            (None, None) => "no final gate".to_string(),
        }
    }

    /// The correction in words (for the notes of a report).
    pub fn note(&self) -> String {
        if matches!(
            self.estimate,
            PixelEstimate::Blend | PixelEstimate::BlendGated | PixelEstimate::BlendSure
        ) {
            let shrunk = ResidualCorrection {
                estimate: PixelEstimate::Shrunk,
                ..self.clone()
            }
            .note();
            let shrunk = shrunk.trim_start_matches("output pixels: ");
            return match (self.blend_weight, &self.auto_fallback) {
                (Some(w), _) => {
                    format!(
                    "output pixels: {name}, per pixel the {how} combination of shrunk and auto \
                     (risks: SURE against the box pixels relative to 1 / (auto² + {eps}), \
                     each averaged over the {side} x {side} window; shrunk's divergence: the \
                     correction's bound {bound} times the shrinkage's exact one, mean {d:.3}; \
                     mean weights: shrunk {w:.3}, auto {wa:.3}{}); {}; {} \
                     pixels projected onto the range of the samples in their 3x3 \
                     neighbourhood; auto: {}; shrunk: {shrunk}",
                    match self.blend_unknown_risk {
                        Some(n) if n > 0 => format!(
                            "; {n} pixels with a risk that is not a number: both weighted 1/2"
                        ),
                        _ => String::new(),
                    },
                    self.final_gate_note(),
                    self.blend_clamped.unwrap_or(0),
                    self.auto_description
                        .as_deref()
                        .unwrap_or("")
                        .trim_start_matches("pixels: auto, "),
                    eps = auto::RELATIVE_EPS,
                    d = self.blend_shrunk_divergence.unwrap_or(SHRUNK_DIVERGENCE_BOUND),
                    bound = SHRUNK_DIVERGENCE_BOUND,
                    wa = self.blend_weight_auto.unwrap_or(0.0),
                    side = 2 * GATE_HALF + 1,
                    name = self.estimate.name(),
                    how = if self.estimate == PixelEstimate::BlendSure {
                        "SURE-weighted"
                    } else {
                        "inverse-risk"
                    },
                )
                }
                (None, reason) => format!(
                    "output pixels: {} fell back to shrunk (auto: {}); {shrunk}",
                    self.estimate.name(),
                    reason.as_deref().unwrap_or("no reason given"),
                ),
            };
        }
        if self.estimate == PixelEstimate::Auto {
            return match (&self.auto_description, &self.auto_fallback) {
                (Some(auto), _) => format!(
                    "output pixels: auto on the plan's samples; {}",
                    auto.trim_start_matches("pixels: auto, ")
                ),
                (None, reason) => {
                    let shrunk = ResidualCorrection {
                        estimate: PixelEstimate::Shrunk,
                        ..self.clone()
                    };
                    format!(
                        "output pixels: auto fell back to shrunk ({}); {}",
                        reason.as_deref().unwrap_or("no reason given"),
                        shrunk.note().trim_start_matches("output pixels: ")
                    )
                }
            };
        }
        match self.estimate {
            PixelEstimate::FitOnly => {
                "output pixels: the fit's box pixels only (no residual correction)".to_string()
            }
            PixelEstimate::Shrunk
            | PixelEstimate::BoxShrunk
            | PixelEstimate::Auto
            | PixelEstimate::Blend
            | PixelEstimate::BlendGated
            | PixelEstimate::BlendSure => {
                let what = if self.estimate == PixelEstimate::Shrunk {
                    format!(
                        "the fit's box pixels plus the significant mean residual ({} of {} \
                         sampled pixels), clamped to the local sample range ({} pixels)",
                        self.corrected, self.sampled, self.clamped
                    )
                } else {
                    "the box pixels (the mean of each pixel's samples; the clamped corrected \
                     pixel where none)"
                        .to_string()
                };
                match (&self.shrink_sigma, &self.shrink_threshold) {
                    (Some(sigma), Some(t)) => format!(
                        "output pixels: {what}, shrunk (soft, orthonormal Haar, 16 shifts) at \
                         the universal threshold {} for the noise level {} per channel (median \
                         variance of a pixel's mean)",
                        fmt_list(t),
                        fmt_list(sigma)
                    ),
                    _ => format!(
                        "output pixels: {what}, not shrunk: no pixel holds two samples, so the \
                         samples give no noise level"
                    ),
                }
            }
            PixelEstimate::ResidualCorrected | PixelEstimate::ResidualClamped => {
                let mut s = format!(
                    "output pixels: the fit's box pixels plus the mean residual in {} of {} \
                     sampled pixels (significant at {} standard errors of noise sigma {:.3e}; \
                     largest correction {:.3e})",
                    self.corrected, self.sampled, self.z, self.sigma, self.largest
                );
                if self.estimate == PixelEstimate::ResidualClamped {
                    s += &format!(
                        "; {} pixels clamped to the range of the samples in their 3x3 \
                         neighbourhood (largest move {:.3e})",
                        self.clamped, self.largest_clamp
                    );
                }
                s
            }
        }
    }
}

/// Adds to `pixels` (per channel, `W H` row-major on `plane`) the mean of `residuals` (per
/// channel, one per sample at `(xs[i], ys[i])`, pixel units) of each pixel where it is
/// significant, `|m_P|_2 > z sigma sqrt(ch / n_P)`. Returns the pixels holding a sample, the
/// pixels corrected and the largest correction `|m_P|_2` applied.
///
/// A sample on the right or bottom border (`x = W`) belongs to the last pixel.
pub fn add_significant_mean_residual(
    pixels: &mut [Vec<f64>],
    plane: ImagePlane,
    xs: &[f64],
    ys: &[f64],
    residuals: &[Vec<f64>],
    sigma: f64,
    z: f64,
) -> (usize, usize, f64) {
    let (w, h) = (plane.width(), plane.height());
    let ch = residuals.len();
    let mut sum = vec![0.0; w * h * ch];
    let mut count = vec![0usize; w * h];
    for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
        let (px, py) = plane.pixel_of(x, y);
        let p = py * w + px;
        count[p] += 1;
        for (c, rc) in residuals.iter().enumerate() {
            sum[p * ch + c] += rc[i];
        }
    }
    let (mut sampled, mut corrected, mut largest) = (0, 0, 0.0f64);
    for (p, &n) in count.iter().enumerate() {
        if n == 0 {
            continue;
        }
        sampled += 1;
        let mean: Vec<f64> = (0..ch).map(|c| sum[p * ch + c] / n as f64).collect();
        let norm = mean.iter().map(|m| m * m).sum::<f64>().sqrt();
        if norm > z * sigma * (ch as f64 / n as f64).sqrt() {
            for (c, m) in mean.iter().enumerate() {
                pixels[c][p] += m;
            }
            corrected += 1;
            largest = largest.max(norm);
        }
    }
    (sampled, corrected, largest)
}

/// The output pixels of `fit` on `tree` for the samples `(xs, ys, values)`: with
/// [`PixelEstimate::ResidualCorrected`], the box pixels plus the significant mean residual
/// (`z` standard errors at noise `sigma`); with [`PixelEstimate::ResidualClamped`], those
/// clamped to the local range of the samples; with [`PixelEstimate::FitOnly`], the box
/// pixels.
/// Returns the fit's box pixels, the output pixels and what the correction did.
#[allow(clippy::too_many_arguments)]
pub fn output_pixels(
    tree: &QuadTree,
    fit: &TreeFit,
    xs: &[f64],
    ys: &[f64],
    values: &[Vec<f64>],
    estimate: PixelEstimate,
    sigma: f64,
    z: f64,
) -> Result<(PixelImage, PixelImage, ResidualCorrection), AdaptiveError> {
    output_pixels_and_shrink_divergence(tree, fit, xs, ys, values, estimate, sigma, z, false)
        .map(|(fit_image, image, report, _)| (fit_image, image, report))
}

/// The shrinkage's divergence per channel and pixel (`None` where nothing was shrunk).
type ShrinkDivergence = Option<Vec<Vec<f64>>>;

/// [`output_pixels`], and with `divergence` set (and a shrinking estimate that shrank), the
/// divergence of the Haar shrinkage in each pixel's own input
/// ([`shrink_channel_with_divergence`]).
#[allow(clippy::too_many_arguments)]
fn output_pixels_and_shrink_divergence(
    tree: &QuadTree,
    fit: &TreeFit,
    xs: &[f64],
    ys: &[f64],
    values: &[Vec<f64>],
    estimate: PixelEstimate,
    sigma: f64,
    z: f64,
    divergence: bool,
) -> Result<(PixelImage, PixelImage, ResidualCorrection, ShrinkDivergence), AdaptiveError> {
    let b = tree.basis();
    let plane = ImagePlane::new(b.width(), b.height()).expect("the basis has a valid size");
    let fit_image = PixelImage {
        plane,
        channels: fit.box_pixels(tree)?,
    };
    if matches!(
        estimate,
        PixelEstimate::Blend | PixelEstimate::BlendGated | PixelEstimate::BlendSure
    ) {
        return blend_shrunk_and_auto(tree, fit, xs, ys, values, sigma, z, estimate)
            .map(|(fit_image, image, report)| (fit_image, image, report, None));
    }
    let mut report = ResidualCorrection {
        estimate,
        z,
        sigma,
        ..ResidualCorrection::default()
    };
    if estimate == PixelEstimate::Auto {
        let chosen = ImageSamples::new(plane, xs.to_vec(), ys.to_vec(), values.to_vec())
            .map_err(|e| e.to_string())
            .and_then(|samples| auto::estimate(&samples, &ShrinkParams::default()));
        match chosen {
            Ok((image, auto)) => {
                report.auto_description = Some(auto.describe());
                report.films = Some(auto.films);
                report.shrink_sigma = Some(auto.sigma);
                report.clamped = auto.range_clamped;
                report.largest_clamp = auto.largest_clamp;
                return Ok((fit_image, image, report, None));
            }
            Err(reason) => report.auto_fallback = Some(reason),
        }
    }
    let mut image = fit_image.clone();
    if estimate != PixelEstimate::FitOnly {
        let coef: Vec<&[f64]> = fit.coefficients.iter().map(|c| c.as_slice()).collect();
        let vals: Vec<&[f64]> = values.iter().map(|v| v.as_slice()).collect();
        let r = residuals(tree, &coef, xs, ys, &vals);
        let (sampled, corrected, largest) =
            add_significant_mean_residual(&mut image.channels, plane, xs, ys, &r, sigma, z);
        report.sampled = sampled;
        report.corrected = corrected;
        report.largest = largest;
    }
    if matches!(
        estimate,
        PixelEstimate::ResidualClamped
            | PixelEstimate::Shrunk
            | PixelEstimate::BoxShrunk
            | PixelEstimate::Auto
    ) {
        let (clamped, largest) = clamp_to_local_range(&mut image.channels, plane, xs, ys, values);
        report.clamped = clamped;
        report.largest_clamp = largest;
    }
    let mut shrink_divergence = None;
    if estimate.shrinks() {
        let stats = PixelStatistics::of(plane, xs, ys, values);
        if estimate == PixelEstimate::BoxShrunk {
            for (channel, mean) in image.channels.iter_mut().zip(&stats.mean) {
                for ((v, &m), &n) in channel.iter_mut().zip(mean).zip(&stats.count) {
                    if n > 0 {
                        *v = m;
                    }
                }
            }
        }
        if let Some(sigma) = stats.noise_level() {
            let shrink = ShrinkParams::default();
            let t: Vec<f64> = sigma
                .iter()
                .map(|&s| universal_threshold(s, plane.pixels(), shrink.threshold_factor))
                .collect();
            let mut div = vec![];
            for (channel, &tc) in image.channels.iter_mut().zip(&t) {
                if divergence {
                    let (shrunk, d) = shrink_channel_with_divergence(
                        channel,
                        plane.width(),
                        plane.height(),
                        tc,
                        shrink.shifts,
                    );
                    *channel = shrunk;
                    div.push(d);
                } else {
                    *channel =
                        shrink_channel(channel, plane.width(), plane.height(), tc, shrink.shifts);
                }
            }
            if divergence {
                shrink_divergence = Some(div);
            }
            report.shrink_sigma = Some(sigma);
            report.shrink_threshold = Some(t);
        }
    }
    Ok((fit_image, image, report, shrink_divergence))
}

/// The bound `d_pre` on the divergence of the corrected, clamped pixel in its own pixel's mean
/// (before the shrinkage), taken for it in the blend's risk of `shrunk`
/// ([`PixelEstimate::Blend`]; module docs, *Blend*: `d_S = d_pre d_H`, `d_H` the shrinkage's
/// exact divergence). The box pixels as a third candidate of the blend (risk `v_P`) and
/// `d_S = 0` were measured and not kept: docs/measurements/plan-quality-history.md.
pub const SHRUNK_DIVERGENCE_BOUND: f64 = 1.0;

/// [`PixelEstimate::Blend`]: the `shrunk` pixels `S_P` and the `auto` pixels `A_P` of the
/// same samples combined per pixel with inverse-risk weights ([`blend_by_risks`]), each risk
/// the SURE against the box pixels `m_P` (the mean of the pixel's own samples), relative (per
/// channel weighted by `omega_{P,c} = 1 / (A_{P,c}² + eps)`, `eps` = [`auto::RELATIVE_EPS`],
/// the scale of `auto`'s own risk) and averaged over the `(2 h + 1)²` window of the gate
/// ([`GATE_HALF`]):
///
/// - `auto`: its gate's window risk ([`auto::AutoReport::window_risk`]);
/// - `shrunk`: `sum_c omega ((S - m)² - v + 2 v d_S)`, `v_P` the noise of the pixel's mean
///   `auto` used ([`auto::AutoReport::pixel_variance`]), `d_S = d_pre d_H` with `d_pre` =
///   [`SHRUNK_DIVERGENCE_BOUND`] and `d_H` the shrinkage's exact divergence (module docs,
///   *Blend*).
///
/// Then the range projection onto the samples of the 3x3 neighbourhood. Where `auto` is not
/// permitted the output is `shrunk`'s, with the reason in
/// [`ResidualCorrection::auto_fallback`].
#[allow(clippy::too_many_arguments)]
fn blend_shrunk_and_auto(
    tree: &QuadTree,
    fit: &TreeFit,
    xs: &[f64],
    ys: &[f64],
    values: &[Vec<f64>],
    sigma: f64,
    z: f64,
    estimate: PixelEstimate,
) -> Result<(PixelImage, PixelImage, ResidualCorrection), AdaptiveError> {
    let (fit_image, shrunk, mut report, shrink_divergence) = output_pixels_and_shrink_divergence(
        tree,
        fit,
        xs,
        ys,
        values,
        PixelEstimate::Shrunk,
        sigma,
        z,
        true,
    )?;
    report.estimate = estimate;
    let plane = shrunk.plane;
    let samples = match ImageSamples::new(plane, xs.to_vec(), ys.to_vec(), values.to_vec()) {
        Ok(s) => s,
        Err(e) => {
            report.auto_fallback = Some(e.to_string());
            return Ok((fit_image, shrunk, report));
        }
    };
    let (auto_image, auto_report) = match auto::estimate(&samples, &ShrinkParams::default()) {
        Ok(chosen) => chosen,
        Err(reason) => {
            report.auto_fallback = Some(reason);
            return Ok((fit_image, shrunk, report));
        }
    };
    // `auto` succeeded, so every pixel holds a sample and the noise of the means is known
    // (`auto`'s own `v_P`, the one its gate's risks used)
    let stats = PixelStatistics::new(&samples);
    let (w, h) = (plane.width(), plane.height());
    let pixels = plane.pixels();
    let mut shrunk_sure = vec![0.0; pixels];
    let mut divergence_sum = 0.0;
    for (c, (s_c, a_c)) in shrunk.channels.iter().zip(&auto_image.channels).enumerate() {
        for p in 0..pixels {
            let omega = 1.0 / (a_c[p] * a_c[p] + auto::RELATIVE_EPS);
            let v = auto_report.pixel_variance[c][p];
            let d = s_c[p] - stats.mean[c][p];
            // d_S = d_pre d_H: the correction's bound times the shrinkage's exact divergence
            // (1 where nothing was shrunk)
            let ds = SHRUNK_DIVERGENCE_BOUND * shrink_divergence.as_ref().map_or(1.0, |d| d[c][p]);
            divergence_sum += ds;
            shrunk_sure[p] += omega * (d * d - v + 2.0 * v * ds);
        }
    }
    let risk_shrunk = window_mean(&shrunk_sure, w, h, GATE_HALF);
    let (mut blended, mut weights) = blend_by_risks(
        &[&shrunk, &auto_image],
        &[&risk_shrunk, &auto_report.window_risk],
    );
    if estimate == PixelEstimate::BlendSure {
        let (image, w_shrunk, sure) =
            blend_by_sure(&shrunk, &auto_image, &risk_shrunk, &auto_report.window_risk);
        blended = image;
        let w_auto = w_shrunk.iter().map(|w| 1.0 - w).collect();
        weights = vec![w_shrunk, w_auto];
        report.sure_blend = Some(sure);
    }
    let mut image = if estimate != PixelEstimate::BlendGated {
        blended
    } else {
        match final_gate::gate_against_box(
            &samples,
            &stats.mean,
            (&auto_image, &auto_report.pixel_variance),
            &blended,
            &weights,
            |c, p| SHRUNK_DIVERGENCE_BOUND * shrink_divergence.as_ref().map_or(1.0, |d| d[c][p]),
        ) {
            Ok((image, gate)) => {
                report.final_gate = Some(gate);
                image
            }
            Err(reason) => {
                report.final_gate_fallback = Some(reason);
                blended
            }
        }
    };
    let (moved, _) = clamp_to_local_range(&mut image.channels, plane, xs, ys, values);
    report.blend_clamped = Some(moved);
    report.auto_description = Some(auto_report.describe());
    report.films = Some(auto_report.films);
    report.blend_weight = Some(mean_weight(&weights, 0, pixels));
    report.blend_weight_auto = Some(mean_weight(&weights, 1, pixels));
    report.blend_shrunk_divergence =
        Some(divergence_sum / (pixels * shrunk.channels.len()).max(1) as f64);
    report.blend_unknown_risk = Some(unknown_risk(&risk_shrunk, &auto_report.window_risk));
    Ok((fit_image, image, report))
}

/// The mean over pixels of the weights of estimate `k` (0 if there is none).
fn mean_weight(weights: &[Vec<f64>], k: usize, pixels: usize) -> f64 {
    weights
        .get(k)
        .map_or(0.0, |x| x.iter().sum::<f64>() / pixels.max(1) as f64)
}

/// Pixels where either risk is not a number.
fn unknown_risk(a: &[f64], b: &[f64]) -> usize {
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.is_nan() || y.is_nan())
        .count()
}

/// Values in short scientific notation, comma-separated.
fn fmt_list(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x:.3e}"))
        .collect::<Vec<_>>()
        .join(", ")
}
