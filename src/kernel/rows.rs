//! The one kernel builder: the pointwise evaluation of a basis at sample positions, row by
//! row, and the CSR assembly of `K[i, c] = Psi_{active(c)}(x_i)` from it.
//!
//! `kernel::kernel_matrix` (its caller) evaluates and filters in one pass;
//! [`EvaluationRows`] keeps the evaluation of every function of a full `Psi(n, D)` at each
//! position (made once per position) so that `K` of any active set inside `Psi(n, D)` is a
//! filter of the cached rows, never a second evaluation (the adaptive refiner's rows).

use rayon::prelude::*;
use sprs::CsMat;

use super::ActiveSet;
use crate::basis::{BasisValue, CdvBasis};

/// Positions per parallel work item.
const CHUNK: usize = 4096;

/// One block of CSR rows: entries per row, column indices, values.
pub(crate) type RowBlock = (Vec<usize>, Vec<usize>, Vec<f64>);

/// Evaluates `basis` at the unit positions `ts` (in parallel), wavelets up to level
/// `depth(t)` ([`crate::basis::Evaluator::eval_unit_to_depth_into`]), and keeps, per row in
/// ascending global index, the functions `column(a)` maps to a column, as `(column, value)`.
pub(crate) fn evaluate_rows(
    basis: &CdvBasis,
    ts: &[f64],
    depth: impl Fn(f64) -> i64 + Sync,
    column: impl Fn(usize) -> Option<usize> + Sync,
) -> Vec<RowBlock> {
    ts.par_chunks(CHUNK)
        .map(|chunk| {
            let mut ev = basis.evaluator();
            let mut out: Vec<BasisValue> = Vec::with_capacity(256);
            let mut counts = Vec::with_capacity(chunk.len());
            let mut indices = Vec::with_capacity(chunk.len() * 40);
            let mut data = Vec::with_capacity(chunk.len() * 40);
            for &t in chunk {
                ev.eval_unit_to_depth_into(t, depth(t), &mut out);
                let before = indices.len();
                for v in &out {
                    if let Some(c) = column(v.index) {
                        indices.push(c);
                        data.push(v.value);
                    }
                }
                counts.push(indices.len() - before);
            }
            (counts, indices, data)
        })
        .collect()
}

/// The CSR matrix (`rows x columns`) of the blocks, in order.
pub(crate) fn assemble(shape: (usize, usize), blocks: Vec<RowBlock>) -> CsMat<f64> {
    let nnz: usize = blocks.iter().map(|b| b.1.len()).sum();
    let mut indptr = Vec::with_capacity(shape.0 + 1);
    let mut indices = Vec::with_capacity(nnz);
    let mut data = Vec::with_capacity(nnz);
    indptr.push(0);
    for (counts, idx, val) in blocks {
        for c in counts {
            indptr.push(indptr.last().copied().unwrap_or(0) + c);
        }
        indices.extend(idx);
        data.extend(val);
    }
    CsMat::new(shape, indptr, indices, data)
}

/// The evaluation of every function of a full basis `Psi(n, D)` at a growing list of
/// positions, one row per position (ascending global index within a row), made once per
/// position; `K` of an active set inside `Psi(n, D)` is filtered from it
/// ([`EvaluationRows::kernel`]).
///
/// ```
/// use rkwave::basis::{CdvBasis, FilterFamily};
/// use rkwave::kernel::{kernel_matrix, ActiveSet, EvaluationRows};
/// use rkwave::sampling::Domain;
///
/// let full = CdvBasis::new(2, FilterFamily::Extremal, 3, 8, Domain::UNIT).unwrap();
/// let mut rows = EvaluationRows::new();
/// let xs: Vec<f64> = (0..100).map(|i| (i as f64 + 0.5) / 100.0).collect();
/// rows.push(&full, &xs); // unit positions
/// let small = CdvBasis::new(2, FilterFamily::Extremal, 3, 5, Domain::UNIT).unwrap();
/// let active = ActiveSet::from_indices(small, [0, 1, 2, 3, 8, 9, 17, 40]);
/// let (cached, fresh) = (rows.kernel(&active), kernel_matrix(&active, &xs)?);
/// // The same entries; values to round-off (the digit walks start at other levels).
/// assert_eq!(cached.indptr(), fresh.indptr());
/// assert_eq!(cached.indices(), fresh.indices());
/// for (a, b) in cached.data().iter().zip(fresh.data()) {
///     assert!((a - b).abs() <= 1e-13 * 16.0);
/// }
/// # Ok::<(), rkwave::kernel::KernelError>(())
/// ```
#[derive(Clone, Debug)]
pub struct EvaluationRows {
    ptr: Vec<usize>,
    index: Vec<usize>,
    value: Vec<f64>,
}

impl Default for EvaluationRows {
    fn default() -> Self {
        Self::new()
    }
}

impl EvaluationRows {
    /// No rows yet.
    pub fn new() -> Self {
        Self {
            ptr: vec![0],
            index: Vec::new(),
            value: Vec::new(),
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.ptr.len() - 1
    }

    /// Whether there is no row.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Evaluates `basis` at the unit positions `ts` (in `[0, 1]`, not checked) and appends
    /// one row per position.
    pub fn push(&mut self, basis: &CdvBasis, ts: &[f64]) {
        for (counts, index, value) in evaluate_rows(basis, ts, |_| basis.fine() as i64, Some) {
            for c in counts {
                let last = *self.ptr.last().expect("ptr starts with 0");
                self.ptr.push(last + c);
            }
            self.index.extend(index);
            self.value.extend(value);
        }
    }

    /// `Psi_a` at row `i` (0 where `a` is not structurally nonzero).
    pub fn value(&self, i: usize, a: usize) -> f64 {
        let (lo, hi) = (self.ptr[i], self.ptr[i + 1]);
        match self.index[lo..hi].binary_search(&a) {
            Ok(t) => self.value[lo + t],
            Err(_) => 0.0,
        }
    }

    /// Row `i` as `(global index, value)` pairs, ascending in the index.
    pub fn row(&self, i: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (lo, hi) = (self.ptr[i], self.ptr[i + 1]);
        self.index[lo..hi]
            .iter()
            .copied()
            .zip(self.value[lo..hi].iter().copied())
    }

    /// `K[i, c] = Psi_{active(c)}(x_i)` over every row (CSR, `len() x active.len()`): the
    /// rows filtered to the active set, whose basis must lie inside the evaluated one (same
    /// coarse level and filters; global indices agree across finest levels).
    pub fn kernel(&self, active: &ActiveSet) -> CsMat<f64> {
        let rows: Vec<usize> = (0..self.len()).collect();
        let blocks: Vec<RowBlock> = rows
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut counts = Vec::with_capacity(chunk.len());
                let (mut indices, mut data) = (Vec::new(), Vec::new());
                for &i in chunk {
                    let before = indices.len();
                    for (a, v) in self.row(i) {
                        if let Some(c) = active.column(a) {
                            indices.push(c);
                            data.push(v);
                        }
                    }
                    counts.push(indices.len() - before);
                }
                (counts, indices, data)
            })
            .collect();
        assemble((self.len(), active.len()), blocks)
    }
}
