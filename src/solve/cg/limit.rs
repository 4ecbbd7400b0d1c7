//! The one policy for a conjugate-gradient solve that stops at its iteration limit short of
//! its tolerance ([`IterationLimit`]): `pcg` and `cgls` never fail, and
//! each caller names what it does with an unconverged channel, at the call, from this list.

use serde::Serialize;

/// What a caller does when a CG solve stops at `CgParams::max_iterations` (or on a
/// breakdown) with a channel's relative residual above the tolerance. Every caller of the
/// solver layer's CG names one at the call; the branch taken is in its report.
///
/// | caller | policy | where it is said |
/// |---|---|---|
/// | 1D global least squares by CGLS (`solve::global_ls`) | [`IterationLimit::Fail`] | the error `SolveError::NotConverged` |
/// | stencil system (uniform 2D fit, `NormalSolver::Cg`) | [`IterationLimit::FallBack`] | `StencilCgReport::fallback` (printed) |
/// | tree system (adaptive 2D fit, PCG) up to `DIRECT_FALLBACK_MAX` unknowns | [`IterationLimit::FallBack`] | `TreeFitReport::solver` `"pcg->direct"` |
/// | tree system above that, and its Schwarz PCG | [`IterationLimit::Accept`] | `TreeFitReport::converged` false |
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum IterationLimit {
    /// The solve's contract is the tolerance: an unconverged channel is an error of kind
    /// `NotConverged`, naming the channel, its iterations and its residual.
    Fail,
    /// Solve the same system by a direct method (the sparse Cholesky) instead, and report
    /// that it was done and why.
    FallBack,
    /// Keep the iterate, reported as not converged with its relative residual (the error
    /// bound `||e|| / ||x*|| <= cond(A) ||b - A x|| / ||b||` holds for it as for any iterate).
    Accept,
}

impl IterationLimit {
    /// The policy in words, for reports and notes.
    pub fn describe(self) -> &'static str {
        match self {
            IterationLimit::Fail => "fail (an error naming the channel and its residual)",
            IterationLimit::FallBack => "fall back to the direct solve (reported)",
            IterationLimit::Accept => "accept the iterate (reported as not converged)",
        }
    }
}
