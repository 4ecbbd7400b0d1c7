//! The set of active basis functions: the columns of `K`.

use crate::basis::CdvBasis;

/// Marks a global index that is not active.
const INACTIVE: u32 = u32::MAX;

/// A set of active functions of an enclosing `Psi(n, N)`: uniformly all of them, or (for the
/// adaptive tree of the refiner) any subset; column `c` of `K` is the `c`-th active function in
/// ascending global index.
#[derive(Clone, Debug)]
pub struct ActiveSet {
    basis: CdvBasis,
    columns: Vec<usize>,
    column_of: Vec<u32>,
}

impl ActiveSet {
    /// Every function of `Psi(n, N)`.
    pub fn uniform(basis: CdvBasis) -> Self {
        let dim = basis.dimension();
        Self {
            basis,
            columns: (0..dim).collect(),
            column_of: (0..dim as u32).collect(),
        }
    }

    /// The given global indices (deduplicated, sorted); indices beyond the basis are dropped.
    pub fn from_indices(basis: CdvBasis, indices: impl IntoIterator<Item = usize>) -> Self {
        let dim = basis.dimension();
        let mut columns: Vec<usize> = indices.into_iter().filter(|&a| a < dim).collect();
        columns.sort_unstable();
        columns.dedup();
        let mut column_of = vec![INACTIVE; dim];
        for (c, &a) in columns.iter().enumerate() {
            column_of[a] = c as u32;
        }
        Self {
            basis,
            columns,
            column_of,
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
}
