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
//! * *Floor.* With `ImageSampling::pixel_floor = f > 0` and `m_f = floor(f N / (W H))` (at
//!   most `floor(N / (W H))`) above the coverage count, the floor goes in the *first* round:
//!   the base positions top every pixel up to `m_f`, drawn from the pixel's own (0, 2)-sequence
//!   where the pixel is a base slot (`super::top_up`: the pixel then holds the first `m_f` points of
//!   one sequence, a `(0, k, 2)`-net when `m_f = 2^k`), and `m = max(m, m_f)` is met from the
//!   start: nothing is held back, no round fills, and the rounds adapt with the rest, `N - m_f
//!   W H`. The tree's oversampling (the children's count, `ceil(rho)`) counts the slots
//!   deepened since the base only: a base slot's `m_f` samples are the floor's, not the
//!   tree's. Where the tree cannot follow the signal (texture past the depth limit, thin
//!   geometry, noise) the final image is close to the box mean of each pixel's samples, of
//!   error `sigma_P^2 / n_P`, and the floor bounds `n_P` from below. Only where the base
//!   slots are the pixels (the base then holds a prefix of each pixel's sequence); elsewhere
//!   (a tiled plan's windows, sides that are not powers of two) the floor is off and the
//!   notes say so. (Held back and filled at
//!   the end instead, the floor doubled the loop's rounds: a sample a round put in a pixel
//!   below the floor was paid from the reserve, so what a round could spend did not shrink
//!   and small rounds went on until the floor was met: docs/measurements/plan-quality-history.md.)
//!
//! Topping up after the rounds is cheaper than the base up front, but on the suite's 4 spp it
//! is behind it (adapting on a sparse base, the rounds decide on noisier fits and leave an
//! uneven density): docs/measurements/plan-quality-history.md. So the base goes up front
//! wherever the budget holds it, and the reserve and fill cover only what it cannot.

use super::pixel_counts::pixel_shortfall;
use super::positions::round_rng;
use super::top_up::top_up;
use super::{ImagePlan, SamplePositions};

impl ImagePlan {
    /// The samples every pixel holds at the end: the coverage rule's `min(ceil(rho), floor(N
    /// / (W H)))` (0: the rule is off, by `ImageSampling::cover_pixels` or a budget below one
    /// sample a pixel), raised to the uniform floor `floor(f N / (W H))`,
    /// `f = ImageSampling::pixel_floor` (module docs).
    pub fn per_pixel(&self) -> usize {
        let (budget, pixels) = (self.params.stop.budget, self.plane.pixels());
        let cover = if self.params.sampling.cover_pixels {
            self.per_slot.min(budget / pixels)
        } else {
            0
        };
        cover.max(self.floor)
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
        let next = top_up(self.plane, &self.tree, &self.params, &paid, m, &mut rng);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::adaptive::AdaptiveParams;
    use crate::image::ImagePlane;

    /// Whether `pts` (in the unit square, `2^k` of them) are a `(0, k, 2)`-net: for every
    /// split `2^a x 2^(k - a)` of the square into elementary intervals of area `2^-k`, one
    /// point in each. Exact counts.
    fn is_net(pts: &[(f64, f64)], k: u32) -> bool {
        (0..=k).all(|a| {
            let (nx, ny) = (1usize << a, 1usize << (k - a));
            let mut hit = vec![0usize; nx * ny];
            for &(u, v) in pts {
                let i = ((u * nx as f64) as usize).min(nx - 1);
                let j = ((v * ny as f64) as usize).min(ny - 1);
                hit[j * nx + i] += 1;
            }
            hit.iter().all(|&h| h == 1)
        })
    }

    /// The fill of the uniform floor continues each pixel's own (0, 2)-sequence: on a
    /// 32 x 32 plane at 16 samples a pixel with the floor at half of them (`m = 8`), the bare
    /// base (two samples in every pixel, slots the size of a pixel) topped up by `top_up` gives
    /// every pixel a `(0, 3, 2)`-net (one point in each of the 8 elementary intervals of all
    /// four shapes), and so does every power-of-two count from 2 to 32. Jittered strata
    /// chosen at random (the stratified pattern) or a wrong start index in the sequence fail
    /// this in most pixels.
    #[test]
    fn the_floor_fill_makes_every_untouched_pixel_a_net() {
        let plane = ImagePlane::new(32, 32).unwrap();
        let mut params = AdaptiveParams::default();
        params.stop.budget = 16 * plane.pixels();
        for m in [2usize, 4, 8, 16, 32] {
            params.sampling.pixel_floor = (m as f64 / 16.0).min(1.0);
            params.stop.budget = (16 * plane.pixels()).max(m * plane.pixels());
            let plan = ImagePlan::new(plane, &params).unwrap();
            assert_eq!(plan.per_pixel(), m.max(2));
            // the base without the floor (the plan's own base holds it already)
            let mut bare = params;
            bare.sampling.pixel_floor = 0.0;
            let base = ImagePlan::new(plane, &bare).unwrap().base_positions();
            assert_eq!(
                base.len(),
                2 * plane.pixels(),
                "the base is two samples a pixel"
            );
            let short = pixel_shortfall(plane, &base.xs, &base.ys, m);
            let mut rng = round_rng(1, 1);
            let fill = top_up(plane, plan.tree(), plan.params(), &short, m, &mut rng);
            let mut per_pixel = vec![Vec::new(); plane.pixels()];
            for (&x, &y) in base
                .xs
                .iter()
                .chain(&fill.xs)
                .zip(base.ys.iter().chain(&fill.ys))
            {
                let (px, py) = plane.pixel_of(x, y);
                per_pixel[py * 32 + px].push((x - px as f64, y - py as f64));
            }
            let k = m.trailing_zeros();
            for (p, pts) in per_pixel.iter().enumerate() {
                assert_eq!(pts.len(), m, "pixel {p} at m = {m}");
                assert!(
                    is_net(pts, k),
                    "pixel {p} at m = {m}: not a (0, {k}, 2)-net"
                );
            }
        }
    }

    /// The floor's count: `max(min(ceil(rho), N / (W H)), floor(f N / (W H)))`, never above
    /// the budget's samples a pixel, 0 beside the coverage rule when both are off.
    #[test]
    fn the_floor_count_follows_the_share() {
        let plane = ImagePlane::new(16, 16).unwrap();
        let mut params = AdaptiveParams::default();
        params.stop.budget = 16 * plane.pixels();
        for (f, m) in [
            (0.0, 2),
            (0.1, 2),
            (0.25, 4),
            (0.5, 8),
            (0.74, 11),
            (1.0, 16),
        ] {
            params.sampling.pixel_floor = f;
            assert_eq!(
                ImagePlan::new(plane, &params).unwrap().per_pixel(),
                m,
                "f = {f}"
            );
        }
        params.sampling.cover_pixels = false;
        params.sampling.pixel_floor = 0.0;
        assert_eq!(ImagePlan::new(plane, &params).unwrap().per_pixel(), 0);
        params.sampling.pixel_floor = 2.0;
        assert!(
            ImagePlan::new(plane, &params).is_err(),
            "a share above 1 is refused"
        );
    }
}
