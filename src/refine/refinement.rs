//! The outcome of a refinement ([`Refinement`]) and its per-round log: the tree, the samples,
//! `K`, the coefficients and how each round went, with evaluation and a from-scratch rebuild
//! to compare a round's cost against (split from the loop in `refiner.rs`).

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMat;

use super::measure::{ErrorFigures, Reconstruction};
use super::refiner::StopReason;
use super::tree::{column_of, WaveletTree};
use super::{RefineError, RefineParams, Sample};
use crate::basis::{BasisError, BasisValue, CdvBasis};
use crate::kernel::LevelChoice;
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
    /// The columns of `kernel`: active global indices, ascending.
    pub columns: Vec<usize>,
    /// The coefficients, one per column.
    pub coefficients: Vec<f64>,
    /// The final kernel matrix `K` (`samples x columns`).
    pub kernel: CsMat<f64>,
    /// The last solve.
    pub solve: GlobalReport,
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
    /// The reconstruction `sum_a c_a Psi_a(x)` at domain positions `xs`.
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError> {
        evaluate_sparse(&self.tree.basis()?, &self.columns, &self.coefficients, xs)
    }
    /// Everything a refinement round reuses, recomputed from scratch on the final tree (the
    /// oracle aside): the evaluation of the basis at every sample, `K`, the solve. Returns the
    /// coefficients (equal to [`Refinement::coefficients`]) and the times, as the cost of a
    /// full rebuild to set against a round's.
    pub fn rebuild(&self) -> Result<(Vec<f64>, RoundTimes), RefineError> {
        let t0 = Instant::now();
        let basis = self.tree.basis()?;
        let unit: Vec<f64> = self.samples.iter().map(|s| s.t).collect();
        let rows: Vec<(Vec<usize>, Vec<usize>, Vec<f64>)> = unit
            .par_chunks(CHUNK)
            .map(|chunk| {
                let mut ev = basis.evaluator();
                let mut out: Vec<BasisValue> = Vec::with_capacity(256);
                let (mut counts, mut index, mut value) = (Vec::new(), Vec::new(), Vec::new());
                for &t in chunk {
                    ev.eval_unit_into(t, &mut out);
                    let before = index.len();
                    for v in &out {
                        if let Some(c) = column_of(&self.columns, v.index) {
                            index.push(c);
                            value.push(v.value);
                        }
                    }
                    counts.push(index.len() - before);
                }
                (counts, index, value)
            })
            .collect();
        let sample_s = t0.elapsed().as_secs_f64();
        let t1 = Instant::now();
        let mut indptr = vec![0usize];
        let (mut indices, mut data) = (Vec::new(), Vec::new());
        for (counts, index, value) in rows {
            for c in counts {
                indptr.push(indptr[indptr.len() - 1] + c);
            }
            indices.extend(index);
            data.extend(value);
        }
        let k = CsMat::new((unit.len(), self.columns.len()), indptr, indices, data);
        let kernel_s = t1.elapsed().as_secs_f64();
        let t2 = Instant::now();
        let values: Vec<f64> = self.samples.iter().map(|s| s.value).collect();
        let mut solved = global_ls(&k, &[&values], &self.params.solve)?;
        let solve_s = t2.elapsed().as_secs_f64();
        Ok((
            solved.coefficients.swap_remove(0),
            RoundTimes {
                sample_s,
                kernel_s,
                solve_s,
                total_s: sample_s + kernel_s + solve_s,
                ..RoundTimes::default()
            },
        ))
    }

    /// Samples of the base sampling.
    pub fn base_samples(&self) -> usize {
        self.samples.iter().filter(|s| s.round == 0).count()
    }
    /// The result as a [`Fit`] over an [`crate::kernel::ActiveSet`] (for the rest of the
    /// crate's tools); refuses trees deeper than
    /// [`crate::refine::ACTIVE_SET_MAX_LEVEL`].
    pub fn fit(&self) -> Result<Fit, RefineError> {
        let active = self.tree.active_set()?;
        let basis = active.basis();
        Ok(Fit {
            levels: LevelChoice {
                coarse: basis.coarse(),
                fine: basis.fine(),
                oversampling: self.samples.len() as f64 / active.len() as f64,
            },
            active,
            coefficients: vec![self.coefficients.clone()],
            timings: Timings::default(),
            solve: SolveReport::Global(self.solve.clone()),
            fallbacks: Vec::new(),
        })
    }
}

/// Samples per parallel evaluation work item.
const CHUNK: usize = 4096;

/// The number of entries of the ascending `list` below `a`, found by doubling steps from the
/// front then bisection: `O(log k)` for an answer `k` (mostly 0 or 1 in a merge).
fn gallop(list: &[usize], a: usize) -> usize {
    let mut hi = 1;
    while hi <= list.len() && list[hi - 1] < a {
        hi *= 2;
    }
    let lo = hi / 2;
    let hi = hi.min(list.len());
    lo + list[lo..hi].partition_point(|&c| c < a)
}

/// `sum_c coefficients[c] Psi_{columns[c]}(x)` for every `x` of `xs`, `basis` holding them all.
pub(crate) fn evaluate_sparse(
    basis: &CdvBasis,
    columns: &[usize],
    coefficients: &[f64],
    xs: &[f64],
) -> Result<Vec<f64>, RefineError> {
    let domain = basis.domain();
    if let Some(&x) = xs.iter().find(|x| !domain.contains(**x)) {
        return Err(RefineError::Basis(BasisError::PositionOutside {
            x,
            a: domain.a(),
            b: domain.b(),
        }));
    }
    let blocks: Vec<Vec<f64>> = xs
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut ev = basis.evaluator();
            let mut out: Vec<BasisValue> = Vec::with_capacity(256);
            chunk
                .iter()
                .map(|&x| {
                    ev.eval_unit_into(domain.to_unit(x), &mut out);
                    // Both lists ascend: a merge, galloping over the columns in between.
                    let mut sum = 0.0;
                    let mut lo = 0;
                    for v in &out {
                        lo += gallop(&columns[lo..], v.index);
                        if columns.get(lo) == Some(&v.index) {
                            sum += coefficients[lo] * v.value;
                        }
                    }
                    sum
                })
                .collect()
        })
        .collect();
    Ok(blocks.concat())
}

impl Reconstruction for Refinement {
    fn values_at(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError> {
        self.evaluate(xs)
    }
}
