//! The adaptive basis as a tree: the coarse scaling functions `phi_{n,k}` and a set of wavelets
//! closed under "parent present" (parent of `psi_{j,k}` is `psi_{j-1, floor(k/2)}`; the level-`n`
//! wavelets hang off the scaling functions, which are always present).
//!
//! Structural supports, in level-`j` cells `[c 2^-j, (c+1) 2^-j)` of the unit interval (the
//! cells at which [`crate::basis::Evaluator`] reports a function): an interior function `k`
//! covers cells `k - p + 1 ..= k + p - 1`, the left edge function `k < p` cells `0 ..= p + k - 1`,
//! the right edge function `2^j - 1 - r` cells `2^j - p - r ..= 2^j - 1`. A child's support lies
//! inside its parent's, so the region `R_j` where some active level-`j` wavelet lives shrinks as
//! `j` grows, and the points of local depth `d` (in `R_d` but not `R_{d+1}`) are whole level-`d+1`
//! cells: the leaves.

use std::collections::BTreeSet;
use std::sync::Arc;

pub use crate::basis::{cell_of, support_cells};
use crate::basis::{BasisError, CdvBasis, FilterBank, FunctionId, FunctionKind};
use crate::kernel::ActiveSet;
use crate::sampling::Domain;

/// Deepest wavelet level the refiner accepts: a level-52 leaf of the unit interval is
/// `2^-52`, two ulps near 1, so the resolution of `f64` ends the refinement before (stop
/// reason `Resolution`: near `t = 0.6` at depth ~48, nearer to 0 deeper). Every sample caches
/// the values of its `(D - n + 2)(2p - 1)` structurally nonzero functions (16 bytes each).
pub const MAX_DEPTH_LIMIT: u32 = 52;

/// Deepest tree [`WaveletTree::active_set`] converts: the evaluator's limit (an [`ActiveSet`]
/// of a sparse or deep tree looks columns up by binary search instead of a dense map).
pub const ACTIVE_SET_MAX_LEVEL: u32 = crate::basis::MAX_LEVEL;

/// A leaf of the tree: the level-`level` cell `cell` of the unit interval, on which the local
/// depth is `level - 1` (one slot of the local space `V_level`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Leaf {
    /// Level of the cell (local depth + 1).
    pub level: u32,
    /// Index of the cell within its level.
    pub cell: u64,
}

impl Leaf {
    /// Local depth on the leaf.
    pub fn depth(&self) -> i32 {
        self.level as i32 - 1
    }
    /// The leaf as `[lo, hi)` in unit coordinates (exact dyadic numbers).
    pub fn unit_bounds(&self) -> (f64, f64) {
        let w = (-(self.level as f64)).exp2();
        (self.cell as f64 * w, (self.cell + 1) as f64 * w)
    }
    /// Whether `t` (unit coordinates) lies in the leaf (by [`cell_of`]).
    pub fn contains(&self, t: f64) -> bool {
        cell_of(t, self.level) == self.cell
    }
}

/// An adaptive subset of `Psi(n, D)`, `D` the depth limit: the `2^n` coarse scaling functions
/// plus wavelets closed under "parent present".
#[derive(Clone, Debug)]
pub struct WaveletTree {
    bank: Arc<FilterBank>,
    coarse: u32,
    max_level: u32,
    domain: Domain,
    wavelets: BTreeSet<usize>,
    /// Per level `coarse..=max_level`: merged inclusive cell ranges covered by active wavelets.
    coverage: Vec<Vec<(u64, u64)>>,
}

impl WaveletTree {
    /// The uniform tree: scaling functions of level `coarse` and every wavelet of the levels
    /// `coarse..=depth` (`depth < coarse` gives no wavelets), with wavelets allowed up to level
    /// `max_level`.
    pub fn uniform(
        bank: Arc<FilterBank>,
        coarse: u32,
        depth: i32,
        max_level: u32,
        domain: Domain,
    ) -> Result<Self, BasisError> {
        // Validates p, coarse >= j_min(p) and the level range.
        CdvBasis::with_bank(bank.clone(), coarse, max_level.max(coarse), domain)?;
        let mut wavelets = BTreeSet::new();
        let top = depth.min(max_level as i32);
        if top >= coarse as i32 {
            wavelets.extend((1usize << coarse)..(1usize << (top + 1)));
        }
        let mut tree = Self {
            bank,
            coarse,
            max_level: max_level.max(coarse),
            domain,
            wavelets,
            coverage: Vec::new(),
        };
        tree.rebuild_coverage();
        Ok(tree)
    }

