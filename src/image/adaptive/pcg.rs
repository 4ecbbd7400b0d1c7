//! Matrix-free preconditioned conjugate gradients for the tree fit.
//!
//! The tree's functions are a subset `T` of the orthonormal non-standard basis, and every one
//! of them is a combination of the single-scale functions of `V_Jx (x) V_Jy` through the 2D
//! synthesis `S` ([`TensorBasis::synthesis`], orthogonal: `S^T` is the analysis). So the tree
//! kernel factors as
//!
//! ```text
//! K_T = E S P_T,        E[i, k] = Phi_k(x_i, y_i)   (single-scale rows, (2p - 1)^2 entries),
//! ```
//!
//! with `P_T` the injection of the tree's coefficients into the Mallat layout. One product
//! `G v = K_T^T K_T v = P_T^T S^T E^T E S P_T v` costs two 2D FWTs and two passes over `E`:
//! `O(nx ny + m (2p - 1)^2)`, against the `~300 P` entries of an assembled `G` whose rows mix
//! every level. `E` does not depend on the tree (a round's fit builds it afresh for all
//! samples; [`SingleScaleRows::append`] could continue it).
//!
//! The normal equations `G c = K_T^T f` are solved by conjugate gradients preconditioned by
//! `diag G`, `G_aa = sum_i Psi_a(x_i, y_i)^2`, from one pass of the multilevel evaluator over
//! the samples (it removes the `4^depth` spread of the sample density between deep and
//! shallow regions, and conditions better than the count estimate `G_aa ~ n_a / |supp_a|`,
//! `n_a` the samples in the `(2p - 1)^2` cells around the function's own, which is kept for
//! reporting unsampled functions). A function with no sample in its support has a zero column in `K_T`: its
//! residual is always 0, so it keeps its start value (0 for a new function), as the direct
//! solve's ridge pins it near 0.
//!
//! *Limit.* At `rho = 2` samples per slot the least-squares problem itself is not well
//! conditioned (jittered pairs of samples leave local near-null directions), so Jacobi-PCG
//! takes hundreds of iterations to a tight residual, more work than the direct solve at small
//! sizes (docs/measurements.md, "The iterative solvers"). So PCG is opt-in; a stronger (local /
//! Schwarz, or previous-factor) preconditioner is what it lacks.
//!
//! Stopping: the relative residual of the normal equations `||K_T^T (f - K_T c)|| / ||K_T^T
//! f|| <= tol`. Then the coefficient error is at most `kappa(G) tol` relative, `kappa`
//! estimated from the Lanczos tridiagonal of the iteration (its extreme eigenvalues are
//! those of the preconditioned `G` from inside).
//!
//! The conjugate gradient itself is the crate's one ([`crate::solve::cg::pcg`], with
//! [`Jacobi`] on the exact diagonal and the Lanczos estimate); the pieces it runs on live
//! beside this file: the solver choice ([`TreeSolver`]), the single-scale rows
//! ([`SingleScaleRows`], [`SingleScaleColumns`]), the operator ([`TreeNormalOperator`]) and
//! the diagonal ([`DiagonalSums`]).

pub use super::diagonal::DiagonalSums;
pub use super::operator::TreeNormalOperator;
pub(crate) use super::single_scale::multilevel_values;
pub use super::single_scale::{SingleScaleColumns, SingleScaleRows};
pub use super::solver::{TreeSolver, DIRECT_FALLBACK_MAX};

use crate::solve::cg::{self, CgParams, CgReport, ConditionEstimate, Jacobi, ResidualReport};
use crate::solve::vectors::interleave;

/// Solves `G c = K_T^T f` by PCG from `start` (zero off the tree; `None`: zero).
pub fn pcg(
    op: &TreeNormalOperator<'_>,
    f: &[f64],
    start: Option<&[f64]>,
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<f64>, CgReport) {
    let starts = start.map(|s| vec![s.to_vec()]);
    let (mut x, report) = pcg_many(op, &[f], starts.as_deref(), tolerance, max_iterations);
    (x.pop().expect("one channel"), report)
}

/// Solves `G c_c = K_T^T f_c` for every channel `c` by PCG from `starts` (per channel, zero
/// off the tree; `None`: zero): independent conjugate-gradient runs in lockstep, whose
/// products `G p_c` share one pass over the rows per iteration
/// ([`TreeNormalOperator::apply_many`]), preconditioned by the exact Jacobi diagonal. A
/// channel stops at its own tolerance; the others go on. The report's residuals are
/// recomputed, `||K_T^T (f - K_T c)|| / ||K_T^T f||`, with the Lanczos condition estimate.
pub fn pcg_many(
    op: &TreeNormalOperator<'_>,
    fs: &[&[f64]],
    starts: Option<&[Vec<f64>]>,
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<Vec<f64>>, CgReport) {
    let k = fs.len();
    let b = op.rhs_many(&interleave(fs), k);
    let n = op.basis().len();
    let xs: Vec<Vec<f64>> = (0..k)
        .map(|c| match starts.and_then(|s| s.get(c)) {
            Some(s) => {
                let mut x = s.clone();
                op.restrict(&mut x);
                x
            }
            None => vec![0.0; n],
        })
        .collect();
    let params = CgParams {
        tolerance,
        max_iterations,
        residual: ResidualReport::Recomputed,
        condition: ConditionEstimate::Lanczos,
    };
    let b: Vec<&[f64]> = b.iter().map(|b| b.as_slice()).collect();
    cg::pcg(
        op,
        &Jacobi::new(op.inverse_diagonal()),
        &b,
        Some(xs),
        &params,
    )
}
