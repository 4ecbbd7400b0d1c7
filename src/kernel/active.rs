//! The set of active basis functions: the columns of `K`.

use std::sync::OnceLock;

use crate::basis::{cell_of, support_cells, BasisValue, CdvBasis, FunctionId};

/// Marks a global index that is not active.
const INACTIVE: u32 = u32::MAX;

/// Largest enclosing dimension for which a dense column map (4 bytes per function of
/// `Psi(n, N)`) is kept; sparser or deeper sets use binary search in the sorted columns.
const DENSE_MAP_LIMIT: usize = 1 << 24;

/// A set of active functions of an enclosing `Psi(n, N)`: uniformly all of them, or (for the
/// adaptive tree of the refiner) any subset; column `c` of `K` is the `c`-th active function in
/// ascending global index.
///
/// ```
/// use rkwave::basis::{CdvBasis, FilterFamily};
/// use rkwave::kernel::{kernel_matrix, ActiveSet};
/// use rkwave::sampling::Domain;
///
/// let basis = CdvBasis::new(2, FilterFamily::Extremal, 3, 5, Domain::UNIT).unwrap();
/// let active = ActiveSet::uniform(basis); // Psi(3, 5): 2^6 = 64 functions
/// assert_eq!(active.len(), 64);
/// let xs: Vec<f64> = (0..200).map(|i| i as f64 / 199.0).collect();
/// let k = kernel_matrix(&active, &xs)?; // K[i, a] = Psi_a(x_i), CSR
/// assert_eq!(k.shape(), (200, 64));
/// # Ok::<(), rkwave::kernel::KernelError>(())
/// ```
#[derive(Clone, Debug)]
pub struct ActiveSet {
    basis: CdvBasis,
    columns: Vec<usize>,
    /// Dense map global index -> column (empty when the set is sparse or deep).
    column_of: Vec<u32>,
    /// Where the active wavelets of each level live (made on first use).
    coverage: OnceLock<Coverage>,
}

impl ActiveSet {
    /// Every function of `Psi(n, N)` (column = global index).
    pub fn uniform(basis: CdvBasis) -> Self {
        let dim = basis.dimension();
        Self {
            basis,
            columns: (0..dim).collect(),
            column_of: if dim <= DENSE_MAP_LIMIT {
                (0..dim as u32).collect()
            } else {
                Vec::new()
            },
            coverage: OnceLock::new(),
        }
    }

    /// The given global indices (deduplicated, sorted); indices beyond the basis are dropped.
    pub fn from_indices(basis: CdvBasis, indices: impl IntoIterator<Item = usize>) -> Self {
        let dim = basis.dimension();
        let mut columns: Vec<usize> = indices.into_iter().filter(|&a| a < dim).collect();
        columns.sort_unstable();
        columns.dedup();
        Self::from_sorted(basis, columns)
    }

    /// The sparse constructor: `columns` already strictly ascending and inside the basis
    /// (an adaptive tree's columns), taken as they are; columns are looked up by a dense map
    /// when the set fills at least 1/16 of a small basis, by binary search otherwise.
    ///
    /// # Panics
    /// If `columns` is not strictly ascending or holds an index beyond the basis (a broken
    /// caller contract).
    pub fn from_sorted(basis: CdvBasis, columns: Vec<usize>) -> Self {
        let dim = basis.dimension();
        assert!(
            columns.windows(2).all(|w| w[0] < w[1]) && columns.last().is_none_or(|&a| a < dim),
            "ActiveSet::from_sorted needs strictly ascending indices below {dim}"
        );
        // Dense map only when it is small and the set fills a good part of it.
        let dense = dim <= DENSE_MAP_LIMIT && columns.len() * 16 >= dim;
        let mut column_of = if dense {
            vec![INACTIVE; dim]
        } else {
            Vec::new()
        };
        if dense {
            for (c, &a) in columns.iter().enumerate() {
                column_of[a] = c as u32;
            }
        }
        Self {
            basis,
            columns,
            column_of,
            coverage: OnceLock::new(),
        }
    }