    /// Vanishing moments `p`.
    pub fn p(&self) -> usize {
        self.bank.p()
    }
    /// The filter bank.
    pub fn bank(&self) -> &Arc<FilterBank> {
        &self.bank
    }
    /// Coarse scaling level `n`.
    pub fn coarse(&self) -> u32 {
        self.coarse
    }
    /// The deepest wavelet level the tree may grow to.
    pub fn max_level(&self) -> u32 {
        self.max_level
    }
    /// The domain.
    pub fn domain(&self) -> Domain {
        self.domain
    }
    /// Number of active functions (scaling functions included).
    pub fn len(&self) -> usize {
        (1usize << self.coarse) + self.wavelets.len()
    }
    /// Whether the tree is empty (never: the scaling functions are always present).
    pub fn is_empty(&self) -> bool {
        false
    }
    /// Active wavelets, ascending global index (level, then position).
    pub fn wavelets(&self) -> impl Iterator<Item = usize> + '_ {
        self.wavelets.iter().copied()
    }
    /// All active global indices, ascending.
    pub fn indices(&self) -> impl Iterator<Item = usize> + '_ {
        (0..(1usize << self.coarse)).chain(self.wavelets())
    }
    /// Whether global index `a` is active.
    pub fn contains(&self, a: usize) -> bool {
        a < (1usize << self.coarse) || self.wavelets.contains(&a)
    }
    /// Describes global index `a`.
    pub fn function(&self, a: usize) -> FunctionId {
        FunctionId::from_index(a, self.coarse, self.bank.edge_count())
    }
    /// The finest active wavelet level, or `n - 1` without wavelets.
    pub fn depth(&self) -> i32 {
        self.wavelets
            .last()
            .map_or(self.coarse as i32 - 1, |&a| self.function(a).level as i32)
    }
    /// Active wavelets per level, for levels `n..=depth`.
    pub fn level_counts(&self) -> Vec<usize> {
        let mut counts = vec![0usize; (self.depth() + 1 - self.coarse as i32).max(0) as usize];
        for a in self.wavelets() {
            counts[(self.function(a).level - self.coarse) as usize] += 1;
        }
        counts
    }

    /// The parent of wavelet `a` (`None` for scaling functions; a scaling function for the
    /// level-`n` wavelets).
    pub fn parent(&self, a: usize) -> Option<usize> {
        let id = self.function(a);
        match id.kind {
            FunctionKind::Scaling => None,
            FunctionKind::Wavelet if id.level == self.coarse => Some(id.index),
            FunctionKind::Wavelet => Some((1usize << (id.level - 1)) + id.index / 2),
        }
    }

    /// The children of `a`: `psi_{j+1,2k}` and `psi_{j+1,2k+1}` for a wavelet, `psi_{n,k}` for a
    /// scaling function; empty beyond the depth limit.
    pub fn children(&self, a: usize) -> Vec<usize> {
        let id = self.function(a);
        match id.kind {
            FunctionKind::Scaling => vec![(1usize << self.coarse) + id.index],
            FunctionKind::Wavelet if id.level >= self.max_level => vec![],
            FunctionKind::Wavelet => {
                let base = 1usize << (id.level + 1);
                vec![base + 2 * id.index, base + 2 * id.index + 1]
            }
        }
    }

    /// Structural support of global index `a` as an inclusive range of cells of its level.
    pub fn support(&self, a: usize) -> (u32, u64, u64) {
        let id = self.function(a);
        let (lo, hi) = support_cells(self.p(), id.level, id.index);
        (id.level, lo, hi)
    }

    /// Structural support of `a` as `[lo, hi]` in unit coordinates.
    pub fn support_unit(&self, a: usize) -> (f64, f64) {
        let (level, lo, hi) = self.support(a);
        let w = (-(level as f64)).exp2();
        (lo as f64 * w, (hi + 1) as f64 * w)
    }

    /// Adds wavelet `a` and every missing ancestor (keeps the tree closed). Indices beyond the
    /// depth limit and scaling functions are ignored. Returns the number of functions added.
    pub fn insert(&mut self, a: usize) -> usize {
        let added = self.insert_quiet(a);
        if added > 0 {
            self.rebuild_coverage();
        }
        added
    }

    /// [`WaveletTree::insert`] for many wavelets; the returned vector lists every function
    /// added (ancestors included), ascending.
    pub fn extend(&mut self, wavelets: impl IntoIterator<Item = usize>) -> Vec<usize> {
        let before = self.wavelets.clone();
        let mut any = 0;
        for a in wavelets {
            any += self.insert_quiet(a);
        }
        if any == 0 {
            return Vec::new();
        }
        self.rebuild_coverage();
        self.wavelets.difference(&before).copied().collect()
    }

    /// Deepens the tree by one level where flagged: adds the children of every flagged active
    /// function (within the depth limit). Returns the functions added, ascending.
    pub fn deepen(&mut self, flagged: &[usize]) -> Vec<usize> {
        let children: Vec<usize> = flagged
            .iter()
            .filter(|&&a| self.contains(a))
            .flat_map(|&a| self.children(a))
            .collect();
        self.extend(children)
    }

    fn insert_quiet(&mut self, a: usize) -> usize {
        if a < (1usize << self.coarse) || self.wavelets.contains(&a) {
            return 0;
        }
        if self.function(a).level > self.max_level {
            return 0;
        }
        let mut added = 0;
        let mut cur = Some(a);
        while let Some(c) = cur.filter(|&c| c >= (1usize << self.coarse)) {
            if !self.wavelets.insert(c) {
                break;
            }
            added += 1;
            cur = self.parent(c);
        }
        added
    }

    fn rebuild_coverage(&mut self) {
        let levels = (self.max_level - self.coarse + 1) as usize;
        let mut coverage: Vec<Vec<(u64, u64)>> = vec![Vec::new(); levels];
        let p = self.p();
        for &a in &self.wavelets {
            let id = FunctionId::from_index(a, self.coarse, self.bank.edge_count());
            let (lo, hi) = support_cells(p, id.level, id.index);
            let ranges = &mut coverage[(id.level - self.coarse) as usize];
            // Ascending index gives ascending `lo` within a level (edges included).
            match ranges.last_mut() {
                Some(last) if lo <= last.1 + 1 => last.1 = last.1.max(hi),
                _ => ranges.push((lo, hi)),
            }
        }
        self.coverage = coverage;
    }

    /// Whether the level-`level` cell `cell` lies in the support of an active level-`level`
    /// wavelet.
    pub fn covered(&self, level: u32, cell: u64) -> bool {
        if level < self.coarse || level > self.max_level {
            return false;
        }
        let ranges = &self.coverage[(level - self.coarse) as usize];
        let i = ranges.partition_point(|r| r.1 < cell);
        ranges.get(i).is_some_and(|r| r.0 <= cell)
    }

    /// Local depth at `t` in `[0, 1]`: the finest level of an active wavelet whose support
    /// contains `t`, or `n - 1` if none.
    pub fn local_depth_unit(&self, t: f64) -> i32 {
        let top = self.depth();
        let mut j = top;
        while j >= self.coarse as i32 {
            if self.covered(j as u32, cell_of(t, j as u32)) {
                return j;
            }
            j -= 1;
        }
        self.coarse as i32 - 1
    }

    /// Local depth at domain position `x` (clamped into the domain).
    pub fn local_depth(&self, x: f64) -> i32 {
        self.local_depth_unit(self.domain.to_unit(x).clamp(0.0, 1.0))
    }

    /// The leaves, left to right: the partition of `[0, 1]` into cells of level `d + 1` on which
    /// the local depth is `d`.
    pub fn leaves(&self) -> Vec<Leaf> {
        let mut out = Vec::new();
        let mut stack: Vec<Leaf> = (0..(1u64 << self.coarse))
            .rev()
            .map(|cell| Leaf {
                level: self.coarse,
                cell,
            })
            .collect();
        while let Some(leaf) = stack.pop() {
            if self.covered(leaf.level, leaf.cell) {
                stack.push(Leaf {
                    level: leaf.level + 1,
                    cell: 2 * leaf.cell + 1,
                });
                stack.push(Leaf {
                    level: leaf.level + 1,
                    cell: 2 * leaf.cell,
                });
            } else {
                out.push(leaf);
            }
        }
        out
    }

    /// `Psi(n, F)` on the domain, `F = max(depth, n)`: the smallest full basis holding the tree.
    pub fn basis(&self) -> Result<CdvBasis, BasisError> {
        let fine = self.depth().max(self.coarse as i32) as u32;
        CdvBasis::with_bank(self.bank.clone(), self.coarse, fine, self.domain)
    }

    /// The columns of `K`: every active global index, ascending (column `c` is `columns[c]`,
    /// the order of [`ActiveSet`]; look one up with [`ActiveSet::column`]).
    pub fn columns(&self) -> Vec<usize> {
        self.indices().collect()
    }

    /// The active set (columns of `K` in ascending global index) over [`WaveletTree::basis`];
    /// refuses trees deeper than [`ACTIVE_SET_MAX_LEVEL`].
    pub fn active_set(&self) -> Result<ActiveSet, BasisError> {
        let depth = self.depth().max(0) as u32;
        if depth > ACTIVE_SET_MAX_LEVEL {
            return Err(BasisError::FineLevelTooDeep {
                fine: depth,
                max: ACTIVE_SET_MAX_LEVEL,
            });
        }
        Ok(ActiveSet::from_indices(self.basis()?, self.indices()))
    }
}

/// The part of the ascending unit positions `sorted` inside `leaf`.
pub(crate) fn range_in<'a>(sorted: &'a [f64], leaf: &Leaf) -> &'a [f64] {
    let (lo, hi) = leaf.unit_bounds();
    let last = leaf.cell + 1 == 1u64 << leaf.level;
    let a = sorted.partition_point(|&t| t < lo);
    let b = if last {
        sorted.len()
    } else {
        sorted.partition_point(|&t| t < hi)
    };
    &sorted[a..b.max(a)]
}
