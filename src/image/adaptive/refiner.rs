//! The adaptive rounds on the image plane (the 2D analogue of [`crate::refine`]).
//!
//! 1. Base: the tree full up to the base step `s0` (slots of `V_{cx+s0} (x) V_{cy+s0}`),
//!    `ceil(rho)` jittered-stratified samples in every slot.
//! 2. Round: fit on the tree ([`super::fit_tree`]); indicate ([`super::indicator`]); stop if the
//!    estimated RMS error `sqrt(sum eta^2 / (W H))` is at most the tolerance, if nothing below
//!    the depth limit can be marked, or at the round limit; otherwise mark by Dörfler
//!    ([`super::marking::dorfler`], at least one slot; extended in indicator order until the
//!    round adds `min_growth` times the current samples), keep the longest prefix the remaining
//!    budget pays for ([`super::marking::within_budget`]; none: stop at the budget), activate
//!    the marked slots and top up each of their four children to `ceil(rho)` samples.
//!
//! Invariant after every round: every slot holds at least `ceil(rho)` samples, and the samples
//! never exceed the budget. Deterministic for a seed: the marked slots are processed in
//! indicator order (ties by cell) with one PCG-64 stream per round.
//!
//! Every round refits from scratch (kernel rows, `G`, Cholesky): the incremental update of the
//! 1D refiner is not yet carried over (the "round costs what changed" is open).

use std::collections::HashMap;
use std::time::Instant;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::Serialize;

use super::fit::{fit_tree, TreeFit, TreeFitReport};
use super::indicator::indicate;
use super::marking::{dorfler, within_budget};
use super::tree::{Cell, QuadTree};
use super::{AdaptiveError, ImageOracle};
use crate::basis::tensor::TensorBasis;
use crate::basis::FilterFamily;
use crate::image::{ImagePlane, PixelImage};
use crate::refine::StopReason;

/// Parameters of the adaptive image refiner.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AdaptiveParams {
    /// Vanishing moments `p` (2 is the practical choice in 2D).
    pub p: usize,
    /// Depth limit below the pixel: the finest level per axis is
    /// `J = ceil(log2 size) + below_pixel` (1: half-pixel functions at edges; measured at 64²,
    /// 4 spp on `shapes`, quarter-pixel ones spent the budget on too few edge cells).
    pub below_pixel: u32,
    /// Level of the base slots along x (`None`: the finest whose samples fit in
    /// `base_fraction` of the budget).
    pub base_level: Option<u32>,
    /// Share of the budget the automatic base level may spend.
    pub base_fraction: f64,
    /// Samples per slot, `ceil(rho)` (the local oversampling).
    pub rho: f64,
    /// Dörfler fraction of the estimated squared error marked per round, in `(0, 1]`.
    pub theta: f64,
    /// Cap `r_max` of the indicator's decay ratio ([`super::indicator`]): `1/2` is a straight
    /// edge's ratio; larger values give unresolved oscillations (textures) more priority and
    /// let a few cells go deep before the whole edge is resolved.
    pub max_ratio: f64,
    /// Least growth per round as a share of the current samples: if the Dörfler set costs
    /// fewer new samples, the next slots in indicator order are marked too (fewer rounds on a
    /// concentrated indicator; 0: pure Dörfler).
    pub min_growth: f64,
    /// Stop when the estimated RMS error (per unit area) is at most this (0: budget-driven).
    pub tolerance: f64,
    /// Most samples in total.
    pub budget: usize,
    /// Most refinement rounds.
    pub max_rounds: usize,
    /// Seed of the sample positions.
    pub seed: u64,
}

impl Default for AdaptiveParams {
    fn default() -> Self {
        Self {
            p: 2,
            below_pixel: 1,
            base_level: None,
            base_fraction: 0.3,
            rho: 2.0,
            theta: 0.5,
            min_growth: 0.25,
            max_ratio: 0.5,
            tolerance: 0.0,
            budget: 0,
            max_rounds: 40,
            seed: 1,
        }
    }
}

