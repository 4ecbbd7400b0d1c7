//! The second half of a round ([`ImagePlan::step`]): tally the slots' samples and the
//! round's allowance, then densify when nothing significant is left to deepen, or mark
//! (Dörfler, extended to the least growth, within the budget), deepen the marked slots and
//! draw the positions that top their children up, spreading the spare samples.

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use super::super::fit::TreeFit;
use super::super::indicator::Indication;
use super::super::significance::residuals;
use super::pixel_spread::{pooled_spread, spread_over_pixels};
use super::positions::spread_samples;
use super::{ImagePlan, ImageRound, SamplePositions};
use crate::adaptive::marking::{dorfler, within_budget, SpreadRule};
use crate::adaptive::Cell;
use crate::adaptive::QuadTree;

impl ImagePlan {
    /// The slots' samples, the oversampling so far, the round's least growth and the
    /// indicator of every slot (the weights of the spare samples); `reserve` samples of the
    /// budget's rest are held back (the coverage rule, module `coverage`).
    pub(super) fn tally(
        &self,
        xs: &[f64],
        ys: &[f64],
        values: &[&[f64]],
        fit: &TreeFit,
        ind: &Indication,
        reserve: usize,
    ) -> Tally {
        let params = &self.params;
        // the samples this round may spend: the budget's rest less the coverage reserve
        let left = params.stop.budget.saturating_sub(xs.len() + reserve);
        // the slots' moments: of the fit's residuals under the uncertainty rule (the output
        // is the fit plus the mean residual, whose variance is the residuals' spread over n)
        let residuals = (params.growth.spread == SpreadRule::Uncertainty).then(|| {
            let coef: Vec<&[f64]> = fit.coefficients.iter().map(|c| c.as_slice()).collect();
            residuals(&self.tree, &coef, xs, ys, values)
        });
        let of: Vec<&[f64]> = match &residuals {
            Some(r) => r.iter().map(|c| c.as_slice()).collect(),
            None => values.to_vec(),
        };
        let moments = SlotMoments::new(&self.tree, xs, ys, &of);
        // the oversampling so far: ceil(rho), or more after densifying rounds; with the
        // uniform floor in the base, over the slots deepened since (the base slots' counts
        // are the floor's, a share of the pixel, not the tree's oversampling)
        let counts: HashMap<Cell, usize> = moments.0.iter().map(|(c, m)| (*c, m.n)).collect();
        let slots = self.tree.leaves();
        let uncertainty = moments.uncertainty(&self.tree, &slots);
        let target = slots
            .iter()
            .filter(|s| self.floor == 0 || s.step > self.base_steps)
            .map(|s| counts.get(s).copied().unwrap_or(0))
            .min()
            .unwrap_or(0)
            .max(self.per_slot);
        // the round's least growth: min_growth x the samples, or the rest of the budget
        let goal = ((params.growth.min_growth * xs.len() as f64).ceil() as usize).min(left);
        let eta: HashMap<Cell, f64> = ind
            .units
            .iter()
            .chain(&ind.insignificant)
            .chain(&ind.at_limit)
            .copied()
            .collect();
        let decaying: HashSet<Cell> = ind.units.iter().map(|u| u.0).collect();
        // the pixels' spreads, when the share is on and some pixel's samples spread (else
        // the round is the tree's alone)
        let pixels = self
            .pixel_share_on()
            .then(|| pooled_spread(self.plane, xs, ys, values))
            .filter(|(s, _)| s.iter().any(|&v| v > 0.0));
        Tally {
            slots,
            counts,
            target,
            left,
            goal,
            eta,
            decaying,
            uncertainty,
            pixels,
        }
    }

