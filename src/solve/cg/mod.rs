//! Conjugate gradients for `A x_c = b_c`, `A` symmetric positive (semi)definite, for `k`
//! right-hand sides in lockstep: one conjugate-gradient run per channel, whose products
//! `A p_c` (and `M^{-1} r_c`) of one iteration go through one call of the operator (and the
//! preconditioner), so one pass over the operator's data serves every channel.
//!
//! Per channel, from `x_0` (0 unless a start is given), `r_0 = b - A x_0`,
//! `z_0 = M^{-1} r_0`, `p_0 = z_0` (Hestenes & Stiefel 1952; Golub & Van Loan 11.5):
//!
//! ```text
//! alpha_j = (r_j . z_j) / (p_j . A p_j)
//! x_{j+1} = x_j + alpha_j p_j,            r_{j+1} = r_j - alpha_j A p_j
//! z_{j+1} = M^{-1} r_{j+1}
//! beta_j  = (r_{j+1} . z_{j+1}) / (r_j . z_j),   p_{j+1} = z_{j+1} + beta_j p_j
//! ```
//!
//! **Stopping rule**, per channel: the channel stops when `||r_j|| <= tol ||b||` (the
//! recurred residual), when `r_j . z_j <= 0` (nothing left the preconditioner sees), or on a
//! breakdown `p_j . A p_j` not positive and finite (the iterate is kept). The others go on.
//! A channel with `b = 0` has the solution 0 and no iteration.
//!
//! **Forward-error stop** ([`CgParams::forward_error`]): a small residual is not a small
//! error. With `M = L L^T`, CG on `A x = b` is CG on `A' x' = b'`, `A' = L^{-1} A L^{-T}`,
//! `x' = L^T x`, `b' = L^{-1} b`, whose residual norm is `||r'|| = sqrt(r . M^{-1} r) =
//! sqrt(r_j . z_j)` (free) and `||b'|| = sqrt(b . M^{-1} b)`. Since `||e'|| <= ||r'|| /
//! lambda_min(A')` and `||x'*|| >= ||b'|| / lambda_max(A')`, the error in the norm of `M`
//! obeys
//!
//! ```text
//! ||x_j - x*||_M / ||x*||_M  <=  cond(M^{-1} A) sqrt(r_j . z_j) / sqrt(b . M^{-1} b)
//! ```
//!
//! With a forward-error tolerance `eps`, a channel whose residual passed `tol` goes on
//! until the right-hand side, with `cond` the Lanczos estimate of the run so far
//! ([`lanczos_extremes`], from inside: a lower estimate that grows towards the truth as the
//! extreme Ritz values converge), is at most `eps`. Near-singular systems (detail at Nyquist
//! in an image fit: `cond` of `1e4` and more) thus iterate until their coefficients, not
//! only their residual, are accurate.
//!
//! **Iteration limit**: [`pcg`] never fails. Past [`CgParams::max_iterations`] it returns
//! its iterate with [`CgReport::converged`] false for that channel; each caller names what
//! it then does, one [`IterationLimit`] (fail, fall back to a direct solve, or accept),
//! written at the call (the 1D global solve fails with
//! [`crate::solve::SolveError::NotConverged`]).
//!
//! The report gives per channel the iterations, the relative residual (the recurred
//! `||r|| / ||b||`, or `||b - A x|| / ||b||` recomputed by one more product,
//! [`ResidualReport`]), whether it is at most the tolerance, and on request the Lanczos
//! estimate of `cond(M^{-1} A)` from the iteration's `alpha_j, beta_j`
//! ([`lanczos_condition`]). With `e = x - x*`, `||e|| / ||x*|| <= cond(A) ||b - A x|| / ||b||`.
//!
//! [`cgls`] is the same iteration in the least-squares form (CGLS) for `A = K D`, whose
//! normal matrix `A^T A` is never formed: the residual is kept as `f - A y` in the sample
//! space and its normal residual `s = A^T (f - A y)` is what the iteration orthogonalises.
//!
//! Every channel's sums run in index order, so the bits do not depend on the thread count
//! nor on the other channels.

mod cgls;
mod lanczos;
mod limit;
mod operator;
mod params;
mod pcg;
mod precondition;
mod schwarz;
mod traits;

pub use cgls::cgls;
pub use lanczos::{lanczos_condition, lanczos_extremes};
pub use limit::IterationLimit;
pub use operator::SparseOperator;
pub use params::{CgParams, CgReport, ConditionEstimate, ResidualReport};
pub use pcg::{pcg, pcg_to};
pub use precondition::{Identity, Jacobi, LocalInverse};
pub use schwarz::{AdditiveSchwarz, SchwarzStats};
pub use traits::{Preconditioner, SymmetricOperator};
