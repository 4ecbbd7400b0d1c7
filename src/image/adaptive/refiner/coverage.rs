//! Every pixel a sample at low budgets (issue 38): the plan's coverage rule.
//!
//! A pixel without a sample has no estimate of its own: its output is the fit's value; and
//! the estimators that compare each pixel with the mean of its own samples (`auto` inside
//! `blend`) need two samples in a pixel to see its noise, and fall back to `shrunk` (whose
//! Haar shrinkage is not range-bound) when fewer than half the pixels have two. At a budget
//! `N >= W H` and `ImageSampling::cover_pixels`, the plan gives every pixel at least
//! `m = min(ceil(rho), floor(N / (W H)))` samples (one between 1 and 2 samples a pixel, two
//! from 2 on with the default `rho = 2`):
//!
//! * *Up front* (`ImagePlan::new`): from `ceil(rho)` samples a pixel on, where the
//!   budget pays for base slots no larger than a pixel (sides that are powers of two, or
//!   large enough), the base tree is raised to them, so every pixel holds `ceil(rho)` base
//!   samples before the tree adapts. Elsewhere:
//! * *Reserve.* Every round, with `n` samples so far and `n_P` of them in pixel `P`, the
//!   marking and spreading of the round may spend at most `N - n - R`, `R = sum_P max(0, m -
//!   n_P)`: the samples that top every pixel up to `m` are held back. A sample in a pixel
//!   below `m` lowers `R` by one, any other is paid from what the round may spend, so
//!   `n + R` never rises above the base's `n_0 + R_0` and the reserve is there when needed.
//! * *Fill.* The round that would stop (budget spent, depth limit, tolerance, round limit)
//!   instead tops every pixel below `m` up to `m` (jittered strata of the pixel from the
//!   round's PCG-64 stream), marks nothing, and the next round fits on them and stops.
//! * *Base.* The automatic base level is lowered, if need be, until `n_0 + R_0 <= N` (at
//!   least one base step; a base level the user gives is kept, and if it leaves no room the
//!   plan says how many samples are missing).
//!
//! Topping up after the rounds is cheaper than the base up front, but on the suite's 4 spp it
//! is behind it (adapting on a sparse base, the rounds decide on noisier fits and leave an
//! uneven density): docs/measurements/plan-quality.md. So the base goes up front wherever the
//! budget holds it, and the reserve and fill cover only what it cannot.

use rand_pcg::Pcg64;

use super::pixel_counts::pixel_shortfall;
use super::positions::round_rng;
use super::{ImagePlan, SamplePositions};
use crate::image::ImagePlane;

/// `need` positions in each pixel of `short` (`(pixel, need)`): jittered strata of the pixel
/// from `rng`'s stream, each moved to the pixel's centre if rounding carries it over the
/// pixel's edge (so that [`ImagePlane::pixel_of`] puts it in the pixel).
fn top_up(plane: ImagePlane, short: &[(usize, usize)], rng: &mut Pcg64) -> SamplePositions {
    let w = plane.width();
    let mut out = SamplePositions::default();
    for &(p, need) in short {
        let (px, py) = (p % w, p / w);
        let (x0, y0) = (px as f64, py as f64);
        let from = out.len();
        out.stratified([x0, x0 + 1.0, y0, y0 + 1.0], need, rng);
        for i in from..out.len() {
            if plane.pixel_of(out.xs[i], out.ys[i]) != (px, py) {
                (out.xs[i], out.ys[i]) = (x0 + 0.5, y0 + 0.5);
            }
        }
    }
    out
}

impl ImagePlan {
    /// The samples every pixel holds under the coverage rule, `m = min(ceil(rho), floor(N / (W
    /// H)))` (0: the rule is off, by `ImageSampling::cover_pixels` or a budget below
    /// one sample a pixel).
    pub fn per_pixel(&self) -> usize {
        if self.params.sampling.cover_pixels {
            self.per_slot
                .min(self.params.stop.budget / self.plane.pixels())
        } else {
            0
        }
    }

    /// The pixels short of [`ImagePlan::per_pixel`] samples so far and what each lacks.
    pub(super) fn shortfall(&self, xs: &[f64], ys: &[f64]) -> Vec<(usize, usize)> {
        match self.per_pixel() {
            0 => Vec::new(),
            m => pixel_shortfall(self.plane, xs, ys, m),
        }
    }

    /// The fill round (module docs): the pixels of `short` topped up, as far as the budget
    /// leaves after `samples` (in pixel order), recorded as a round that marks nothing. `None`
    /// when there is nothing to fill or no sample left; the note says what was done or why not.
    pub(super) fn fill(
        &mut self,
        round: usize,
        samples: usize,
        short: &[(usize, usize)],
    ) -> (Option<SamplePositions>, Option<String>) {
        let missing: usize = short.iter().map(|s| s.1).sum();
        if missing == 0 {
            return (None, None);
        }
        let left = self.params.stop.budget.saturating_sub(samples);
        let mut paid = Vec::new();
        let mut spent = 0;
        for &(p, need) in short {
            let n = need.min(left - spent);
            if n == 0 {
                break;
            }
            paid.push((p, n));
            spent += n;
        }
        let m = self.per_pixel();
        let lacking = (spent < missing).then(|| {
            format!(
                "{} samples are missing for {m} in every pixel: the budget of {} has {left} left \
                 after {samples} samples (raise the budget by {}, or lower the base level)",
                missing - spent,
                self.params.stop.budget,
                missing - spent
            )
        });
        if spent == 0 {
            return (None, lacking);
        }
        // a partial fill: the next round, with nothing left, says what is missing
        let mut rng = round_rng(self.params.sampling.seed, round + 1);
        let next = top_up(self.plane, &paid, &mut rng);
        self.progress.marked.push(Vec::new());
        self.progress.samples_fitted = samples;
        let note = format!(
            "coverage: round {round} topped {} pixels up to {m} samples each ({spent} samples, \
             held back from the rounds before; cover_pixels = false leaves them to the tree)",
            paid.len()
        );
        (Some(next), Some(note))
    }
}
