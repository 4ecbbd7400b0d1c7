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
            PositionPattern::Sobol => out.append(slot_points(self.seed, cell, rect, have, need)),
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
    pub(super) fn append(&mut self, other: SamplePositions) {
        self.xs.extend(other.xs);
        self.ys.extend(other.ys);
    }

    /// Appends the point `(u, v)` of the unit square stretched to `rect` (`[x0, x1, y0, y1]`),
    /// kept inside it where rounding would carry it over the far edge.
    fn push_in(&mut self, rect: [f64; 4], u: f64, v: f64) {
        self.xs
            .push((rect[0] + u * (rect[1] - rect[0])).min(rect[1]));
        self.ys
            .push((rect[2] + v * (rect[3] - rect[2])).min(rect[3]));
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
        out.push_in(rect, u, v);
    }
    out
}

/// Points `start .. start + need` of slot `cell` (rectangle `rect`) under
/// [`PositionPattern::Sobol`]. A slot no smaller than a pixel takes its own sequence
/// ([`slot_sobol`]). A slot smaller than a pixel (the depth limit's) takes the points of its
/// *anchor*'s sequence that fall in it, the anchor being its ancestor `d` steps up, the
/// smallest no smaller than a pixel: every aligned block `[k 4^d, (k + 1) 4^d)` of the
/// anchor's (0, 2)-sequence is a `(0, 2d, 2)`-net, so it holds exactly one point in each of
/// the `2^d x 2^d` sub-cells, and point `k` of the slot is the block `k`'s point in it. So
/// the children of a deepened pixel, whatever their counts `n_q`, hold together the first
/// `4 min_q n_q` points of the pixel's own sequence and one point of each later block they
/// reached: the pixel's samples keep the stratification of one (0, 2)-sequence (its 1D
/// projections too), where four independent sequences of the children would be stratified
/// only within each child. Where the parent's points already lie in a child, they are the
/// child's first points (a slot that held `n = 4 j` points of its sequence, once deepened,
/// continues that sequence exactly). The points depend only on the seed, the cells and the
/// count, as the slots' own sequences do.
pub(super) fn slot_points(
    seed: u64,
    cell: Cell,
    rect: [f64; 4],
    start: usize,
    need: usize,
) -> SamplePositions {
    let (w, h) = (rect[1] - rect[0], rect[3] - rect[2]);
    let mut d = 0u32;
    while d < cell.step
        && d < 15
        && (w * f64::from(1u32 << d) < 1.0 || h * f64::from(1u32 << d) < 1.0)
    {
        d += 1;
    }
    if d == 0 {
        return slot_sobol(seed, cell, rect, start, need);
    }
    let side = 1usize << d;
    let anchor = Cell {
        step: cell.step - d,
        kx: cell.kx >> d,
        ky: cell.ky >> d,
    };
    let (qx, qy) = (cell.kx & (side - 1), cell.ky & (side - 1));
    let seeds = slot_seeds(seed, anchor);
    let block = side * side;
    let mut out = SamplePositions::default();
    for k in start..start + need {
        // the point of block k in sub-cell (qx, qy); the net property guarantees one
        let found = (k * block..(k + 1) * block).find_map(|i| {
            let (u, v) = owen_sobol_02(i as u32, seeds);
            let (a, b) = (u * side as f64, v * side as f64);
            (a.floor() as usize == qx && b.floor() as usize == qy)
                .then_some((a - qx as f64, b - qy as f64))
        });
        // never taken (a block of a (0, 2)-sequence is a net); the slot's own point if it were
        let (u, v) = found.unwrap_or_else(|| owen_sobol_02(k as u32, slot_seeds(seed, cell)));
        out.push_in(rect, u, v);
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

#[cfg(test)]
mod tests {
    use super::*;

    fn sorted(p: &SamplePositions) -> Vec<(f64, f64)> {
        let mut v: Vec<(f64, f64)> = p.xs.iter().copied().zip(p.ys.iter().copied()).collect();
        v.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        v
    }

    /// The four half-pixel children of pixel `(5, 9)` (a cell of step 3 whose rectangle is
    /// the pixel), each drawing `n` points from 0 by [`slot_points`], hold together exactly
    /// the pixel's own first `4 n` points ([`slot_sobol`]): bit for bit, as sets (the
    /// coordinates are sums of dyadic fractions, exact in `f64`). A child drawing on from the
    /// points of the pixel's sequence already in it continues the same sequence; the points
    /// lie in the child's rectangle. Independent sequences per child (the rule before) fail
    /// the first check.
    #[test]
    fn children_of_a_pixel_share_the_pixels_sequence() {
        let pixel = Cell {
            step: 3,
            kx: 5,
            ky: 9,
        };
        let prect = [5.0, 6.0, 9.0, 10.0];
        for seed in [1u64, 7, 12345] {
            for n in [1usize, 2, 3, 5, 8] {
                let mut union = SamplePositions::default();
                for q in 0..4 {
                    let child = Cell {
                        step: 4,
                        kx: 2 * pixel.kx + (q & 1),
                        ky: 2 * pixel.ky + (q >> 1),
                    };
                    let r = [
                        5.0 + 0.5 * (q & 1) as f64,
                        5.5 + 0.5 * (q & 1) as f64,
                        9.0 + 0.5 * (q >> 1) as f64,
                        9.5 + 0.5 * (q >> 1) as f64,
                    ];
                    let pts = slot_points(seed, child, r, 0, n);
                    for (&x, &y) in pts.xs.iter().zip(&pts.ys) {
                        assert!(x >= r[0] && x < r[1] && y >= r[2] && y < r[3]);
                    }
                    // drawing a points, then the rest, gives the same points
                    let mut split = slot_points(seed, child, r, 0, n / 2);
                    split.append(slot_points(seed, child, r, n / 2, n - n / 2));
                    assert_eq!(split, pts);
                    union.append(pts);
                }
                let own = slot_sobol(seed, pixel, prect, 0, 4 * n);
                assert_eq!(sorted(&union), sorted(&own), "seed {seed}, n = {n}");
            }
        }
    }

    /// A slot no smaller than a pixel keeps its own sequence.
    #[test]
    fn slots_of_a_pixel_or_more_keep_their_own_sequence() {
        let cell = Cell {
            step: 2,
            kx: 1,
            ky: 3,
        };
        for rect in [[2.0, 4.0, 6.0, 8.0], [1.0, 2.0, 3.0, 4.0]] {
            assert_eq!(
                slot_points(3, cell, rect, 2, 6),
                slot_sobol(3, cell, rect, 2, 6)
            );
        }
    }
}
