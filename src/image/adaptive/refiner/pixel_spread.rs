//! The hybrid of the tree and the pixels ([`super::GrowthParams::pixel_share`], issue 38):
//! a share of each round's new samples goes to the *pixels* by the spread of their own
//! samples, beside the tree's marking.
//!
//! Where the tree cannot follow the signal (texture past the depth limit, thin geometry,
//! noise) the final image is close to the mean of each pixel's samples, whose squared error
//! is about `s_P^2 / n_P` (`s_P^2` the variance of one sample of pixel `P`). Minimising
//! `sum_P s_P^2 / n_P` for a given `sum_P n_P` gives Neyman's allocation `n_P = lambda s_P`
//! (Lagrange: `s_P^2 / n_P^2 = mu`). A round's pixel share is water-filled towards it over
//! the counts the pixels already hold (`crate::adaptive::marking::spread`: each pixel is
//! raised to `max(n_P, lambda s_P)` with `lambda` chosen so the added samples are exactly
//! the share).
//!
//! The spread `s_P` is of the pixel's samples with every channel clipped to `[0, 1]` (what a
//! display shows; one firefly does not draw the whole share), the channels' unbiased
//! variances summed, and pooled over the pixel's 3 x 3 neighbourhood (clipped at the
//! plane's edges): `s_P^2 = sum_Q M2_Q / sum_Q (n_Q - 1)`, `M2_Q` the sum of squared
//! deviations from the mean of pixel `Q`'s samples. At two samples a pixel one pixel's
//! spread has one degree of freedom, and a pixel whose two samples happen to agree would
//! get nothing; pooled over nine pixels it has nine (docs/measurements/plan-quality.md, the
//! prototype of the sixteenth session: without pooling grid 4 lost 5.7 dB).
//!
//! When: only at a budget of at most [`SHARE_MAX_SPP`] samples a pixel. There the floor's
//! two samples a pixel are what the texture rows lose on, and the share lifted them without
//! a loss on the tuning half at two seeds; at 8 and 16 samples a pixel it lost 1-5 dB on
//! glossy, caustic and thin-geometry scenes (the tree's fit is the gain there), and a share
//! only to pixels whose detail the noise test found significant lost `fog` 8 and `rough` 8
//! instead (docs/measurements/plan-quality.md, "When the share may apply"). Above it the
//! round is the tree's alone, sample for sample, and a note says so.
//!
//! Why it is still opt-in (docs/measurements/plan-quality.md, "The texture rows' allocation"):
//! on texture past the depth limit the tree's counts are no better than uniform counts for
//! the pixel integrals (in the model `sum_P s_P^2 / n_P`, within about 1 dB of uniform where
//! Neyman's is 2-4 dB ahead), and the share lifts every texture row at 4 samples a pixel
//! above the best film + 1 dB; but since the final image's gate (the eighteenth session) it
//! costs `cornell` 4 1.9 dB (0.25: 1.6), and a share only to pixels whose mean the fit
//! misses, or only to pixels under no slot the tree can deepen, lost more.
//!
//! Placement: the share goes only where the base slots are the pixels (the uniform floor's
//! condition, module `coverage`). A pixel that is still a slot takes the next points of its
//! own (0, 2)-sequence (as the floor's top-up does), so its samples stay a prefix of that
//! sequence; a pixel the tree deepened spreads its share over its slots by their area (each
//! slot continuing its own points, `super::positions::slot_points`). Slots the round
//! deepens are topped up by the tree and take none. When every pixel's spread is 0 (a
//! noise-free flat image) the share goes back to the tree's spare samples.

use std::collections::HashMap;

use super::positions::{spread_samples, Placer};
use super::{ImagePlan, SamplePositions};
use crate::adaptive::marking::spread;
use crate::adaptive::{Cell, QuadTree};
use crate::image::ImagePlane;

/// The largest budget (samples a pixel) at which the pixel share applies; above it the
/// tree alone places the samples. Chosen on the issue-38 suite's tuning half against the share
/// at every budget and against a share only to pixels with significant detail above it
/// (docs/measurements/plan-quality.md, "When the share may apply").
pub const SHARE_MAX_SPP: f64 = 4.0;

impl ImagePlan {
    /// Whether the pixel share is on: a share above 0, base slots that are the pixels and a
    /// budget of at most [`SHARE_MAX_SPP`] samples a pixel.
    pub(super) fn pixel_share_on(&self) -> bool {
        self.params.growth.pixel_share > 0.0
            && self.base_slots_are_pixels()
            && self.budget_takes_share()
    }

