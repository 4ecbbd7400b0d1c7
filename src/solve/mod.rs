//! Solver layer: `c = K^+ f`, with `K` the `m x P` sparse kernel matrix
//! `K[i, a] = basis_a(sample_i)` and `K^+` its Moore–Penrose pseudo-inverse.
//!
//! Generic over any `sprs` CSR matrix (nothing here knows about wavelets):
//!
//! * [`local_inversion`] / [`apply_local`]: the approximate `K~ ≈ K^+` assembled from
//!   pseudo-inverses of small neighbourhood blocks `K[jdx, idx]` (docs/design.md §4), one
//!   factorization per distinct neighbourhood, in parallel ([`LocalInversionParams`],
//!   [`Solver`]).
//! * [`dense_pinv`]: dense `K^+` by faer's SVD, the truth for small problems.
//! * [`global_ls`]: `argmin ||K c - f||` for large problems by sparse Cholesky of `K^T K`
//!   or CGLS ([`GlobalLsParams`]); [`normal_ls`] the same Cholesky from a given `K^T K`.
//! * [`cg`]: one (preconditioned, multi-right-hand-side, lockstep) conjugate gradient over
//!   a [`cg::SymmetricOperator`], with Jacobi, local-inversion and additive-Schwarz
//!   preconditioners, and its least-squares form (CGLS) for the global solve.
//! * [`vectors`]: the dot product and the interleaved layout of several channels.
//! * [`compare_dense`], [`compare_sparse_dense`], [`compare_vectors`]: error figures.
//!
//! Every entry point validates its input, scales `K` by an exact power of two (so
//! magnitudes `1e±300` are safe), reports cut-offs, shifts and condition numbers, and
//! returns [`SolveError`] instead of panicking or returning NaN.

pub(crate) mod band;
mod block;
pub mod cg;
pub mod cholesky;
mod compare;
mod error;
mod global;
mod local;
mod normal;
mod outcome;
mod params;
mod sparse;
pub mod stencil;
pub mod tree;
pub mod vectors;
pub(crate) use sparse::{csr_by_rows, raw as csr_raw, transpose_with_positions};
#[cfg(test)]
mod tests;

pub use compare::{compare_dense, compare_sparse_dense, compare_vectors, Comparison};
pub use error::SolveError;
pub use global::{dense_pinv, global_ls, DensePinv, DENSE_LIMIT};
pub use local::{
    apply_local, local_inversion, GroupStats, LocalApply, LocalInversion, LocalStats, Summary,
    CHOLESKY_MAX_CONDITION, WEAK_CONDITION,
};
pub use normal::{normal_ls, normal_ls_corrected, NormalResidual};
pub use outcome::{GlobalLs, GlobalReport};
pub use params::{
    GlobalLsParams, GlobalMethod, LocalInversionParams, RankPolicy, Solver, MAX_RINGS,
};
