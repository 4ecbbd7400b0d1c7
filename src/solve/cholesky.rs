//! The sparse Cholesky factorization of a symmetric positive definite `A` (`n x n`, its
//! lower triangle read from a CSC pattern):
//!
//! ```text
//! P A P^T = L L^T,        A x = b  <=>  x = P^T L^{-T} L^{-1} P b,
//! ```
//!
//! `P` a fill-reducing ordering (faer's approximate minimum degree, or one given). The
//! symbolic step ([`SparseCholesky::analyze`]: ordering, elimination tree, the pattern of
//! `L`, supernodal when worth it) depends on the pattern alone and is done once; the numeric
//! step ([`SparseCholesky::factor`]) on the values, as often as they change; every
//! right-hand side is solved from the one factor ([`SparseCholesky::solve_in_place`]).
//! The one wrapper of faer's sparse Cholesky for every caller: the 1D and tree normal
//! equations (`solve::normal_ls`) and the 2D stencil normal equations
//! (the image fit's `NormalSystem`).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltError, LltRegularization};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, simplicial::SimplicialLltRef, supernodal::SupernodalLltRef,
    LltRef, SymbolicCholesky, SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};
use thiserror::Error;

/// What the numeric factorization does with a small pivot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pivots {
    /// Any pivot `<= 0` stops the factorization ([`NonPositivePivot`]).
    Strict,
    /// A pivot `<= epsilon` is replaced by 1 (faer's dynamic regularization with `delta =
    /// 1`): on an equilibrated matrix (unit diagonal) that fixes the direction's component at
    /// about 0 instead of failing.
    ReplaceBelow {
        /// The threshold.
        epsilon: f64,
    },
}

/// The numeric factorization met a pivot `<= 0` at elimination step `step` (the column
/// eliminated `step`-th; may be `n` for a zero trailing block).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NonPositivePivot {
    /// The elimination step.
    pub step: usize,
}

/// Errors of a sparse Cholesky factorization, each naming the matrix and the value at fault.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum CholeskyError {
    /// The symbolic step failed (faer: out of memory or an index overflow).
    #[error(
        "symbolic sparse Cholesky of the {size} x {size} {what} ({nnz} stored entries) failed: \
         {reason}; fewer unknowns or an iterative solve"
    )]
    Symbolic {
        /// Which matrix.
        what: &'static str,
        /// Its order `n`.
        size: usize,
        /// Its stored entries.
        nnz: usize,
        /// faer's error.
        reason: String,
    },
    /// The numeric step met a non-positive pivot although a ridge was added.
    #[error(
        "numeric sparse Cholesky of the {size} x {size} {what} failed with ridge {ridge:e}: \
         non-positive pivot at elimination step {step}; more samples where that function \
         lives, or the iterative solve"
    )]
    NotPositive {
        /// Which matrix.
        what: &'static str,
        /// Its order `n`.
        size: usize,
        /// The elimination step of the pivot.
        step: usize,
        /// The relative ridge on the diagonal when it failed.
        ridge: f64,
    },
}

/// A sparse Cholesky factorization: the symbolic analysis and, after
/// [`SparseCholesky::factor`], the values of `L`.
pub struct SparseCholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
    n: usize,
}

impl std::fmt::Debug for SparseCholesky {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SparseCholesky")
            .field("n", &self.n)
            .field("factor_nnz", &self.factor_nnz())
            .finish()
    }
}

impl SparseCholesky {
    /// The symbolic step for the pattern `(col_ptr, row_idx)` (CSC, sorted rows; only the
    /// lower triangle is read) with the elimination order `ordering` (`ordering[q]` = the
    /// column eliminated `q`-th; `None`: approximate minimum degree). `what` names the matrix
    /// in errors.
    pub fn analyze(
        what: &'static str,
        col_ptr: &[usize],
        row_idx: &[usize],
        ordering: Option<&[usize]>,
    ) -> Result<Self, CholeskyError> {
        let n = col_ptr.len() - 1;
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
        let inverse: Vec<usize> = ordering.map_or_else(Vec::new, |fwd| {
            let mut inv = vec![0usize; fwd.len()];
            for (q, &a) in fwd.iter().enumerate() {
                inv[a] = q;
            }
            inv
        });
        let order = match ordering {
            Some(fwd) => SymmetricOrdering::Custom(PermRef::new_checked(fwd, &inverse, n)),
            None => SymmetricOrdering::Amd,
        };
        let symbolic = factorize_symbolic_cholesky(pattern, Side::Lower, order, Default::default())
            .map_err(|e| CholeskyError::Symbolic {
                what,
                size: n,
                nnz: row_idx.len(),
                reason: format!("{e:?}"),
            })?;
        Ok(Self {
            symbolic,
            values: Vec::new(),
            n,
        })
    }

