//! The final gate of the plan's `blend_gated` output pixels: per pixel the least
//! estimated risk of the box pixels, `auto` and the blend of `shrunk` and `auto`
//! (`src/image/adaptive/correction.rs`, module docs, *No harm*).
//!
//! Each candidate's relative SURE against the box pixels `m_P` with `auto`'s noise `v_P`,
//! `sum_c omega ((x - m)² - v + 2 v d)` with `omega = 1 / (A² + eps)` (`A` the `auto`
//! pixels, `eps` = [`auto::RELATIVE_EPS`]), summed over the gate's `(2 h + 1)²` window at the
//! pixel's level (levels `L_P = (1/C) sum_c |A_{P,c}|`), decides
//! ([`crate::image::estimate::gate::gate`]; ties to the box). The divergences: the box 1,
//! `auto`'s `d_A` by one random probe of its own samples
//! ([`crate::image::estimate::divergence`]), the blend's `w_P d_S + (1 - w_P) d_A` with
//! `d_S` `shrunk`'s (the caller's: the correction's bound times the shrinkage's exact
//! divergence) (the weights' dependence on the data, through window sums, neglected).

use serde::Serialize;

use crate::image::estimate::auto;
use crate::image::estimate::divergence::probe_divergence;
use crate::image::estimate::gate::{gate, GateCandidate, GateCount, GATE_HALF};
use crate::image::estimate::ShrinkParams;
use crate::image::{ImageSamples, PixelImage};

/// The seed of the signs of the probe of `auto`'s divergence (fixed, so the final image is a
/// function of the samples).
pub const PROBE_SEED: u64 = 0x7e47_4a52;

/// What the final gate did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FinalGate {
    /// Pixels per candidate (box, auto, blend).
    pub counts: Vec<GateCount>,
    /// The mean over pixels of the chosen candidate's SURE summed over channels (absolute).
    pub risk: f64,
    /// The mean over pixels of the box pixels' `sum_c v_{P,c}`.
    pub box_risk: f64,
    /// Pixel-channels whose probe of `auto`'s divergence was a jump (clamped).
    pub jumps: usize,
}

impl FinalGate {
    /// The gate in words.
    pub fn describe(&self) -> String {
        format!(
            "final gate against the box pixels (per pixel the least relative SURE over the \
             {side} x {side} window at its level; auto's divergence by a probe, {} jumps \
             clamped): {}; estimated risk a pixel {:.3e} against the box's {:.3e}",
            self.jumps,
            self.counts
                .iter()
                .map(|c| format!("{} {}", c.candidate, c.pixels))
                .collect::<Vec<_>>()
                .join(", "),
            self.risk,
            self.box_risk,
            side = 2 * GATE_HALF + 1,
        )
    }
}

/// The gated pixels of the box `mean`, `auto` = (its pixels, its `v_P` per channel and pixel)
/// and `blended` (weights `weights[0]` of `shrunk`, `weights[1]` of `auto`; `shrunk_divergence`
/// its input's `d_S` of channel `c`, pixel `P`), before the range projection; the error
/// is the probe's (`auto` failing on the shifted samples).
pub fn gate_against_box(
    samples: &ImageSamples,
    mean: &[Vec<f64>],
    auto: (&PixelImage, &[Vec<f64>]),
    blended: &PixelImage,
    weights: &[Vec<f64>],
    shrunk_divergence: impl Fn(usize, usize) -> f64,
) -> Result<(PixelImage, FinalGate), String> {
    let (auto_image, variance) = auto;
    let plane = auto_image.plane;
    let pixels = plane.pixels();
    let channels = auto_image.channels.len();
    let probe = probe_divergence(
        samples,
        auto_image,
        |s| auto::estimate(s, &ShrinkParams::default()).map(|(image, _)| image),
        PROBE_SEED,
    )?;
    let blend_divergence: Vec<Vec<f64>> = (0..channels)
        .map(|c| {
            (0..pixels)
                .map(|p| {
                    let ds = shrunk_divergence(c, p);
                    weights[0][p] * ds + weights[1][p] * probe.divergence[c][p]
                })
                .collect()
        })
        .collect();
    let candidates = [
        GateCandidate {
            name: "box".into(),
            image: PixelImage {
                plane,
                channels: mean.to_vec(),
            },
            divergence: vec![vec![1.0; pixels]; channels],
        },
        GateCandidate {
            name: "auto".into(),
            image: auto_image.clone(),
            divergence: probe.divergence,
        },
        GateCandidate {
            name: "blend".into(),
            image: blended.clone(),
            divergence: blend_divergence,
        },
    ];
    let omega: Vec<Vec<f64>> = auto_image
        .channels
        .iter()
        .map(|a| {
            a.iter()
                .map(|x| 1.0 / (x * x + auto::RELATIVE_EPS))
                .collect()
        })
        .collect();
    let level: Vec<f64> = (0..pixels)
        .map(|p| auto_image.channels.iter().map(|a| a[p].abs()).sum::<f64>() / channels as f64)
        .collect();
    let gated = gate(
        &candidates,
        mean,
        variance,
        Some(&omega),
        Some(&level),
        GATE_HALF,
    );
    Ok((
        gated.image,
        FinalGate {
            counts: gated.counts,
            risk: gated.risk,
            box_risk: gated.box_risk,
            jumps: probe.jumps,
        },
    ))
}
