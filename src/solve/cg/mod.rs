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
mod pcg;
mod precondition;
mod schwarz;

pub use cgls::cgls;
pub use lanczos::{lanczos_condition, lanczos_extremes};
pub use limit::IterationLimit;
pub use operator::SparseOperator;
pub use pcg::pcg;
pub use precondition::{Identity, Jacobi, LocalInverse};
pub use schwarz::{AdditiveSchwarz, SchwarzStats};

use serde::Serialize;

/// A symmetric positive (semi)definite operator `A`, applied to several vectors at once.
pub trait SymmetricOperator: Sync {
    /// Unknowns `n` (the length of every vector).
    fn dim(&self) -> usize;
    /// `q_c = A p_c` for every `c` (`q[c]` is overwritten or replaced by a vector of length
    /// [`Self::dim`]).
    fn apply(&self, p: &[&[f64]], q: &mut [Vec<f64>]);
}

/// A preconditioner `M^{-1} ≈ A^{-1}` (symmetric positive definite on the range of `A`),
/// applied to several vectors at once.
pub trait Preconditioner: Sync {
    /// `z_c = M^{-1} r_c` for every `c` (`z[c]`, of the length of `r[c]`, overwritten).
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]);
}

/// Which relative residual the report gives.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ResidualReport {
    /// The recurred `||r_j|| / ||b||` (free; drifts from the true one by rounding).
    Recurred,
    /// `||b - A x|| / ||b||` from one more product with `A` (the true residual).
    Recomputed,
}

/// Whether the Lanczos condition estimate is computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum ConditionEstimate {
    /// Not estimated (the `alpha_j, beta_j` are not kept).
    Skip,
    /// `cond(M^{-1} A)` from the Lanczos tridiagonal of the run (a dense eigenvalue
    /// problem of the iterations' size, at most 300).
    Lanczos,
}

/// What a conjugate-gradient solve is asked for.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CgParams {
    /// Stop a channel at `||r|| <= tolerance ||b||`.
    pub tolerance: f64,
    /// Most iterations; past them the iterate is returned, `converged` false.
    pub max_iterations: usize,
    /// The residual reported (recurred: free; recomputed: one more product, exact).
    pub residual: ResidualReport,
    /// The condition estimate (costs keeping two numbers an iteration and one small
    /// eigenvalue problem).
    pub condition: ConditionEstimate,
    /// The forward-error stop (module docs): `Some(eps)` also asks `cond(M^{-1} A)
    /// ||r||_{M^{-1}} / ||b||_{M^{-1}} <= eps` of a channel before it stops (keeps the
    /// Lanczos coefficients, `O(j)` a check); `None` stops on the residual alone.
    pub forward_error: Option<f64>,
}

/// What one conjugate-gradient solve did, per channel.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CgReport {
    /// Iterations taken per channel.
    pub iterations: Vec<usize>,
    /// Final relative residual per channel (see [`CgParams::residual`]; for [`cgls`] the
    /// recurred normal residual `||A^T r|| / ||A^T f||`).
    pub relative_residual: Vec<f64>,
    /// Per channel, whether the tolerance (and the forward-error tolerance, when asked) was
    /// reached.
    pub converged: Vec<bool>,
    /// Lanczos estimate of `cond(M^{-1} A)` per channel (1 with fewer than two iterations),
    /// when asked.
    pub condition: Option<Vec<f64>>,
    /// With [`CgParams::forward_error`]: per channel the final estimated bound on the
    /// relative error `||x - x*||_M / ||x*||_M` (module docs).
    pub forward_error: Option<Vec<f64>>,
}

impl CgReport {
    /// Whether every channel reached the tolerance.
    pub fn all_converged(&self) -> bool {
        self.converged.iter().all(|&c| c)
    }
    /// The first channel that did not reach the tolerance.
    pub fn first_unconverged(&self) -> Option<usize> {
        self.converged.iter().position(|&c| !c)
    }
}
