//! Drawing the sample positions the refiner asks for in a slot's rectangle, by the plan's
//! [`PositionPattern`]:
//!
//! * [`PositionPattern::Sobol`] (the default): every slot (cell) has its own Owen-scrambled
//!   Sobol (0, 2)-sequence ([`crate::image::sampler::owen_sobol_02`]), seeded by the run's seed
//!   and the cell, and a slot holding `n` samples takes the next points `n, n + 1, ...` of it.
//!   So the base samples of a slot and the batches later rounds add to it are one prefix of a
//!   (0, 2)-sequence: `2^m` of them are a `(0, m, 2)`-net of the slot (one point in every
//!   elementary interval of area `2^-m` of the rectangle), whatever the batch sizes, and a
//!   batch that is an aligned block of `2^k` indices is a net on its own. The points depend
//!   only on the seed, the cell and the count, so a renderer driving the plan through files
//!   gets the same points as one long in-process call. (A child of a deepened slot holds some
//!   of its parent's points and continues its own sequence from their count: its union is
//!   then stratified by the parent's net and its own, not one net.)
//! * [`PositionPattern::Stratified`]: a `k x k` grid (`k^2 >= need`) per batch, `need` of its
//!   strata chosen at random, one uniform point in each, one PCG-64 stream per round (the
//!   pattern of state files written before the choice).

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};
use thiserror::Error;

use std::collections::HashMap;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use crate::adaptive::marking::spread;
use crate::adaptive::{Cell, QuadTree};
use crate::image::sampler::owen_sobol_02;

/// Where a slot's positions go (`ImageSampling::pattern`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PositionPattern {
    /// Per slot, the continued Owen-scrambled Sobol (0, 2)-sequence.
    #[default]
    Sobol,
    /// Per batch, jittered strata chosen at random.
    Stratified,
}

impl PositionPattern {
    /// Every pattern, the default first.
    pub const ALL: [PositionPattern; 2] = [PositionPattern::Sobol, PositionPattern::Stratified];

    /// The name on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            PositionPattern::Sobol => "sobol",
            PositionPattern::Stratified => "stratified",
        }
    }
}

impl fmt::Display for PositionPattern {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A pattern name that is not one of [`PositionPattern::ALL`].
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown position pattern `{name}`: expected sobol or stratified")]
pub struct ParsePatternError {
    /// The name as given.
    pub name: String,
}

impl FromStr for PositionPattern {
    type Err = ParsePatternError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let t = s.trim().to_ascii_lowercase();
        PositionPattern::ALL
            .into_iter()
            .find(|p| p.name() == t)
            .ok_or_else(|| ParsePatternError {
                name: s.to_string(),
            })
    }
}

/// Draws a round's positions by a [`PositionPattern`]: the round's PCG-64 stream for the
/// stratified pattern, the seed for the slots' sequences.
pub(super) struct Placer {
    pattern: PositionPattern,
    seed: u64,
    rng: Pcg64,
}

impl Placer {
    /// The placer of round `round` (0: the base positions) of a run seeded by `seed`.
    pub(super) fn new(pattern: PositionPattern, seed: u64, round: usize) -> Self {
        Self {
            pattern,
            seed,
            rng: round_rng(seed, round),
        }
    }

    /// Appends `need` positions in slot `cell` (rectangle `rect`) that holds `have` samples.
    pub(super) fn place(
        &mut self,
        out: &mut SamplePositions,
        cell: Cell,
        rect: [f64; 4],
        have: usize,
        need: usize,
    ) {
        match self.pattern {
            PositionPattern::Stratified => out.stratified(rect, need, &mut self.rng),
            PositionPattern::Sobol => out.append(slot_sobol(self.seed, cell, rect, have, need)),
        }
    }
}

/// The two scramble seeds of a slot's sequence: SplitMix64 of the run's seed and the cell.
fn slot_seeds(seed: u64, cell: Cell) -> [u32; 2] {
    let mut z = seed
        ^ (cell.step as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (cell.kx as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9)
        ^ (cell.ky as u64).wrapping_mul(0x94D0_49BB_1331_11EB);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    [z as u32, (z >> 32) as u32]
}

/// Sample positions (pixel units) the refiner asks a renderer for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SamplePositions {
    /// x positions.
    pub xs: Vec<f64>,
    /// y positions.
    pub ys: Vec<f64>,
}

impl SamplePositions {
    /// Number of positions.
    pub fn len(&self) -> usize {
        self.xs.len()
    }
    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.xs.is_empty()
    }

    /// Appends `need` jittered-stratified positions in `rect`: a `k x k` grid (`k^2 >= need`),
    /// `need` of its strata chosen at random, one uniform point in each.
    pub(crate) fn stratified(&mut self, rect: [f64; 4], need: usize, rng: &mut Pcg64) {
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
            self.xs
                .push((rect[0] + (i as f64 + rng.random::<f64>()) * dx).min(rect[1]));
            self.ys
                .push((rect[2] + (j as f64 + rng.random::<f64>()) * dy).min(rect[3]));
        }
    }
}

impl SamplePositions {
    /// Appends `other`'s positions.
    fn append(&mut self, other: SamplePositions) {
        self.xs.extend(other.xs);
        self.ys.extend(other.ys);
    }
}

/// Points `start .. start + need` of slot `cell`'s sequence under the run's `seed`
/// ([`PositionPattern::Sobol`]): the Owen-scrambled Sobol (0, 2)-sequence with the cell's
/// scramble seeds, stretched to the slot's rectangle `rect` (`[x0, x1, y0, y1]`, pixel
/// units). Drawing `a` points and then `b` from `a` gives the `a + b` points of one draw.
pub fn slot_sobol(
    seed: u64,
    cell: Cell,
    rect: [f64; 4],
    start: usize,
    need: usize,
) -> SamplePositions {
    let seeds = slot_seeds(seed, cell);
    let mut out = SamplePositions::default();
    for i in start..start + need {
        let (u, v) = owen_sobol_02(i as u32, seeds);
        out.xs
            .push((rect[0] + u * (rect[1] - rect[0])).min(rect[1]));
        out.ys
            .push((rect[2] + v * (rect[3] - rect[2])).min(rect[3]));
    }
    out
}

/// The PCG-64 stream of round `round` (0: the base positions) of a run seeded by `seed`.
pub(super) fn round_rng(seed: u64, round: usize) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ (round as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// Spreads `extra` samples over `slots` (holding `counts`) with weights `weights`
/// (`super::super::marking::spread`), placed by `placer` in each slot's rectangle of `tree`,
/// in slot order. Returns the samples added and the least count after.
pub(super) fn spread_samples(
    tree: &QuadTree,
    slots: &[Cell],
    counts: &HashMap<Cell, usize>,
    weights: &[f64],
    extra: usize,
    next: &mut SamplePositions,
    placer: &mut Placer,
) -> (usize, usize) {
    let have: Vec<usize> = slots
        .iter()
        .map(|s| counts.get(s).copied().unwrap_or(0))
        .collect();
    let add = spread(weights, &have, extra);
    for ((s, &a), &h) in slots.iter().zip(&add).zip(&have) {
        placer.place(next, *s, tree.rect(*s), h, a);
    }
    let least = have.iter().zip(&add).map(|(h, a)| h + a).min().unwrap_or(0);
    (add.iter().sum(), least)
}
