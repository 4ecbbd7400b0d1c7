//! Sparse kernel matrices `K[i, a] = Psi_a(lambda_i)` (docs/design.md §3), the active basis sets that
//! index their columns, and the automatic choice of levels.
//!
//! Each row holds the values of the functions of the active set that are nonzero at one
//! sample, straight from the one-pass pointwise evaluation (about `2p - 1` per level plus edge
//! functions), built in parallel with rayon.

mod active;
mod levels;
mod matrix;
mod rows;

pub use active::ActiveSet;
pub use levels::{LevelChoice, LevelParams};
pub use matrix::{check_positions, kernel_matrix, KernelError};
pub use rows::EvaluationRows;