impl AdaptiveParams {
    fn validate(&self) -> Result<(), AdaptiveError> {
        let bad = |parameter, value: String, expected| {
            Err(AdaptiveError::Parameter {
                parameter,
                value,
                expected,
            })
        };
        if !(1..=8).contains(&self.p) {
            return bad("p", self.p.to_string(), "vanishing moments in 1..=8");
        }
        if self.below_pixel > 6 {
            return bad(
                "below_pixel",
                self.below_pixel.to_string(),
                "levels below the pixel in 0..=6",
            );
        }
        if !(self.rho.is_finite() && (1.0..=256.0).contains(&self.rho)) {
            return bad("rho", self.rho.to_string(), "samples per slot in [1, 256]");
        }
        if !(self.theta > 0.0 && self.theta <= 1.0) {
            return bad(
                "theta",
                self.theta.to_string(),
                "a Dörfler fraction in (0, 1]",
            );
        }
        if !(self.base_fraction > 0.0 && self.base_fraction <= 1.0) {
            return bad(
                "base_fraction",
                self.base_fraction.to_string(),
                "a share of the budget in (0, 1]",
            );
        }
        if !(self.max_ratio > 0.0 && self.max_ratio < 1.0) {
            return bad(
                "max_ratio",
                self.max_ratio.to_string(),
                "a decay ratio cap in (0, 1)",
            );
        }
        if !(self.min_growth.is_finite() && (0.0..=10.0).contains(&self.min_growth)) {
            return bad(
                "min_growth",
                self.min_growth.to_string(),
                "a share of the samples in [0, 10]",
            );
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return bad(
                "tolerance",
                self.tolerance.to_string(),
                "a finite RMS error >= 0 (0: run until the budget is spent)",
            );
        }
        if self.budget == 0 {
            return bad("budget", "0".into(), "a positive number of samples");
        }
        Ok(())
    }
}

/// What one round saw and did.
#[derive(Clone, Debug, Serialize)]
pub struct ImageRound {
    /// Round number (0 = the base fit).
    pub round: usize,
    /// Samples in this round's fit.
    pub samples: usize,
    /// Samples added for this round's fit.
    pub new_samples: usize,
    /// Active functions.
    pub functions: usize,
    /// Deepest slot step.
    pub max_depth: u32,
    /// Estimated RMS error (per unit area) of this round's fit.
    pub estimate_rms: f64,
    /// Slots marked after this fit (0 in the last round).
    pub marked: usize,
    /// The solve.
    pub fit: TreeFitReport,
}

/// Seconds by stage.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct AdaptiveTimes {
    /// Oracle calls.
    pub sample_s: f64,
    /// Fits (all rounds).
    pub fit_s: f64,
    /// Indicators, marking, deepening.
    pub refine_s: f64,
}

/// What the adaptive run did.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReport {
    /// Finest levels `(Jx, Jy)` (the depth limit).
    pub levels: (u32, u32),
    /// Coarse levels `(cx, cy)`.
    pub coarse_levels: (u32, u32),
    /// Levels of the base slots `(cx + s0, cy + s0)`.
    pub base_levels: (u32, u32),
    /// Base samples.
    pub base_samples: usize,
    /// Samples in total.
    pub samples: usize,
    /// The budget.
    pub budget: usize,
    /// Active functions of the final tree.
    pub functions: usize,
    /// Active cells per step.
    pub cells_per_step: Vec<usize>,
    /// Why the refiner stopped.
    pub stop: StopReason,
    /// Per round.
    pub rounds: Vec<ImageRound>,
    /// Seconds by stage.
    pub times: AdaptiveTimes,
    /// Fallbacks, in words.
    pub notes: Vec<String>,
}

/// The result: tree, samples, fit.
#[derive(Clone, Debug)]
pub struct AdaptiveImage {
    /// The final tree.
    pub tree: QuadTree,
    /// Sample x positions (pixel units).
    pub xs: Vec<f64>,
    /// Sample y positions.
    pub ys: Vec<f64>,
    /// Values per channel.
    pub values: Vec<Vec<f64>>,
    /// The round that added each sample (0 = base).
    pub round_of: Vec<u32>,
    /// The fit on the final tree.
    pub fit: TreeFit,
    /// What happened.
    pub report: AdaptiveReport,
}

impl AdaptiveImage {
    /// Exact box pixels of the final fit.
    pub fn pixels(&self) -> Result<PixelImage, AdaptiveError> {
        let b = self.tree.basis();
        let plane = ImagePlane::new(b.width(), b.height()).expect("the basis has a valid size");
        Ok(PixelImage {
            plane,
            channels: self.fit.box_pixels(&self.tree)?,
        })
    }
}

