//! The set of active basis functions: the columns of `K`.

use crate::basis::CdvBasis;

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
        }
    }

    /// The given global indices (deduplicated, sorted); indices beyond the basis are dropped.
    pub fn from_indices(basis: CdvBasis, indices: impl IntoIterator<Item = usize>) -> Self {
        let dim = basis.dimension();
        let mut columns: Vec<usize> = indices.into_iter().filter(|&a| a < dim).collect();
        columns.sort_unstable();
        columns.dedup();
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
}