    /// The enclosing basis.
    pub fn basis(&self) -> &CdvBasis {
        &self.basis
    }
    /// Number of active functions `P` (columns of `K`).
    pub fn len(&self) -> usize {
        self.columns.len()
    }
    /// Whether no function is active.
    pub fn is_empty(&self) -> bool {
        self.columns.is_empty()
    }
    /// Column of global index `a`, if active.
    pub fn column(&self, a: usize) -> Option<usize> {
        if self.column_of.is_empty() {
            return self.columns.binary_search(&a).ok();
        }
        self.column_of
            .get(a)
            .copied()
            .filter(|&c| c != INACTIVE)
            .map(|c| c as usize)
    }
    /// Global index of column `c`.
    pub fn global(&self, c: usize) -> usize {
        self.columns[c]
    }
    /// All active global indices, ascending.
    pub fn indices(&self) -> &[usize] {
        &self.columns
    }
    /// Whether every function of the enclosing basis is active.
    pub fn is_uniform(&self) -> bool {
        self.columns.len() == self.basis.dimension()
    }

    /// `sum_a c_a Psi_a(t)` over the active functions among `values` (one evaluation, in
    /// ascending global index), `coefficients` by column: a dense map lookup, or for a sparse
    /// set a merge of the two ascending lists galloping over the columns in between.
    pub fn combine(&self, values: &[BasisValue], coefficients: &[f64]) -> f64 {
        let mut sum = 0.0;
        if !self.column_of.is_empty() {
            for v in values {
                if let Some(c) = self.column(v.index) {
                    sum += coefficients[c] * v.value;
                }
            }
            return sum;
        }
        let mut lo = 0;
        for v in values {
            lo += gallop(&self.columns[lo..], v.index);
            if self.columns.get(lo) == Some(&v.index) {
                sum += coefficients[lo] * v.value;
            }
        }
        sum
    }

    /// The local depth at `t` in `[0, 1]`: the finest level `j` of an active wavelet whose
    /// structural support contains `t` (level-`j` cells, [`support_cells`]), or `n - 1` when
    /// no active wavelet is nonzero there. Functions of finer levels are all zero at `t`, so
    /// evaluation may stop at this level ([`crate::basis::Evaluator::eval_unit_to_depth_into`]).
    /// `O(levels log(ranges))`; a uniform set answers `N` at once.
    pub fn local_depth_unit(&self, t: f64) -> i64 {
        let n = self.basis.coarse();
        if self.is_uniform() {
            return self.basis.fine() as i64;
        }
        let coverage = self.coverage.get_or_init(|| self.build_coverage());
        let covered = |l: usize| {
            let ranges = &coverage.levels[l];
            let cell = cell_of(t, n + l as u32);
            let i = ranges.partition_point(|r| r.1 < cell);
            ranges.get(i).is_some_and(|r| r.0 <= cell)
        };
        let levels = coverage.levels.len();
        let covered_levels = if coverage.nested {
            // Covered levels are a prefix: the first uncovered one by bisection.
            let (mut lo, mut hi) = (0, levels);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if covered(mid) {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo
        } else {
            (0..levels).rev().find(|&l| covered(l)).map_or(0, |l| l + 1)
        };
        n as i64 + covered_levels as i64 - 1
    }

    fn build_coverage(&self) -> Coverage {
        let n = self.basis.coarse();
        let p = self.basis.p();
        let e = self.basis.bank().edge_count();
        let mut coverage: Vec<Vec<(u64, u64)>> =
            vec![Vec::new(); (self.basis.fine() - n + 1) as usize];
        for &a in self.columns.iter().filter(|&&a| a >= 1usize << n) {
            let id = FunctionId::from_index(a, n, e);
            let (lo, hi) = support_cells(p, id.level, id.index);
            let ranges = &mut coverage[(id.level - n) as usize];
            // Ascending index gives ascending `lo` within a level (edges included).
            match ranges.last_mut() {
                Some(last) if lo <= last.1 + 1 => last.1 = last.1.max(hi),
                _ => ranges.push((lo, hi)),
            }
        }
        // Nested when each level's region lies in the coarser level's (a tree closed under
        // "parent present": a child's support lies in its parent's).
        let nested = coverage.windows(2).all(|w| {
            w[1].iter().all(|&(lo, hi)| {
                let i = w[0].partition_point(|r| r.1 < lo / 2);
                w[0].get(i).is_some_and(|r| r.0 <= lo / 2 && hi / 2 <= r.1)
            })
        });
        Coverage {
            levels: coverage,
            nested,
        }
    }
}

/// Where the active wavelets live: per level `n..=N`, the merged ranges of level-`j` cells
/// covered by the structural supports of the active level-`j` wavelets.
#[derive(Clone, Debug)]
struct Coverage {
    levels: Vec<Vec<(u64, u64)>>,
    /// Whether each level's covered region lies inside the coarser level's, so the covered
    /// levels at any point are a prefix `n..=d`.
    nested: bool,
}

/// The number of entries of the ascending `list` below `a`, found by doubling steps from the
/// front then bisection: `O(log k)` for an answer `k` (mostly 0 or 1 in a merge).
fn gallop(list: &[usize], a: usize) -> usize {
    let mut hi = 1;
    while hi <= list.len() && list[hi - 1] < a {
        hi *= 2;
    }
    let lo = hi / 2;
    let hi = hi.min(list.len());
    lo + list[lo..hi].partition_point(|&c| c < a)
}

#[cfg(test)]
mod tests {
    use super::ActiveSet;
    use crate::basis::{BasisValue, CdvBasis, FilterFamily};
    use crate::sampling::Domain;

