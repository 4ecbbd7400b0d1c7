//! The normal equations of the tree, kept up to date between rounds: rounds cost what
//! changed.
//!
//! With `K[i, a] = Psi_a(x_i)` over the active functions, the fit solves
//!
//! ```text
//! G c = K^T f,      G_ab = sum_i Psi_a(x_i) Psi_b(x_i),      (K^T f)_a = sum_i Psi_a(x_i) f_i.
//! ```
//!
//! A round adds samples `i` (new rows) and functions `a` (new columns), and nothing leaves.
//! Both sums are updated in place instead of rebuilt: first the new samples add the outer
//! products of their rows over the functions already active, `G_ab += Psi_a(x_i) Psi_b(x_i)`
//! (column `a` gathered through a dense position map); then the new functions join the rows
//! of the samples in their support and their columns are `G_{.s} = sum_i Psi_s(x_i) k_i`
//! over the final rows, mirrored into the old columns (new slots are the largest, so they
//! append in order). Each pair of a row is counted once. Values come from the cached
//! evaluation rows ([`EvaluationRows`]), never from a second evaluation. With `s_a` the samples
//! in the support of `a` and `r_i` the active functions at `x_i`, a round costs
//!
//! ```text
//! sum_{new a} s_a r  +  sum_{new i} r_i^2      (r: active functions per sample)
//! ```
//!
//! for the update, `O(nnz(G))` to hand `G` (columns in order of arrival) to the sparse
//! Cholesky of [`crate::solve::normal_ls_corrected`] (one corrected semi-normal step from the
//! cached rows: `O(nnz(K))` more), and that factorization, in AMD order. An earlier version
//! eliminated the finest level first (sparser on a narrow adaptive tree), but on a full level
//! the chain of same-level neighbours carries the fill of each elimination to the next one,
//! so every coarser level ends up coupled to every other (docs/measurements/one-d.md, "What a round
//! costs").

use std::collections::HashMap;

use rayon::prelude::*;
use sprs::CsMat;

use super::{RefineError, Sample};
use crate::basis::CdvBasis;
use crate::kernel::EvaluationRows;
use crate::solve::{normal_ls_corrected, GlobalLs, GlobalLsParams};

/// Rows per parallel work item.
const CHUNK: usize = 1024;

/// Cached rows restricted to the active functions, maintained as functions arrive: the
/// sparse rows of `K` by slot (a function's slot is its order of arrival).
#[derive(Clone, Debug, Default)]
pub(crate) struct ActiveRows {
    rows: Vec<Vec<(u32, f64)>>,
    /// `(t, row)` ascending in `t`: the rows in a support, by binary search.
    order: Vec<(f64, u32)>,
}

impl ActiveRows {
    /// Appends the rows `self.len()..cached.len()` (unit positions `t_of(i)`) restricted to the
    /// active functions `slot_of`; `on_row(i, row)` sees each new row.
    fn add_rows(
        &mut self,
        cached: &EvaluationRows,
        t_of: impl Fn(usize) -> f64,
        slot_of: &HashMap<usize, u32>,
        mut on_row: impl FnMut(usize, &[(u32, f64)]),
    ) {
        let first = self.rows.len();
        for i in first..cached.len() {
            let row: Vec<(u32, f64)> = cached
                .row(i)
                .filter_map(|(a, v)| slot_of.get(&a).map(|&s| (s, v)))
                .collect();
            on_row(i, &row);
            self.rows.push(row);
            self.order.push((t_of(i), i as u32));
        }
        if first < self.rows.len() {
            self.order.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
    }

    /// Adds function `a` (slot `slot`, unit support `[lo, hi]`) to every row where it is
    /// nonzero; `on_entry(i, value, row_before)` sees each entry with the row as it was.
    fn activate(
        &mut self,
        cached: &EvaluationRows,
        a: usize,
        slot: u32,
        (lo, hi): (f64, f64),
        mut on_entry: impl FnMut(usize, f64, &[(u32, f64)]),
    ) {
        let start = self.order.partition_point(|e| e.0 < lo);
        let end = self.order.partition_point(|e| e.0 <= hi);
        for &(_, i) in &self.order[start..end] {
            let i = i as usize;
            let v = cached.value(i, a);
            if v != 0.0 {
                on_entry(i, v, &self.rows[i]);
                self.rows[i].push((slot, v));
            }
        }
    }

    /// `sum_s coefficient[s] K[i, s]` for every row.
    pub fn apply(&self, coefficient: &[f64]) -> Vec<f64> {
        self.rows
            .par_iter()
            .map(|r| r.iter().map(|&(s, v)| coefficient[s as usize] * v).sum())
            .collect()
    }

    /// `K^T (f - K c)` by slot for coefficients `c` by slot (`f_i = samples[i].value`).
    fn residual_product(&self, samples: &[Sample], c: &[f64]) -> Vec<f64> {
        let p = c.len();
        self.rows
            .par_chunks(CHUNK)
            .zip(samples.par_chunks(CHUNK))
            .fold(
                || vec![0.0; p],
                |mut acc, (rows, samples)| {
                    for (row, s) in rows.iter().zip(samples) {
                        let fit: f64 = row.iter().map(|&(a, v)| c[a as usize] * v).sum();
                        let r = s.value - fit;
                        for &(a, v) in row {
                            acc[a as usize] += v * r;
                        }
                    }
                    acc
                },
            )
            .reduce(
                || vec![0.0; p],
                |mut a, b| {
                    a.iter_mut().zip(b).for_each(|(x, y)| *x += y);
                    a
                },
            )
    }
}

/// The kernel of fixed points (the reference grid of the diagnostics) kept round after round:
/// the evaluation rows once ([`EvaluationRows`]), their restriction to the active functions
/// updated as functions arrive, so the fit's values there are `K_grid c` (`O(nnz)` a round,
/// no evaluation of the basis).
#[derive(Clone, Debug)]
pub(crate) struct TrackedPoints {
    ts: Vec<f64>,
    cached: EvaluationRows,
    active: ActiveRows,
    known: usize,
}

impl TrackedPoints {
    /// The points `ts` (unit coordinates), evaluated once in `full`.
    pub fn new(full: &CdvBasis, ts: Vec<f64>) -> Self {
        let mut cached = EvaluationRows::new();
        cached.push(full, &ts);
        Self {
            ts,
            cached,
            active: ActiveRows::default(),
            known: 0,
        }
    }

