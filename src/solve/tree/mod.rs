//! The tree system: least squares on the adaptive image plane's wavelet tree, `G c = K_T^T f`
//! with `G = K_T^T K_T` over the tree's active functions (docs/design.md §7).
//!
//! * [`gram`]: the assembly of `G` (upper triangle, in parallel, deterministic) and its
//!   update between rounds, bit for bit the rebuilt matrix;
//! * [`pcg`]: the matrix-free solve, `K_T = E S P_T` applied through the single-scale rows,
//!   with the exact diagonal of `G` as Jacobi preconditioner, by the crate's one conjugate
//!   gradient ([`crate::solve::cg::pcg`]); the solver choice ([`pcg::TreeSolver`]) and the
//!   warm start carried between rounds;
//! * [`schwarz`]: the additive Schwarz preconditioner on overlapping tiles with every level.
//!
//! The fit that calls them (and names what it does at an iteration limit,
//! [`crate::solve::cg::IterationLimit`]) is `image::adaptive::fit`.

mod diagonal;
pub mod gram;
mod operator;
pub mod pcg;
pub mod schwarz;
mod single_scale;
pub(crate) mod solver;