    /// Densify (nothing significant left to deepen): up to double the samples per slot, at
    /// least the least growth, spread evenly (by the uncertainty of the slots' means under
    /// [`SpreadRule::Uncertainty`]). `None` when the budget is spent; else the positions and
    /// the seconds they took.
    pub(super) fn densify(
        &mut self,
        round: usize,
        samples: usize,
        tally: &Tally,
        log: &mut ImageRound,
    ) -> Option<(SamplePositions, f64)> {
        let doubling: usize = tally
            .slots
            .iter()
            .map(|s| (2 * tally.target).saturating_sub(tally.counts.get(s).copied().unwrap_or(0)))
            .sum();
        let extra = doubling.max(tally.goal).min(tally.left);
        if extra == 0 {
            return None;
        }
        let t = Instant::now();
        let mut placer = self.placer(round + 1);
        let mut next = SamplePositions::default();
        let rule = match self.params.growth.spread {
            SpreadRule::Uncertainty => SpreadRule::Uncertainty,
            _ => SpreadRule::Uniform,
        };
        // the pixel share first (module `pixel_spread`), the rest over the slots
        let share = (self.params.growth.pixel_share * extra as f64).ceil() as usize;
        let by_pixel = self.over_pixels(tally, &tally.slots, share, &mut next, &mut placer);
        log.pixel_spread = by_pixel;
        let (_, to) = spread_samples(
            &self.tree,
            &tally.slots,
            &tally.counts,
            &tally.weights(rule, &tally.slots),
            extra - by_pixel,
            &mut next,
            &mut placer,
        );
        log.densified_to = Some(to);
        self.progress.marked.push(Vec::new());
        self.progress.samples_fitted = samples;
        Some((next, t.elapsed().as_secs_f64()))
    }

    /// Mark: Dörfler's set ([`super::super::marking::dorfler`], at least one slot), extended
    /// in indicator order to the least growth (less the share reserved for spreading), cut to
    /// the prefix the budget pays for ([`super::super::marking::within_budget`]); the spare
    /// samples beside. `None` when the round would hand out no position (neither a slot's
    /// new samples nor a spare sample fits the budget).
    pub(super) fn mark(
        &self,
        xs: &[f64],
        ys: &[f64],
        ind: &Indication,
        tally: &Tally,
    ) -> Option<Marking> {
        let params = &self.params;
        let tree = &self.tree;
        let (left, goal, target) = (tally.left, tally.goal, tally.target);
        let etas: Vec<f64> = ind.units.iter().map(|u| u.1).collect();
        let n = dorfler(&etas, params.marking.theta).max(1);
        // every unit is a candidate: the Dörfler set, extended to the least growth
        let marked: Vec<Cell> = ind.units.iter().map(|u| u.0).collect();
        // samples already in each child of each marked slot
        let index: HashMap<Cell, usize> = marked.iter().enumerate().map(|(i, &c)| (c, i)).collect();
        let mut child_counts = vec![[0usize; 4]; marked.len()];
        for (&x, &y) in xs.iter().zip(ys) {
            let slot = tree.leaf_at(x, y);
            if let Some(&i) = index.get(&slot) {
                let c = tree.cell_at(slot.step + 1, x, y);
                child_counts[i][(c.ky & 1) * 2 + (c.kx & 1)] += 1;
            }
        }
        // children at the depth limit get at least ceil(rho_limit) samples
        let per_child = PerChild {
            target,
            limit_slot: target.max(params.sampling.rho_limit.ceil() as usize),
            steps: tree.steps(),
        };
        let costs: Vec<usize> = marked
            .iter()
            .zip(&child_counts)
            .map(|(m, cc)| cc.iter().map(|&c| per_child.of(m).saturating_sub(c)).sum())
            .collect();
        // a share of the least growth kept for spreading, and the pixels' share
        let reserved = (params.growth.spread_share * goal as f64).ceil() as usize;
        let by_pixel = if tally.pixels.is_some() {
            (params.growth.pixel_share * goal as f64).ceil() as usize
        } else {
            0
        };
        let kept = reserved + by_pixel;
        let mark_goal = goal - kept.min(goal);
        let mut k = n;
        let mut spent: usize = costs[..n].iter().sum();
        while k < costs.len() && spent < mark_goal && etas[k] > 0.0 {
            spent += costs[k];
            k += 1;
        }
        let k = within_budget(&costs[..k], left - kept.min(left));
        let spent: usize = costs[..k].iter().sum();
        // the spare samples: the least growth the marked slots do not take; with the pixel
        // share on, all but the slots' own share go to the pixels
        let rest = goal.saturating_sub(spent).max(kept).min(left - spent);
        let (extra, pixels) = if tally.pixels.is_some() {
            (reserved.min(rest), rest - reserved.min(rest))
        } else {
            (rest, 0)
        };
        let extra = extra + pixels;
        // a round must hand out positions: marks whose children already hold their samples
        // and no spare sample (the coverage reserve took the rest) end the marking
        if spent + extra == 0 {
            return None;
        }
        Some(Marking {
            marked,
            child_counts,
            k,
            extra,
            pixels,
            per_child,
        })
    }

