//! The outcome of a refinement ([`Refinement`]) and its per-round log: the tree, the samples,
//! `K`, the coefficients and how each round went, with evaluation and a from-scratch rebuild
//! to compare a round's cost against (split from the loop in `refiner.rs`).

use std::time::Instant;

use serde::Serialize;
use sprs::CsMat;

use super::measure::{ErrorFigures, Reconstruction};
use super::{RefineError, RefineParams, Sample};
use crate::adaptive::tree::interval::WaveletTree;
use crate::adaptive::StopReason;
use crate::kernel::{kernel_matrix, ActiveSet, LevelChoice};
use crate::reconstruct::{Fit, SolveReport, Timings};
use crate::solve::{global_ls, GlobalReport};

/// Seconds spent in one round (diagnostic error measurement excluded).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct RoundTimes {
    /// Oracle calls and basis evaluation at this round's new samples.
    pub sample_s: f64,
    /// `K` from the cached evaluations.
    pub kernel_s: f64,
    /// The least-squares solve.
    pub solve_s: f64,
    /// The indicator (probes included).
    pub indicate_s: f64,
    /// Marking, the budget search and deepening the tree.
    pub mark_s: f64,
    /// All of the above.
    pub total_s: f64,
}

/// What one round saw and did: the fit of this round, its indicator, the marks made.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RoundLog {
    /// Round number (0 = the base fit).
    pub round: usize,
    /// Samples in this round's fit.
    pub samples: usize,
    /// Samples added for this round's fit.
    pub new_samples: usize,
    /// Active functions `P`.
    pub basis_size: usize,
    /// Finest active wavelet level.
    pub depth: i32,
    /// Leaves of the tree.
    pub leaves: usize,
    /// Fewest samples in a leaf (the invariant: at least `ceil(rho)`).
    pub min_leaf_samples: usize,
    /// Largest indicator of this fit (`None` if not computed).
    pub indicator_max: Option<f64>,
    /// Estimated RMS error of this fit (`None` if not computed).
    pub estimated_error: Option<f64>,
    /// Error against the oracle on the reference grid (if requested).
    pub error: Option<ErrorFigures>,
    /// Marked refinements accepted after this fit.
    pub marked: usize,
    /// Wavelets those marks added (ancestors included).
    pub added_functions: usize,
    /// Seconds per stage.
    pub times: RoundTimes,
}

/// The outcome of a refinement.
#[derive(Clone, Debug)]
pub struct Refinement {
    /// The final tree.
    pub tree: WaveletTree,
    /// Every sample, in the order of the rows of `kernel`.
    pub samples: Vec<Sample>,
    /// The fit on the tree: its active set (the tree's functions, ascending global index,
    /// over [`WaveletTree::basis`]), one channel of coefficients and the last solve
    /// ([`SolveReport::Global`]).
    pub fit: Fit,
    /// The final kernel matrix `K` (`samples x columns`).
    pub kernel: CsMat<f64>,
    /// One entry per round.
    pub rounds: Vec<RoundLog>,
    /// Why it stopped.
    pub stop: StopReason,
    /// Depth of the base tree.
    pub base_depth: u32,
    /// The parameters it ran with.
    pub params: RefineParams,
}

impl Refinement {
    /// The reconstruction `sum_a c_a Psi_a(x)` at domain positions `xs` ([`Fit::evaluate`]).
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError> {
        Ok(self.fit.evaluate(xs)?.swap_remove(0))
    }
    /// The columns of `kernel`: active global indices, ascending.
    pub fn columns(&self) -> &[usize] {
        self.fit.active.indices()
    }
    /// The coefficients, one per column.
    pub fn coefficients(&self) -> &[f64] {
        &self.fit.coefficients[0]
    }
    /// Everything a refinement round reuses, recomputed from scratch on the final tree (the
    /// oracle aside): `K` from a new evaluation of the basis at every sample
    /// ([`kernel_matrix`]) and the solve. Returns the coefficients (equal to
    /// [`Refinement::coefficients`]) and the times, as the cost of a full rebuild to set
    /// against a round's.
    pub fn rebuild(&self) -> Result<(Vec<f64>, RoundTimes), RefineError> {
        let t0 = Instant::now();
        let xs: Vec<f64> = self.samples.iter().map(|s| s.x).collect();
        let k = kernel_matrix(&self.fit.active, &xs)?;
        let kernel_s = t0.elapsed().as_secs_f64();
        let t2 = Instant::now();
        let values: Vec<f64> = self.samples.iter().map(|s| s.value).collect();
        let mut solved = global_ls(&k, &[&values], &self.params.solve)?;
        let solve_s = t2.elapsed().as_secs_f64();
        Ok((
            solved.coefficients.swap_remove(0),
            RoundTimes {
                kernel_s,
                solve_s,
                total_s: kernel_s + solve_s,
                ..RoundTimes::default()
            },
        ))
    }

    /// Samples of the base sampling.
    pub fn base_samples(&self) -> usize {
        self.samples.iter().filter(|s| s.round == 0).count()
    }
    /// The last solve.
    pub fn solve(&self) -> Option<&GlobalReport> {
        match &self.fit.solve {
            SolveReport::Global(g) => Some(g),
            _ => None,
        }
    }
}

impl Reconstruction for Refinement {
    fn values_at(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError> {
        self.evaluate(xs)
    }
}

/// The fit on `active` with coefficients `coefficients` (one per column) from the global solve
/// `solve`, `samples` samples: the library's [`Fit`].
pub(crate) fn tree_fit(
    active: ActiveSet,
    coefficients: Vec<f64>,
    solve: GlobalReport,
    samples: usize,
) -> Fit {
    let basis = active.basis();
    Fit {
        levels: LevelChoice {
            coarse: basis.coarse(),
            fine: basis.fine(),
            oversampling: samples as f64 / active.len().max(1) as f64,
        },
        active,
        coefficients: vec![coefficients],
        timings: Timings::default(),
        solve: SolveReport::Global(solve),
        fallbacks: Vec::new(),
    }
}
