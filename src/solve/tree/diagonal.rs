//! The exact diagonal `G_aa = sum_i Psi_a(x_i, y_i)^2` of the tree's normal matrix, from
//! one pass of the multilevel evaluator over the samples, continued from round to round:
//! PCG's Jacobi preconditioner.
//!
//! Each sample is evaluated only to the depth of the tree around it ([`StepReach`]): a
//! function of step `s` is nonzero only inside its structural support, so where no tree
//! function of step `s` or deeper reaches a sample, the evaluation stops above `s` (the
//! deeper levels' scaling functions are the evaluation's largest cost). The terms kept are
//! the same, added in the same order: the sums are those of the whole evaluation bit for
//! bit (`tests/image_adaptive_pcg.rs`).

use rayon::prelude::*;

use crate::adaptive::tree::quad::QuadTree;

/// The exact diagonal `G_aa = sum_i Psi_a(x_i, y_i)^2` of a tree's normal matrix over the
/// first `samples` samples, kept so that the next round continues it: a round's samples are
/// the previous ones plus new ones and its tree holds the previous tree, so
///
/// ```text
/// G'_aa = G_aa + sum_{new i} Psi_a(x_i)^2                         (a in the previous tree),
/// G'_aa = sum_{old i in supp a} Psi_a(x_i)^2 + sum_{new i} ...     (a new function),
/// ```
///
/// the old samples evaluated only where a new function's support covers them (new functions
/// sit in the marked cells). The sums are added in another order than a rebuild's, so the
/// bits differ by rounding; the diagonal only preconditions CG.
#[derive(Clone, Debug)]
pub struct DiagonalSums {
    /// Samples summed over.
    pub(super) samples: usize,
    /// [`positions_hash`] of the samples summed over: a continuation checks that they are a
    /// prefix of its samples, in order.
    pub(super) positions: u64,
    /// The tree's functions (Mallat layout).
    pub(super) mask: Vec<bool>,
    pub(super) sums: Vec<f64>,
}

/// An order-dependent hash of positions (their bits, one 64-bit mix per coordinate).
pub(crate) fn positions_hash(xs: &[f64], ys: &[f64]) -> u64 {
    xs.iter().zip(ys).fold(0x243F_6A88_85A3_08D3, |h, (x, y)| {
        crate::image::adaptive::oracle::mix64(
            crate::image::adaptive::oracle::mix64(h ^ x.to_bits()) ^ y.to_bits(),
        )
    })
}

impl DiagonalSums {
    /// The diagonal of `tree` over the samples `(xs, ys)`, continuing `previous` when it is
    /// a prefix of them on a subtree (otherwise summed afresh).
    pub fn new(tree: &QuadTree, xs: &[f64], ys: &[f64], previous: Option<&Self>) -> Self {
        let basis = tree.basis();
        let mut mask = vec![false; basis.len()];
        for f in tree.functions() {
            mask[f] = true;
        }
        let usable = previous.filter(|d| {
            d.continues(xs, ys)
                && d.mask.len() == mask.len()
                && d.mask.iter().zip(&mask).all(|(&was, &is)| !was || is)
        });
        let positions = positions_hash(xs, ys);
        let Some(previous) = usable else {
            let sums = exact_diagonal(tree, &mask, xs, ys);
            return Self {
                samples: xs.len(),
                positions,
                mask,
                sums,
            };
        };
        let old = previous.samples;
        let mut sums = previous.sums.clone();
        let add = |sums: &mut Vec<f64>, part: Vec<f64>| {
            for (s, v) in sums.iter_mut().zip(part) {
                *s += v;
            }
        };
        add(
            &mut sums,
            exact_diagonal(tree, &mask, &xs[old..], &ys[old..]),
        );
        let fresh: Vec<bool> = mask
            .iter()
            .zip(&previous.mask)
            .map(|(&is, &was)| is && !was)
            .collect();
        if fresh.iter().any(|&f| f) {
            let covered = support_cover(tree, &fresh);
            let (w, _) = tree.cell_dims(tree.steps());
            let (cx, cy): (Vec<f64>, Vec<f64>) = xs[..old]
                .iter()
                .zip(&ys[..old])
                .filter(|(&x, &y)| {
                    let c = tree.cell_at(tree.steps(), x, y);
                    covered[c.ky * w + c.kx]
                })
                .map(|(&x, &y)| (x, y))
                .unzip();
            add(&mut sums, exact_diagonal(tree, &fresh, &cx, &cy));
        }
        Self {
            samples: xs.len(),
            positions,
            mask,
            sums,
        }
    }

    /// Whether the samples summed over are the first of `(xs, ys)`, in order, on a basis of
    /// the same size (the condition to continue the sums with the rest).
    pub fn continues(&self, xs: &[f64], ys: &[f64]) -> bool {
        self.samples <= xs.len()
            && self.sums.len() == self.mask.len()
            && positions_hash(&xs[..self.samples], &ys[..self.samples]) == self.positions
    }

