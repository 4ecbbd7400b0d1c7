//! The plan's `blend_sure` output pixels: `shrunk` and `auto` combined per pixel by the
//! weight of least SURE of the combination itself ([`crate::image::estimate::sure_blend`]),
//! capped by `blend`'s inverse-risk weight (`src/image/adaptive/correction.rs`, module docs,
//! *Blend* and *SURE blend*).
//!
//! With `R^S_P` and `R^A_P` the risks `blend` weighs (`shrunk`'s and `auto`'s relative SURE
//! against the box pixels, window-averaged: `correction.rs`, *Blend*) and
//! `Q_P = (1 / |W|) sum_W sum_c omega (S - A)²` over the `(2 h + 1)²` window around `P`
//! (`h` = [`SURE_BLEND_HALF`], `omega = 1 / (A² + eps)`, `eps` = [`auto::RELATIVE_EPS`]),
//! the combination `w S + (1 - w) A` has the estimated risk
//! `(1 - w) R^A + w R^S - w (1 - w) Q`, least at
//! `w^Q_P = min(max((R^A - R^S + Q) / (2 Q), 0), 1)`: the inverse-risk weight
//! `w^I_P = R^A / (R^S + R^A)` where the two errors are uncorrelated (`E Q = R^S + R^A`), less
//! weight on the worse input where they correlate. The weight of `shrunk` is
//! `w_P = min(w^Q_P, w^I_P)`: the SURE weight only ever takes weight from `shrunk`, never
//! adds to it (measured: the uncapped weight, and the exact SURE with `auto`'s divergence by
//! a random probe instead of the two risks, lose more against `blend` on the tuning half's
//! noisy rows, where a small `Q` makes `w^Q` follow the noise of `R^A - R^S`:
//! docs/measurements/plan-quality.md, "The blend weighted by the SURE of the combination").
//! Each pixel lies between its two inputs.

use serde::Serialize;

use crate::image::estimate::auto;
use crate::image::estimate::blend::combine;
use crate::image::estimate::blend::inverse_risk_weight;
use crate::image::estimate::sure::window_mean;
use crate::image::estimate::sure_blend::{combination_risk, weights_from_risks};
use crate::image::PixelImage;

/// The half side `h` of the `(2 h + 1)²` window of `Q` (chosen on the tuning half, seed 1,
/// among 2, 4 and 8: docs/measurements/plan-quality.md, "The blend weighted by the SURE of
/// the combination").
pub const SURE_BLEND_HALF: usize = 2;

/// What the SURE blend did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SureBlend {
    /// The side of `Q`'s window, `2 h + 1`.
    pub window: usize,
    /// Pixels whose SURE weight took weight from `shrunk` (`w^Q < w^I`).
    pub capped: usize,
    /// Pixels that took `auto` alone (`w = 0`).
    pub auto_only: usize,
    /// Pixels whose window saw `shrunk` and `auto` equal (`Q = 0`).
    pub flat: usize,
    /// Pixels whose risks or `Q` were not finite (`auto` taken).
    pub not_finite: usize,
    /// Mean over pixels of the estimated risk at the chosen weights (relative, a pixel).
    pub risk: f64,
    /// The same at `blend`'s inverse-risk weights.
    pub risk_inverse: f64,
    /// The mean over pixels of `Q`.
    pub q: f64,
}

impl SureBlend {
    /// The SURE blend in words.
    pub fn describe(&self) -> String {
        format!(
            "weights of least SURE of the combination (Q over the {side} x {side} window), \
             capped by the inverse-risk weights: {} pixels took weight from shrunk, {} auto \
             alone{}{}; estimated relative risk a pixel {:.3e} against {:.3e} at the \
             inverse-risk weights (mean Q {:.3e})",
            self.capped,
            self.auto_only,
            if self.flat > 0 {
                format!(", {} with shrunk = auto on the window", self.flat)
            } else {
                String::new()
            },
            if self.not_finite > 0 {
                format!(
                    ", {} with a risk that is not a number (auto taken)",
                    self.not_finite
                )
            } else {
                String::new()
            },
            self.risk,
            self.risk_inverse,
            self.q,
            side = self.window,
        )
    }
}

/// The SURE blend of `shrunk` and `auto` with their window risks `risk_shrunk`, `risk_auto`
/// per pixel (module docs). Returns the image, the weight of `shrunk` per pixel and the
/// report.
///
/// Panics if the images differ in plane or channels or a risk list is not one a pixel.
pub fn blend_by_sure(
    shrunk: &PixelImage,
    auto_image: &PixelImage,
    risk_shrunk: &[f64],
    risk_auto: &[f64],
) -> (PixelImage, Vec<f64>, SureBlend) {
    let plane = auto_image.plane;
    let (w, h) = (plane.width(), plane.height());
    let pixels = plane.pixels();
    let mut q = vec![0.0; pixels];
    for (s_c, a_c) in shrunk.channels.iter().zip(&auto_image.channels) {
        for p in 0..pixels {
            let omega = 1.0 / (a_c[p] * a_c[p] + auto::RELATIVE_EPS);
            q[p] += omega * (s_c[p] - a_c[p]).powi(2);
        }
    }
    let q = window_mean(&q, w, h, SURE_BLEND_HALF);
    let sure = weights_from_risks(risk_shrunk, risk_auto, &q);
    let mut report = SureBlend {
        window: 2 * SURE_BLEND_HALF + 1,
        capped: 0,
        auto_only: 0,
        flat: sure.flat,
        not_finite: sure.not_finite,
        risk: 0.0,
        risk_inverse: 0.0,
        q: 0.0,
    };
    let mut weight = sure.weight;
    let mut counted = 0usize;
    for (p, wp) in weight.iter_mut().enumerate() {
        let inverse = inverse_risk_weight(risk_shrunk[p], risk_auto[p]);
        if *wp < inverse {
            report.capped += 1;
        }
        *wp = wp.min(inverse);
        if *wp == 0.0 {
            report.auto_only += 1;
        }
        let (rs, ra) = (risk_shrunk[p], risk_auto[p]);
        if rs.is_finite() && ra.is_finite() && q[p].is_finite() {
            report.risk += combination_risk(*wp, rs, ra, q[p]);
            report.risk_inverse += combination_risk(inverse, rs, ra, q[p]);
            report.q += q[p];
            counted += 1;
        }
    }
    let n = counted.max(1) as f64;
    report.risk /= n;
    report.risk_inverse /= n;
    report.q /= n;
    (combine(shrunk, auto_image, &weight), weight, report)
}
