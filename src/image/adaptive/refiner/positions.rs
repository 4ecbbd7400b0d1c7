//! Drawing the sample positions the refiner asks for: jittered-stratified positions in a
//! slot's rectangle, one PCG-64 stream per round.

use std::collections::HashMap;

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use crate::adaptive::marking::{spread, SpreadRule};
use crate::adaptive::{Cell, QuadTree};

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

/// The PCG-64 stream of round `round` (0: the base positions) of a run seeded by `seed`.
pub(super) fn round_rng(seed: u64, round: usize) -> Pcg64 {
    Pcg64::seed_from_u64(seed ^ (round as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// Spreads `extra` samples over `slots` (holding `counts`) by `rule`
/// ([`super::super::marking::spread`], weights `eta`), jittered-stratified in each slot's
/// rectangle of `tree`, in slot order. Returns the samples added and the least count after.
#[allow(clippy::too_many_arguments)]
pub(super) fn spread_samples(
    tree: &QuadTree,
    slots: &[Cell],
    counts: &HashMap<Cell, usize>,
    eta: &HashMap<Cell, f64>,
    rule: SpreadRule,
    extra: usize,
    next: &mut SamplePositions,
    rng: &mut Pcg64,
) -> (usize, usize) {
    let have: Vec<usize> = slots
        .iter()
        .map(|s| counts.get(s).copied().unwrap_or(0))
        .collect();
    let weights: Vec<f64> = match rule {
        SpreadRule::Uniform => vec![1.0; slots.len()],
        SpreadRule::Indicator => slots
            .iter()
            .map(|s| eta.get(s).copied().unwrap_or(0.0))
            .collect(),
    };
    let add = spread(&weights, &have, extra);
    for (s, &a) in slots.iter().zip(&add) {
        next.stratified(tree.rect(*s), a, rng);
    }
    let least = have.iter().zip(&add).map(|(h, a)| h + a).min().unwrap_or(0);
    (add.iter().sum(), least)
}
