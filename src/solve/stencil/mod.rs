//! The stencil system: the uniform image plane's least squares on the single-scale tensor
//! space `V_Jx (x) V_Jy`, `G z = b_c` with `G = K^T K` a banded (stencil) matrix, whose
//! nonzeros are the pairs of functions with overlapping supports (docs/design.md §7).
//!
//! * [`normal`]: the assembly of `G` and `b_c = K^T f_c`, sample by sample;
//! * [`system`]: its solves, the sparse Cholesky or preconditioned CG (Jacobi, local
//!   inversion), with what the CG does at its iteration limit named at the call
//!   ([`crate::solve::cg::IterationLimit`]);
//! * [`precondition`]: the local-inversion preconditioner's kernel matrix `K` in 2D.
//!
//! The fit that assembles and solves it per channel is `image::fit`.

pub mod normal;
pub mod precondition;
pub mod system;