    /// The values of `sum c_s Psi_s` at the points, for the functions of `normal` (slots and
    /// supports) with coefficients by slot.
    pub fn values(&mut self, normal: &NormalEquations, by_slot: &[f64]) -> Vec<f64> {
        if self.active.rows.is_empty() {
            self.active
                .add_rows(&self.cached, |i| self.ts[i], &HashMap::new(), |_, _| {});
        }
        for s in self.known..normal.globals.len() {
            let a = normal.globals[s];
            self.active
                .activate(&self.cached, a, s as u32, normal.supports[s], |_, _, _| {});
        }
        self.known = normal.globals.len();
        self.active.apply(by_slot)
    }
}

/// `G = K^T K`, `K^T f` and the rows of `K`, by slot, kept up to date across rounds (module
/// docs).
#[derive(Clone, Debug, Default)]
pub(crate) struct NormalEquations {
    /// Global index of each slot.
    globals: Vec<usize>,
    slot_of: HashMap<usize, u32>,
    /// Unit support `[lo, hi]` of each slot.
    supports: Vec<(f64, f64)>,
    rows: ActiveRows,
    /// Column `s` of `G`: `(slot, value)` ascending in slot.
    gram: Vec<Vec<(u32, f64)>>,
    /// `(K^T f)_s`.
    rhs: Vec<f64>,
    /// Samples in the support of each slot (nonzero entries of its column of `K`).
    counts: Vec<usize>,
}

/// Scratch of one worker: a dense accumulator over the slots.
struct Scratch {
    /// Position of a slot in the column being built (`u32::MAX`: absent).
    pos: Vec<u32>,
}

impl Scratch {
    fn new(p: usize) -> Self {
        Self {
            pos: vec![u32::MAX; p],
        }
    }
}

/// Adds `sum_{(i, v) in list} v * rows[i]` into the sorted column `column` (a dense position
/// map for the duplicates; new rows appended, then sorted once).
fn accumulate(
    column: &mut Vec<(u32, f64)>,
    list: &[(u32, f64)],
    rows: &[Vec<(u32, f64)>],
    scratch: &mut Scratch,
) {
    for (t, e) in column.iter().enumerate() {
        scratch.pos[e.0 as usize] = t as u32;
    }
    let old = column.len();
    for &(i, v) in list {
        for &(b, vb) in &rows[i as usize] {
            let slot = &mut scratch.pos[b as usize];
            if *slot == u32::MAX {
                *slot = column.len() as u32;
                column.push((b, v * vb));
            } else {
                column[*slot as usize].1 += v * vb;
            }
        }
    }
    for e in column.iter() {
        scratch.pos[e.0 as usize] = u32::MAX;
    }
    if column.len() > old {
        column.sort_unstable_by_key(|e| e.0);
    }
}

impl NormalEquations {
    /// Brings the system to the samples of `cached` (values `f_i`, unit positions `t_i`)
    /// and the active functions `columns` (ascending global indices; a superset of the last
    /// call's), `support(a)` giving the unit support of `a`.
    pub fn update(
        &mut self,
        cached: &EvaluationRows,
        samples: &[Sample],
        columns: &[usize],
        support: impl Fn(usize) -> (f64, f64),
    ) {
        let old = self.globals.len();
        let first_row = self.rows.rows.len();
        // New samples against the functions already active: G += k_i k_i^T, column by
        // column (`touches[a]`: the new rows where old function `a` is nonzero).
        self.rows
            .add_rows(cached, |i| samples[i].t, &self.slot_of, |_, _| {});
        let mut touches: Vec<Vec<(u32, f64)>> = vec![Vec::new(); old];
        for (i, row) in self.rows.rows.iter().enumerate().skip(first_row) {
            for &(a, va) in row {
                touches[a as usize].push((i as u32, va));
                self.rhs[a as usize] += va * samples[i].value;
                self.counts[a as usize] += 1;
            }
        }
        let rows = &self.rows.rows;
        self.gram
            .par_iter_mut()
            .zip(touches.par_iter())
            .filter(|(_, list)| !list.is_empty())
            .for_each_init(
                || Scratch::new(old),
                |scratch, (column, list)| accumulate(column, list, rows, scratch),
            );
        // New functions join the rows of every sample in their support ...
        let mut lists: Vec<Vec<(u32, f64)>> = Vec::new();
        for &a in columns {
            if self.slot_of.contains_key(&a) {
                continue;
            }
            let s = self.globals.len() as u32;
            self.globals.push(a);
            self.slot_of.insert(a, s);
            let sup = support(a);
            self.supports.push(sup);
            let mut list = Vec::new();
            self.rows
                .activate(cached, a, s, sup, |i, v, _| list.push((i as u32, v)));
            self.rhs.push(
                list.iter()
                    .map(|&(i, v)| v * samples[i as usize].value)
                    .sum(),
            );
            self.counts.push(list.len());
            lists.push(list);
        }
        // ... then their columns are `sum_i Psi_s(x_i) k_i` over the final rows, and the old
        // columns get the symmetric entries (new slots are the largest: appended in order).
        let p = self.globals.len();
        let rows = &self.rows.rows;
        let new_columns: Vec<Vec<(u32, f64)>> = lists
            .par_iter()
            .map_init(
                || Scratch::new(p),
                |scratch, list| {
                    let mut column = Vec::new();
                    accumulate(&mut column, list, rows, scratch);
                    column
                },
            )
            .collect();
        for (k, column) in new_columns.iter().enumerate() {
            let s = (old + k) as u32;
            for &(b, v) in column.iter().filter(|e| (e.0 as usize) < old) {
                self.gram[b as usize].push((s, v));
            }
        }
        self.gram.extend(new_columns);
    }

