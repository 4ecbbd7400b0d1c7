//! The adaptive refiner (docs/design.md §6; paper supplement §4, figure 4): an adaptive wavelet tree
//! and the samples that keep it locally oversampled, grown together until a tolerance, a
//! depth limit or a sample budget is reached.
//!
//! The basis is a tree `T`: the coarse scaling functions `phi_{n,k}` and a set of wavelets
//! closed under "parent present" (parent of `psi_{j,k}` is `psi_{j-1, floor(k/2)}`). Its local
//! depth `d(x)` is the finest level of an active wavelet whose support contains `x` (`n - 1`
//! if none); the points of depth `d` form whole dyadic cells of level `d + 1` (supports nest),
//! the *leaves*, and each leaf is one slot of the local space `V_{d+1}`: the tree has
//! `2^{d(x)+1}` functions per unit length around `x`. The sampling invariant is
//!
//! ```text
//! samples(C) >= ceil(rho)      for every leaf C,
//! ```
//!
//! so every active function has at least `rho` samples per slot of its support. One round:
//!
//! 1. fit `c = argmin ||K c - f||` on the active set (sparse Cholesky of `K^T K`, kept up
//!    to date between rounds);
//! 2. indicate ([`Indicator`]): predict the coefficient of every missing child `psi_{j+1,k'}`
//!    of an active wavelet from the coefficients near its parent and their decay
//!    `r = |c_j| / |c_{j-1}|` across levels (`|c~| = r |c_j| / sqrt(1 - r^2)`, the norm of the
//!    predicted subtree), and/or measure the residual at probe points in each leaf;
//! 3. stop if the estimated RMS error `sqrt(sum eta^2 / (b - a))` is below the tolerance;
//! 4. mark the largest indicators holding a fraction `theta` of the estimated error (Dörfler
//!    marking), as many as the budget allows, and add them to the tree: one level deeper where
//!    flagged;
//! 5. add jittered samples to every leaf that has fewer than `ceil(rho)` (only the new, finer
//!    leaves lack them), so the invariant holds again.
//!
//! Between rounds the refiner keeps and reuses: the sample values (every oracle call is a
//! sample, made once), the pointwise evaluation of every basis function of `Psi(n, D)` at every
//! sample (cached rows), the rows of `K` restricted to the tree and the normal equations
//! `K^T K c = K^T f` themselves, updated by what the round added (new samples, new functions:
//! module `normal`, cost in the number of new samples and functions), the sorted positions
//! (leaf counts by binary search) and the random stream. [`Refinement::rebuild`] recomputes
//! all of it from scratch as a check. Rebuilt each round: the tree's coverage and leaves
//! (`O(P)`) and the sparse Cholesky factor of `K^T K` (finest level eliminated first).

//! The refiner is a client of the pipeline: each round's columns are a sparse
//! [`crate::kernel::ActiveSet`] ([`crate::kernel::ActiveSet::from_sorted`], looked up by
//! [`crate::kernel::ActiveSet::column`]; trees go to level [`MAX_DEPTH_LIMIT`]), its `K` is
//! filtered from the cached evaluation rows ([`crate::kernel::EvaluationRows`]), each fit is a
//! [`crate::reconstruct::Fit`] ([`Refinement::fit`]) and evaluates through
//! [`crate::reconstruct::Fit::evaluate`], stopping at the tree's local depth.
//!
//! ```
//! use rkwave::refine::{refine, RefineParams, SampleOracle};
//!
//! let f = |x: f64| if x < 0.4 { x } else { 1.0 + x }; // one jump
//! let mut params = RefineParams::default();
//! params.interval.max_depth = 10;
//! params.stop.tolerance = 1e-6;
//! let result = refine(&f, &params)?;
//! assert!(result.tree.local_depth(0.4) > result.tree.local_depth(0.9));
//! # Ok::<(), rkwave::refine::RefineError>(())
//! ```

pub mod density;
mod error;
pub mod experiment;
mod indicator;
mod measure;
mod normal;
mod oracle;
mod params;
mod refinement;
mod refiner;
mod samples;

#[cfg(test)]
mod tests;

pub use crate::adaptive::tree::interval::{
    cell_of, support_cells, Leaf, WaveletTree, ACTIVE_SET_MAX_LEVEL,
};
pub use crate::adaptive::StopReason;
pub use crate::adaptive::{MarkingParams, StopParams, TreeParams};
pub use error::RefineError;
pub use measure::{grid_error, quadrature_error, ErrorFigures, Reconstruction};
pub use oracle::{ExpressionError, ExpressionOracle, SampleOracle, SignalOracle};
pub use params::{BaseSampling, Indicator, IntervalTreeParams, RefineParams, MAX_DEPTH_LIMIT};
pub use refinement::{Refinement, RoundLog, RoundTimes};
pub use refiner::{refine, Refiner, Step};
pub use samples::{Sample, SampleOrigin};