    /// A deterministic stream in `[0, 1)` (no dependency).
    fn stream(mut state: u64) -> impl FnMut() -> f64 {
        move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The evaluation stopped at the local depth gives every active function that the full
    /// evaluation gives, with the same value (to round-off of the shorter digit walk), and
    /// `combine` is the plain filtered sum. Checked on a parent-closed tree (nested coverage,
    /// depth by bisection) and on a set that is not one (linear scan), p = 1..=4.
    #[test]
    fn evaluation_capped_at_the_local_depth_loses_no_active_function() {
        let mut u = stream(7);
        for p in 1..=4usize {
            let n = crate::basis::minimum_level(p);
            let fine = n + 14;
            let basis =
                CdvBasis::new(p, FilterFamily::cdv_default(p), n, fine, Domain::UNIT).unwrap();
            // A tree: every wavelet whose support holds 1/3 or 0.8125 down to its depth, with
            // its parents (supports nest), plus the scaling functions.
            let mut tree: Vec<usize> = (0..1usize << n).collect();
            let mut odd: Vec<usize> = (0..1usize << n).collect();
            for (x, depth) in [(1.0 / 3.0, fine), (0.8125, n + 6)] {
                for j in n..=depth {
                    let k = crate::basis::cell_of(x, j) as usize;
                    tree.push((1usize << j) + k);
                }
            }
            // Not a tree: one deep wavelet without its parents.
            odd.push((1usize << (fine - 1)) + (1usize << (fine - 2)));
            for set in [tree, odd] {
                let active = ActiveSet::from_indices(basis.clone(), set);
                let mut ev = basis.evaluator();
                let (mut full, mut capped) = (Vec::<BasisValue>::new(), Vec::new());
                let coefficients: Vec<f64> = (0..active.len()).map(|_| u() - 0.5).collect();
                let ts = (0..400).map(|_| u()).chain([0.0, 1.0, 1.0 / 3.0, 0.8125]);
                for t in ts {
                    ev.eval_unit_into(t, &mut full);
                    let depth = active.local_depth_unit(t);
                    ev.eval_unit_to_depth_into(t, depth, &mut capped);
                    let keep = |v: &Vec<BasisValue>| -> Vec<(usize, f64)> {
                        v.iter()
                            .filter(|b| active.column(b.index).is_some())
                            .map(|b| (b.index, b.value))
                            .collect()
                    };
                    let (a, b) = (keep(&full), keep(&capped));
                    assert_eq!(
                        a.iter().map(|e| e.0).collect::<Vec<_>>(),
                        b.iter().map(|e| e.0).collect::<Vec<_>>(),
                        "p = {p}, t = {t}, depth {depth}"
                    );
                    for ((_, x), (_, y)) in a.iter().zip(&b) {
                        let scale = x.abs().max(1.0) * (1u64 << (fine / 2 + 1)) as f64;
                        assert!((x - y).abs() <= 1e-13 * scale, "p = {p}, t = {t}: {x} {y}");
                    }
                    let plain: f64 = a
                        .iter()
                        .map(|&(g, v)| coefficients[active.column(g).unwrap()] * v)
                        .sum();
                    let merged = active.combine(&full, &coefficients);
                    assert!((plain - merged).abs() <= 1e-12 * (1.0 + plain.abs()));
                }
            }
        }
    }
}