    /// Order `n`.
    pub fn len(&self) -> usize {
        self.n
    }
    /// Whether `n = 0`.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Stored entries of `L` (known after the symbolic step).
    pub fn factor_nnz(&self) -> usize {
        self.symbolic.len_val()
    }

    /// The elimination order: entry `q` is the column eliminated `q`-th.
    pub fn permutation(&self) -> Vec<usize> {
        match self.symbolic.perm() {
            Some(perm) => perm.arrays().0.to_vec(),
            None => (0..self.n).collect(),
        }
    }

    /// The numeric step: `L` of the matrix with the analysed pattern `(col_ptr, row_idx)`
    /// and `values`, with the small-pivot rule `pivots`, on `par` threads.
    pub fn factor(
        &mut self,
        col_ptr: &[usize],
        row_idx: &[usize],
        values: &[f64],
        pivots: Pivots,
        par: Par,
    ) -> Result<(), NonPositivePivot> {
        let n = self.n;
        let pattern = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
        self.values.clear();
        self.values.resize(self.symbolic.len_val(), 0.0);
        let mut mem = MemBuffer::new(
            self.symbolic
                .factorize_numeric_llt_scratch::<f64>(par, Default::default()),
        );
        let regularization = match pivots {
            Pivots::Strict => LltRegularization::default(),
            Pivots::ReplaceBelow { epsilon } => LltRegularization {
                dynamic_regularization_delta: 1.0,
                dynamic_regularization_epsilon: epsilon,
            },
        };
        self.symbolic
            .factorize_numeric_llt(
                &mut self.values,
                SparseColMatRef::new(pattern, values),
                Side::Lower,
                regularization,
                par,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map(|_| ())
            .map_err(|e| match e {
                LltError::NonPositivePivot { index } => NonPositivePivot { step: index },
            })
    }

    /// The diagonal `L_qq` of the factor, in elimination order.
    pub fn diagonal(&self) -> Vec<f64> {
        let mut diag = vec![0.0f64; self.n];
        match self.symbolic.raw() {
            SymbolicCholeskyRaw::Simplicial(s) => {
                let l = SimplicialLltRef::new(s, &self.values);
                let (cp, ri) = (s.col_ptr(), s.row_idx());
                for (j, dj) in diag.iter_mut().enumerate() {
                    if let Some(t) = (cp[j]..cp[j + 1]).find(|&t| ri[t] == j) {
                        *dj = l.values()[t];
                    }
                }
            }
            SymbolicCholeskyRaw::Supernodal(s) => {
                let l = SupernodalLltRef::new(s, &self.values);
                for sn in 0..s.n_supernodes() {
                    let node = l.supernode(sn);
                    let v = node.val();
                    for c in 0..v.ncols() {
                        diag[node.start() + c] = v[(c, c)];
                    }
                }
            }
        }
        diag
    }

    /// `B <- A^{-1} B` for every column of `rhs` (`n x k`), from the factor, on `par` threads.
    pub fn solve_in_place(&self, rhs: MatMut<'_, f64>, par: Par) {
        let mut mem = MemBuffer::new(
            self.symbolic
                .solve_in_place_scratch::<f64>(rhs.ncols(), par),
        );
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs,
            par,
            MemStack::new(&mut mem),
        );
    }
}

impl CholeskyError {
    /// The kind of this error ([`crate::error`]): a failed factorization is numerical.
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            CholeskyError::Symbolic { .. } | CholeskyError::NotPositive { .. } => {
                crate::error::ErrorKind::Numerical
            }
        }
    }
}

crate::error::classified!(CholeskyError);