    /// Deepen and sample: activate the marked slots, top each of their four children up to
    /// its count, spread the spare samples over the slots that stay slots, and record the
    /// round in the plan's progress.
    pub(super) fn deepen_and_sample(
        &mut self,
        round: usize,
        samples: usize,
        tally: &Tally,
        marking: &Marking,
        log: &mut ImageRound,
    ) -> SamplePositions {
        let k = marking.k;
        let mut placer = self.placer(round + 1);
        let mut next = SamplePositions::default();
        for (cell, counts) in marking.marked[..k].iter().zip(&marking.child_counts) {
            let per_slot = marking.per_child.of(cell);
            self.tree.deepen(*cell);
            for (q, child) in cell.children().into_iter().enumerate() {
                let need = per_slot.saturating_sub(counts[q]);
                placer.place(&mut next, child, self.tree.rect(child), counts[q], need);
            }
        }
        if marking.extra > 0 {
            // the slots that stay slots (the marked ones' children are topped up above)
            let deepened: HashSet<Cell> = marking.marked[..k].iter().copied().collect();
            let stay: Vec<Cell> = tally
                .slots
                .iter()
                .copied()
                .filter(|s| !deepened.contains(s))
                .collect();
            // the pixels' share first (module `pixel_spread`); what they cannot take (no
            // spread anywhere) goes to the slots with the rest
            let by_pixel = self.over_pixels(tally, &stay, marking.pixels, &mut next, &mut placer);
            log.pixel_spread = by_pixel;
            let (added, _) = spread_samples(
                &self.tree,
                &stay,
                &tally.counts,
                &tally.weights(self.params.growth.spread, &stay),
                marking.extra - by_pixel,
                &mut next,
                &mut placer,
            );
            log.spread = added;
        }
        self.progress.marked.push(marking.marked[..k].to_vec());
        self.progress.samples_fitted = samples;
        next
    }

    /// `share` samples over the pixels by their pooled spread, in the slots `stay`
    /// (module `pixel_spread`); the samples added (0 when the share is off or no pixel
    /// has a spread).
    fn over_pixels(
        &self,
        tally: &Tally,
        stay: &[Cell],
        share: usize,
        next: &mut SamplePositions,
        placer: &mut super::positions::Placer,
    ) -> usize {
        match &tally.pixels {
            Some((spread_of, pixel_counts)) => spread_over_pixels(
                self.plane,
                &self.tree,
                stay,
                &tally.counts,
                spread_of,
                pixel_counts,
                share,
                next,
                placer,
            ),
            None => 0,
        }
    }
}

/// The slots at the start of marking and the round's allowance.
pub(super) struct Tally {
    /// The tree's slots.
    slots: Vec<Cell>,
    /// Samples per slot.
    counts: HashMap<Cell, usize>,
    /// The least samples of a slot, at least `ceil(rho)`: the oversampling so far.
    target: usize,
    /// Samples left in the budget, less the coverage reserve.
    left: usize,
    /// The round's least growth.
    goal: usize,
    /// The indicator of every slot (the weights of the spare samples).
    eta: HashMap<Cell, f64>,
    /// The slots whose detail is significant and below the depth limit (the markable ones).
    decaying: HashSet<Cell>,
    /// The uncertainty `sqrt(A) s` of every slot's mean, `s` the spread of the fit's
    /// residuals in the slot ([`SlotMoments::uncertainty`]).
    uncertainty: HashMap<Cell, f64>,
    /// With the pixel share on: every pixel's pooled spread and its samples (module
    /// `pixel_spread`).
    pixels: Option<(Vec<f64>, Vec<usize>)>,
}

