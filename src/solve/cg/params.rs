//! The parameters and the report of a conjugate-gradient run.

use serde::Serialize;

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
    /// `cond(M^{-1} A)` from the Lanczos tridiagonal of the run (its extreme eigenvalues
    /// by Sturm bisection, `O(j)` each).
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
    /// Lanczos coefficients, `O(j)` a check); `None` stops on the residual alone. [`super::cgls`]
    /// does not take it.
    pub forward_error: Option<f64>,
}

/// What one conjugate-gradient solve did, per channel.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CgReport {
    /// Iterations taken per channel.
    pub iterations: Vec<usize>,
    /// Final relative residual per channel (see [`CgParams::residual`]; for CGLS the
    /// recurred normal residual `||A^T r|| / ||A^T f||`).
    pub relative_residual: Vec<f64>,
    /// Per channel, the relative residual of the start, `||b - A x_0|| / ||b||` (1 from a
    /// zero start; empty for [`super::cgls`]).
    pub start_residual: Vec<f64>,
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