/// Growing sample store.
struct Store<'a> {
    oracle: &'a dyn ImageOracle,
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
    round_of: Vec<u32>,
    buf: Vec<f64>,
}

impl Store<'_> {
    fn push(&mut self, x: f64, y: f64, round: u32) {
        self.oracle.sample(x, y, &mut self.buf);
        self.xs.push(x);
        self.ys.push(y);
        for (c, v) in self.values.iter_mut().zip(&self.buf) {
            c.push(*v);
        }
        self.round_of.push(round);
    }

    /// `need` jittered-stratified positions in `rect`: a `k x k` grid (`k^2 >= need`), `need`
    /// of its strata chosen at random, one uniform point in each.
    fn fill(&mut self, rect: [f64; 4], need: usize, round: u32, rng: &mut Pcg64) {
        if need == 0 {
            return;
        }
        let k = (need as f64).sqrt().ceil() as usize;
        let mut strata: Vec<usize> = (0..k * k).collect();
        if k * k > need {
            strata.shuffle(rng);
        }
        let (dx, dy) = (
            (rect[1] - rect[0]) / k as f64,
            (rect[3] - rect[2]) / k as f64,
        );
        for &s in &strata[..need] {
            let (i, j) = (s % k, s / k);
            let x = (rect[0] + (i as f64 + rng.random::<f64>()) * dx).min(rect[1]);
            let y = (rect[2] + (j as f64 + rng.random::<f64>()) * dy).min(rect[3]);
            self.push(x, y, round);
        }
    }
}

