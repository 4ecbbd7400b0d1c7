//! The second half of a round ([`ImagePlan::step`]): tally the slots' samples and the
//! round's allowance, then densify when nothing significant is left to deepen, or mark
//! (Dörfler, extended to the least growth, within the budget), deepen the marked slots and
//! draw the positions that top their children up, spreading the spare samples.

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use super::super::indicator::Indication;
use super::positions::{round_rng, spread_samples};
use super::{ImagePlan, ImageRound, SamplePositions};
use crate::adaptive::marking::{dorfler, within_budget, SpreadRule};
use crate::adaptive::Cell;

impl ImagePlan {
    /// The slots' samples, the oversampling so far, the round's least growth and the
    /// indicator of every slot (the weights of the spare samples).
    pub(super) fn tally(&self, xs: &[f64], ys: &[f64], ind: &Indication) -> Tally {
        let params = &self.params;
        let left = params.stop.budget.saturating_sub(xs.len());
        // the oversampling so far: ceil(rho), or more after densifying rounds
        let counts = self.tree.leaf_counts(xs, ys);
        let slots = self.tree.leaves();
        let target = slots
            .iter()
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
        Tally {
            slots,
            counts,
            target,
            left,
            goal,
            eta,
        }
    }

    /// Densify (nothing significant left to deepen): up to double the samples per slot, at
    /// least the least growth, spread evenly. `None` when the budget is spent; else the
    /// positions and the seconds they took.
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
        let mut rng = round_rng(self.params.sampling.seed, round + 1);
        let mut next = SamplePositions::default();
        let (_, to) = spread_samples(
            &self.tree,
            &tally.slots,
            &tally.counts,
            &tally.eta,
            SpreadRule::Uniform,
            extra,
            &mut next,
            &mut rng,
        );
        log.densified_to = Some(to);
        self.progress.marked.push(Vec::new());
        self.progress.samples_fitted = samples;
        Some((next, t.elapsed().as_secs_f64()))
    }

    /// Mark: Dörfler's set ([`super::super::marking::dorfler`], at least one slot), extended
    /// in indicator order to the least growth (less the share reserved for spreading), cut to
    /// the prefix the budget pays for ([`super::super::marking::within_budget`]); the spare
    /// samples beside. `None` when neither a slot nor a spare sample fits the budget.
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
        // a share of the least growth kept for spreading
        let reserved = (params.growth.spread_share * goal as f64).ceil() as usize;
        let mark_goal = goal - reserved.min(goal);
        let mut k = n;
        let mut spent: usize = costs[..n].iter().sum();
        while k < costs.len() && spent < mark_goal && etas[k] > 0.0 {
            spent += costs[k];
            k += 1;
        }
        let k = within_budget(&costs[..k], left - reserved.min(left));
        let spent: usize = costs[..k].iter().sum();
        // the spare samples: the least growth the marked slots do not take
        let extra = goal.saturating_sub(spent).max(reserved).min(left - spent);
        if k == 0 && extra == 0 {
            return None;
        }
        Some(Marking {
            marked,
            child_counts,
            k,
            extra,
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
        let mut rng = round_rng(self.params.sampling.seed, round + 1);
        let mut next = SamplePositions::default();
        for (cell, counts) in marking.marked[..k].iter().zip(&marking.child_counts) {
            let per_slot = marking.per_child.of(cell);
            self.tree.deepen(*cell);
            for (q, child) in cell.children().into_iter().enumerate() {
                let need = per_slot.saturating_sub(counts[q]);
                next.stratified(self.tree.rect(child), need, &mut rng);
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
            let (added, _) = spread_samples(
                &self.tree,
                &stay,
                &tally.counts,
                &tally.eta,
                self.params.growth.spread,
                marking.extra,
                &mut next,
                &mut rng,
            );
            log.spread = added;
        }
        self.progress.marked.push(marking.marked[..k].to_vec());
        self.progress.samples_fitted = samples;
        next
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
    /// Samples left in the budget.
    left: usize,
    /// The round's least growth.
    goal: usize,
    /// The indicator of every slot (the weights of the spare samples).
    eta: HashMap<Cell, f64>,
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
    /// Spare samples to spread over the slots that stay slots.
    extra: usize,
    per_child: PerChild,
}