    /// Coefficients by slot from coefficients in the order of `columns` (all active).
    pub fn by_slot(&self, columns: &[usize], coefficients: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.globals.len()];
        for (&a, &c) in columns.iter().zip(coefficients) {
            out[self.slot(a).expect("every column is active")] = c;
        }
        out
    }

    /// Slot of global index `a`.
    pub fn slot(&self, a: usize) -> Option<usize> {
        self.slot_of.get(&a).map(|&s| s as usize)
    }

    /// Solves `G c = K^T f` (sparse Cholesky in AMD order) with one corrected semi-normal
    /// step from the cached rows of `K` and the values of `samples` (the samples of the last
    /// [`NormalEquations::update`]): forward error of order `eps cond(K)`, not
    /// `eps cond(K)^2` ([`normal_ls_corrected`]); the coefficients by slot.
    pub fn solve(
        &self,
        samples: &[Sample],
        params: &GlobalLsParams,
    ) -> Result<GlobalLs, RefineError> {
        let p = self.globals.len();
        let mut indptr = Vec::with_capacity(p + 1);
        indptr.push(0);
        let nnz: usize = self.gram.iter().map(Vec::len).sum();
        let mut indices = Vec::with_capacity(nnz);
        let mut data = Vec::with_capacity(nnz);
        for column in &self.gram {
            indices.extend(column.iter().map(|e| e.0 as usize));
            data.extend(column.iter().map(|e| e.1));
            indptr.push(indices.len());
        }
        let g = CsMat::new((p, p), indptr, indices, data);
        let residual = |c: &[Vec<f64>]| -> Vec<Vec<f64>> {
            c.iter()
                .map(|c| self.rows.residual_product(samples, c))
                .collect()
        };
        Ok(normal_ls_corrected(
            &g,
            &[&self.rhs],
            self.rows.rows.len(),
            &self.counts,
            None,
            &residual,
            params,
        )?)
    }

    /// `G` and `K^T f` densely, in the order of `columns` (tests).
    #[cfg(test)]
    pub fn dense(&self, columns: &[usize]) -> (Vec<Vec<f64>>, Vec<f64>) {
        let p = columns.len();
        let slot: Vec<usize> = columns.iter().map(|&a| self.slot(a).unwrap()).collect();
        let mut column_of_slot = vec![0; p];
        for (c, &s) in slot.iter().enumerate() {
            column_of_slot[s] = c;
        }
        let mut g = vec![vec![0.0; p]; p];
        for (c, &s) in slot.iter().enumerate() {
            for &(r, v) in &self.gram[s] {
                g[c][column_of_slot[r as usize]] = v;
            }
        }
        (g, slot.iter().map(|&s| self.rhs[s]).collect())
    }
}