fn round_rng(seed: u64, round: usize) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ (round as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

fn finest_level(size: usize, below: u32) -> u32 {
    (size.max(1) as f64).log2().ceil() as u32 + below
}

/// Refines the image of `oracle` on `plane`: adaptive tree and samples, until the tolerance,
/// the depth limit, the budget or the round limit.
pub fn refine_image(
    oracle: &dyn ImageOracle,
    plane: ImagePlane,
    params: &AdaptiveParams,
) -> Result<AdaptiveImage, AdaptiveError> {
    params.validate()?;
    let (w, h) = (plane.width(), plane.height());
    let levels = (
        finest_level(w, params.below_pixel).max(crate::basis::minimum_level(params.p) + 2),
        finest_level(h, params.below_pixel).max(crate::basis::minimum_level(params.p) + 2),
    );
    let basis = TensorBasis::new(params.p, FilterFamily::cdv_default(params.p), w, h, levels)?;
    let steps = basis.steps();
    let (cx, cy) = basis.coarse_levels();
    let per_slot = params.rho.ceil() as usize;
    let base_cost = |s: u32| (1usize << (cx + s)) * (1usize << (cy + s)) * per_slot;
    let s0 = match params.base_level {
        Some(level) => {
            if level <= cx || level > cx + steps {
                return Err(AdaptiveError::Parameter {
                    parameter: "base_level",
                    value: level.to_string(),
                    expected: "a level above the coarse level and at most the depth limit",
                });
            }
            level - cx
        }
        None => (1..steps)
            .rev()
            .find(|&s| base_cost(s) as f64 <= params.base_fraction * params.budget as f64)
            .unwrap_or(1),
    };
    if base_cost(s0) > params.budget {
        return Err(AdaptiveError::BudgetTooSmall {
            budget: params.budget,
            base: base_cost(s0),
            slots: base_cost(s0) / per_slot,
            per_slot,
        });
    }
    let mut tree = QuadTree::uniform(basis, s0);
    let mut times = AdaptiveTimes::default();
    let mut store = Store {
        oracle,
        xs: Vec::new(),
        ys: Vec::new(),
        values: vec![Vec::new(); oracle.channels()],
        round_of: Vec::new(),
        buf: vec![0.0; oracle.channels()],
    };
    let t = Instant::now();
    let mut rng = round_rng(params.seed, 0);
    for slot in tree.slots() {
        store.fill(tree.rect(slot), per_slot, 0, &mut rng);
    }
    times.sample_s += t.elapsed().as_secs_f64();
    let base_samples = store.xs.len();
    let mut rounds = Vec::new();
    let mut new_samples = base_samples;
    let (fit, stop) = loop {
        let round = rounds.len();
        let t = Instant::now();
        let values: Vec<&[f64]> = store.values.iter().map(|v| v.as_slice()).collect();
        let fit = fit_tree(&tree, &store.xs, &store.ys, &values)?;
        times.fit_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let ind = indicate(&tree, &fit.coefficients, params.max_ratio);
        let estimate_rms = (ind.total_sq / plane.pixels() as f64).sqrt();
        let mut log = ImageRound {
            round,
            samples: store.xs.len(),
            new_samples,
            functions: fit.report.functions,
            max_depth: tree.slots().iter().map(|c| c.step).max().unwrap_or(0),
            estimate_rms,
            marked: 0,
            fit: fit.report.clone(),
        };
        let stop = if estimate_rms <= params.tolerance {
            Some(StopReason::Tolerance)
        } else if ind.markable_sq <= 0.0 || ind.units.is_empty() {
            Some(StopReason::DepthLimit)
        } else if round >= params.max_rounds {
            Some(StopReason::MaxRounds)
        } else {
            None
        };
        if let Some(stop) = stop {
            rounds.push(log);
            times.refine_s += t.elapsed().as_secs_f64();
            break (fit, stop);
        }
        let etas: Vec<f64> = ind.units.iter().map(|u| u.1).collect();
        let n = dorfler(&etas, params.theta).max(1);
        // every unit is a candidate: the Dörfler set, extended to the least growth
        let marked: Vec<Cell> = ind.units.iter().map(|u| u.0).collect();
        // samples already in each child of each marked slot
        let index: HashMap<Cell, usize> = marked.iter().enumerate().map(|(i, &c)| (c, i)).collect();
        let mut child_counts = vec![[0usize; 4]; marked.len()];
        for (&x, &y) in store.xs.iter().zip(&store.ys) {
            let slot = tree.slot_at(x, y);
            if let Some(&i) = index.get(&slot) {
                let c = tree.cell_at(slot.step + 1, x, y);
                child_counts[i][(c.ky & 1) * 2 + (c.kx & 1)] += 1;
            }
        }
        let costs: Vec<usize> = child_counts
            .iter()
            .map(|cc| cc.iter().map(|&c| per_slot.saturating_sub(c)).sum())
            .collect();
        let left = params.budget - store.xs.len();
        let growth = (params.min_growth * store.xs.len() as f64).ceil() as usize;
        let mut k = n;
        let mut spent: usize = costs[..n].iter().sum();
        while k < costs.len() && spent < growth && etas[k] > 0.0 {
            spent += costs[k];
            k += 1;
        }
        let k = within_budget(&costs[..k], left);
        if k == 0 {
            rounds.push(log);
            times.refine_s += t.elapsed().as_secs_f64();
            break (fit, StopReason::Budget);
        }
        log.marked = k;
        rounds.push(log);
        times.refine_s += t.elapsed().as_secs_f64();
        let t = Instant::now();
        let mut rng = round_rng(params.seed, round + 1);
        let before = store.xs.len();
        for (cell, counts) in marked[..k].iter().zip(&child_counts) {
            tree.activate(*cell);
            for (q, child) in cell.children().into_iter().enumerate() {
                let need = per_slot.saturating_sub(counts[q]);
                store.fill(tree.rect(child), need, round as u32 + 1, &mut rng);
            }
        }
        new_samples = store.xs.len() - before;
        times.sample_s += t.elapsed().as_secs_f64();
    };
    let report = AdaptiveReport {
        levels: tree.basis().levels(),
        coarse_levels: (cx, cy),
        base_levels: (cx + s0, cy + s0),
        base_samples,
        samples: store.xs.len(),
        budget: params.budget,
        functions: fit.report.functions,
        cells_per_step: tree.cells_per_step(),
        stop,
        rounds,
        times,
        notes: fit_notes(&fit.report),
    };
    Ok(AdaptiveImage {
        tree,
        xs: store.xs,
        ys: store.ys,
        values: store.values,
        round_of: store.round_of,
        fit,
        report,
    })
}

fn fit_notes(r: &TreeFitReport) -> Vec<String> {
    let mut notes = Vec::new();
    if r.ridge > 0.0 {
        notes.push(format!(
            "the final normal matrix was numerically singular (smallest pivot {:.1e}): a \
             relative ridge {:.0e} was added",
            r.min_pivot, r.ridge
        ));
    }
    if r.unsampled > 0 {
        notes.push(format!(
            "{} active functions have no sample in their support (held at 0 by the ridge)",
            r.unsampled
        ));
    }
    notes
}