    /// Samples summed over.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// `G_aa` per function (full Mallat layout, 0 off the tree).
    pub fn sums(&self) -> &[f64] {
        &self.sums
    }
}

/// The cells of the deepest step (row-major) inside the support of a function of `functions`
/// (a mask over the Mallat layout; no coarse scaling function among them): per axis, the
/// structural support of the function's level ([`crate::basis::support_cells`]).
fn support_cover(tree: &QuadTree, functions: &[bool]) -> Vec<bool> {
    let steps = tree.steps();
    let (w, h) = tree.cell_dims(steps);
    let (cx, cy) = tree.basis().coarse_levels();
    let p = tree.basis().p();
    let mut covered = vec![false; w * h];
    for (f, _) in functions.iter().enumerate().filter(|(_, &m)| m) {
        let cell = tree
            .cell_of_function(f)
            .expect("coarse scaling functions are in every tree");
        let scale = 1usize << (steps - cell.step);
        let (x0, x1) = crate::basis::support_cells(p, cx + cell.step, cell.kx);
        let (y0, y1) = crate::basis::support_cells(p, cy + cell.step, cell.ky);
        for ky in y0 as usize * scale..(y1 as usize + 1) * scale {
            covered[ky * w + x0 as usize * scale..(x1 as usize + 1) * scale + ky * w]
                .iter_mut()
                .for_each(|c| *c = true);
        }
    }
    covered
}

/// Parts of the exact diagonal's sum (fixed, so the sum's order does not depend on threads).
const DIAGONAL_PARTS: usize = 8;

/// Per step `s`, the cells of step `s` inside the structural support of a function of
/// `functions` (a mask over the Mallat layout) of step `s`, grown by one cell on each side
/// (a sample on a cell's edge is inside whichever cell [`QuadTree::cell_at`] gives): at a
/// sample outside every grown support of the steps `s` and deeper, the functions of those
/// steps vanish.
struct StepReach {
    /// Per step, row-major over the step's cells.
    reach: Vec<Vec<bool>>,
}

impl StepReach {
    fn new(tree: &QuadTree, functions: &[bool]) -> Self {
        let steps = tree.steps();
        let (cx, cy) = tree.basis().coarse_levels();
        let p = tree.basis().p();
        let mut reach: Vec<Vec<bool>> = (0..steps)
            .map(|s| {
                let (w, h) = tree.cell_dims(s);
                vec![false; w * h]
            })
            .collect();
        for (f, _) in functions.iter().enumerate().filter(|(_, &m)| m) {
            let Some(cell) = tree.cell_of_function(f) else {
                continue; // a coarse scaling function: always evaluated
            };
            let (w, h) = tree.cell_dims(cell.step);
            let (x0, x1) = crate::basis::support_cells(p, cx + cell.step, cell.kx);
            let (y0, y1) = crate::basis::support_cells(p, cy + cell.step, cell.ky);
            let grid = &mut reach[cell.step as usize];
            let (x0, x1) = (
                (x0 as usize).saturating_sub(1),
                (x1 as usize + 1).min(w - 1),
            );
            let (y0, y1) = (
                (y0 as usize).saturating_sub(1),
                (y1 as usize + 1).min(h - 1),
            );
            for ky in y0..=y1 {
                grid[ky * w + x0..=ky * w + x1].fill(true);
            }
        }
        Self { reach }
    }

    /// The steps to evaluate at `(x, y)`: one past the deepest step whose grown supports
    /// reach it (0: the coarse scaling functions only).
    fn steps_at(&self, tree: &QuadTree, x: f64, y: f64) -> u32 {
        (0..self.reach.len() as u32)
            .rev()
            .find(|&s| {
                let c = tree.cell_at(s, x, y);
                let (w, _) = tree.cell_dims(s);
                self.reach[s as usize][c.ky * w + c.kx]
            })
            .map_or(0, |s| s + 1)
    }
}

/// `G_aa = sum_i Psi_a(x_i, y_i)^2` on the tree (`mask`), from the multilevel evaluator
/// (each sample to the steps the tree's functions reach there, [`StepReach`]).
fn exact_diagonal(tree: &QuadTree, mask: &[bool], xs: &[f64], ys: &[f64]) -> Vec<f64> {
    let basis = tree.basis();
    let reach = StepReach::new(tree, mask);
    let part = xs.len().div_ceil(DIAGONAL_PARTS).max(1);
    let parts: Vec<Vec<f64>> = xs
        .par_chunks(part)
        .zip(ys.par_chunks(part))
        .map(|(cx, cy)| {
            let mut ev = basis.multilevel_evaluator();
            let mut acc = vec![0.0; mask.len()];
            for (&x, &y) in cx.iter().zip(cy) {
                ev.for_each_steps(x, y, reach.steps_at(tree, x, y), |index, value| {
                    if mask[index] {
                        acc[index] += value * value;
                    }
                })
                .expect("positions are checked before the solve");
            }
            acc
        })
        .collect();
    let mut total = vec![0.0; mask.len()];
    for p in parts {
        for (t, v) in total.iter_mut().zip(p) {
            *t += v;
        }
    }
    total
}