impl Tally {
    /// The weights of `slots` for spreading by `rule` ([`SpreadRule`]): under
    /// [`SpreadRule::Uncertainty`], a slot whose detail is significant and can still be
    /// deepened keeps its indicator `eta` (the detail decays: deepening will resolve it); a
    /// slot at the depth limit or within the noise (detail that does not decay: texture past
    /// the depth limit, noise) takes the uncertainty of its mean, `sqrt(A) s`. Both are norms
    /// of an error over the slot, so they weigh against each other.
    fn weights(&self, rule: SpreadRule, slots: &[Cell]) -> Vec<f64> {
        let of = |m: &HashMap<Cell, f64>, s: &Cell| m.get(s).copied().unwrap_or(0.0);
        match rule {
            SpreadRule::Uniform => vec![1.0; slots.len()],
            SpreadRule::Indicator => slots.iter().map(|s| of(&self.eta, s)).collect(),
            SpreadRule::Uncertainty => slots
                .iter()
                .map(|s| {
                    if self.decaying.contains(s) {
                        of(&self.eta, s)
                    } else {
                        of(&self.uncertainty, s)
                    }
                })
                .collect(),
        }
    }
}

/// Count, mean and sum of squared deviations (Welford) of one slot's samples per channel.
#[derive(Clone, Default)]
struct Moments {
    n: usize,
    mean: Vec<f64>,
    m2: Vec<f64>,
}

/// The samples' moments in every slot that holds one.
struct SlotMoments(HashMap<Cell, Moments>);

impl SlotMoments {
    fn new(tree: &QuadTree, xs: &[f64], ys: &[f64], values: &[&[f64]]) -> Self {
        let ch = values.len();
        let mut slots: HashMap<Cell, Moments> = HashMap::new();
        for (i, (&x, &y)) in xs.iter().zip(ys).enumerate() {
            let m = slots.entry(tree.leaf_at(x, y)).or_insert_with(|| Moments {
                n: 0,
                mean: vec![0.0; ch],
                m2: vec![0.0; ch],
            });
            m.n += 1;
            for (c, v) in values.iter().enumerate() {
                let d = v[i] - m.mean[c];
                m.mean[c] += d / m.n as f64;
                m.m2[c] += d * (v[i] - m.mean[c]);
            }
        }
        Self(slots)
    }

    /// The uncertainty of each slot's mean as a spreading weight: `sqrt(A_i) s_i`, the square
    /// root of the slot's area in pixels times the spread of its samples' residuals
    /// `s_i = sqrt(sum_c s_{i,c}^2)` (unbiased sample variances). An error `e_i` of the
    /// slot's mean costs `A_i e_i^2` in the image's squared error, and `E e_i^2 = s_i^2 / n_i`,
    /// so Neyman's allocation `n_i ~ sqrt(A_i) s_i` minimises `sum_i A_i s_i^2 / n_i` for the
    /// samples spent. A slot with fewer than two samples takes the mean spread of the slots
    /// with two or more.
    fn uncertainty(&self, tree: &QuadTree, slots: &[Cell]) -> HashMap<Cell, f64> {
        let spread = |m: &Moments| (m.m2.iter().sum::<f64>() / (m.n - 1) as f64).sqrt();
        let known: Vec<f64> = self.0.values().filter(|m| m.n >= 2).map(spread).collect();
        let pooled = known.iter().sum::<f64>() / known.len().max(1) as f64;
        slots
            .iter()
            .map(|&s| {
                let r = tree.rect(s);
                let area = (r[1] - r[0]) * (r[3] - r[2]);
                let side = area.sqrt();
                let sd = match self.0.get(&s) {
                    Some(m) if m.n >= 2 => spread(m),
                    _ => pooled,
                };
                (s, side * sd)
            })
            .collect()
    }
}

/// Samples each child of a marked slot is topped up to: the oversampling so far, at least
/// `ceil(rho_limit)` at the depth limit.
#[derive(Clone, Copy)]
struct PerChild {
    target: usize,
    limit_slot: usize,
    steps: u32,
}

impl PerChild {
    /// The count for the children of `cell`.
    fn of(&self, cell: &Cell) -> usize {
        if cell.step + 1 >= self.steps {
            self.limit_slot
        } else {
            self.target
        }
    }
}

/// The round's marks: every candidate slot in indicator order, the samples in each child,
/// the accepted prefix and the spare samples.
pub(super) struct Marking {
    marked: Vec<Cell>,
    child_counts: Vec<[usize; 4]>,
    /// Accepted marks: `marked[..k]`.
    pub(super) k: usize,
    /// Spare samples to spread over the slots that stay slots, `pixels` of them first over
    /// the pixels by their pooled spread.
    extra: usize,
    /// The pixels' share of `extra` (module `pixel_spread`).
    pixels: usize,
    per_child: PerChild,
}