    /// Whether the budget is at most [`SHARE_MAX_SPP`] samples a pixel (the share's budgets).
    pub(super) fn budget_takes_share(&self) -> bool {
        self.params.stop.budget as f64 <= SHARE_MAX_SPP * self.plane.pixels() as f64
    }

    /// [`SHARE_MAX_SPP`]: the largest budget, in samples a pixel, that takes the share.
    pub(super) fn share_max_spp(&self) -> f64 {
        SHARE_MAX_SPP
    }

    /// Whether the base slots are the pixels (the pixel share's condition).
    pub(super) fn base_slots_are_pixels(&self) -> bool {
        self.tree.cell_dims(self.base_steps) == (self.plane.width(), self.plane.height())
    }
}

/// The pooled spread `s_P` of every pixel (row-major; module docs) and the samples each
/// pixel holds, from the samples `(xs, ys)` with channels `values`.
pub(super) fn pooled_spread(
    plane: ImagePlane,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> (Vec<f64>, Vec<usize>) {
    let (w, h) = (plane.width(), plane.height());
    let ch = values.len();
    let mut n = vec![0usize; w * h];
    let mut mean = vec![0.0f64; w * h * ch];
    let mut m2 = vec![0.0f64; w * h];
    for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
        let (px, py) = plane.pixel_of(x, y);
        let p = py * w + px;
        n[p] += 1;
        for (c, v) in values.iter().enumerate() {
            let v = v[i].clamp(0.0, 1.0);
            let m = &mut mean[p * ch + c];
            let d = v - *m;
            *m += d / n[p] as f64;
            m2[p] += d * (v - *m);
        }
    }
    let mut s = vec![0.0; w * h];
    for py in 0..h {
        for px in 0..w {
            let (mut num, mut dof) = (0.0, 0usize);
            for qy in py.saturating_sub(1)..(py + 2).min(h) {
                for qx in px.saturating_sub(1)..(px + 2).min(w) {
                    let q = qy * w + qx;
                    num += m2[q];
                    dof += n[q].saturating_sub(1);
                }
            }
            if dof > 0 {
                s[py * w + px] = (num.max(0.0) / dof as f64).sqrt();
            }
        }
    }
    (s, n)
}

/// Spreads `extra` samples over the pixels by `spread_of` (the pooled spreads `s_P`) above
/// `pixel_counts` (module docs), placed in the slots `stay` (the slots the round does not
/// deepen, with their `counts`) of `tree` by `placer`. Pixels without a slot in `stay` take
/// none. Returns the samples added: `extra`, or 0 when no pixel with a slot has a spread.
#[allow(clippy::too_many_arguments)]
pub(super) fn spread_over_pixels(
    plane: ImagePlane,
    tree: &QuadTree,
    stay: &[Cell],
    counts: &HashMap<Cell, usize>,
    spread_of: &[f64],
    pixel_counts: &[usize],
    extra: usize,
    next: &mut SamplePositions,
    placer: &mut Placer,
) -> usize {
    let w = plane.width();
    let mut slots_of: HashMap<usize, Vec<Cell>> = HashMap::new();
    for &s in stay {
        let r = tree.rect(s);
        let (px, py) = plane.pixel_of(0.5 * (r[0] + r[1]), 0.5 * (r[2] + r[3]));
        slots_of.entry(py * w + px).or_default().push(s);
    }
    let weights: Vec<f64> = (0..spread_of.len())
        .map(|p| {
            if slots_of.contains_key(&p) {
                spread_of[p]
            } else {
                0.0
            }
        })
        .collect();
    if extra == 0 || !weights.iter().any(|&v| v > 0.0) {
        return 0;
    }
    let add = spread(&weights, pixel_counts, extra);
    let mut added = 0;
    for (p, &a) in add.iter().enumerate() {
        if a == 0 {
            continue;
        }
        let Some(slots) = slots_of.get(&p) else {
            continue;
        };
        // by area over the pixel's slots (one slot: the pixel itself, its own sequence)
        let area: Vec<f64> = slots
            .iter()
            .map(|s| {
                let r = tree.rect(*s);
                (r[1] - r[0]) * (r[3] - r[2])
            })
            .collect();
        let (n, _) = spread_samples(tree, slots, counts, &area, a, next, placer);
        added += n;
    }
    added
}
