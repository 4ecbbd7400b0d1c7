//! The samples of a refinement and everything computed from them once: the oracle's values
//! and the pointwise evaluation of `Psi(n, D)` (`D` the depth limit) at every sample, from
//! which each round's kernel matrix is filtered.

use rand::Rng;
use rand_pcg::Pcg64;
use serde::Serialize;

use super::{RefineError, SampleOracle};
use crate::adaptive::tree::interval::{range_in, Leaf};
use crate::basis::CdvBasis;
use crate::kernel::EvaluationRows;
use crate::sampling::Domain;

/// Whether a sample belongs to the base sampling or was added by refinement.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SampleOrigin {
    /// The base sampling (round 0, top-ups of the base tree included).
    Base,
    /// Added in a refinement round (new leaves, residual probes).
    Refinement,
}

/// One sample.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Sample {
    /// Position in the domain.
    pub x: f64,
    /// Position on the unit interval (`domain.to_unit(x)`, the coordinate the basis sees).
    pub t: f64,
    /// `f(x)`.
    pub value: f64,
    /// Round whose fit first used it (0 = base).
    pub round: usize,
}

impl Sample {
    /// Base or refinement.
    pub fn origin(&self) -> SampleOrigin {
        if self.round == 0 {
            SampleOrigin::Base
        } else {
            SampleOrigin::Refinement
        }
    }
}

/// Samples, values, sorted positions and cached basis evaluations (CSR-like rows).
#[derive(Clone, Debug)]
pub(crate) struct SampleStore {
    pub samples: Vec<Sample>,
    /// Unit positions, ascending (for counting per leaf).
    sorted: Vec<f64>,
    /// The evaluation of `Psi(n, D)` at every sample.
    pub rows: EvaluationRows,
}

impl SampleStore {
    pub fn new() -> Self {
        Self {
            samples: Vec::new(),
            sorted: Vec::new(),
            rows: EvaluationRows::new(),
        }
    }

    pub fn len(&self) -> usize {
        self.samples.len()
    }

    pub fn values(&self) -> Vec<f64> {
        self.samples.iter().map(|s| s.value).collect()
    }

    /// Samples `xs` (domain positions) through the oracle, evaluates `basis` there once and
    /// keeps both.
    pub fn add<O: SampleOracle + ?Sized>(
        &mut self,
        xs: &[f64],
        oracle: &O,
        basis: &CdvBasis,
        round: usize,
    ) -> Result<(), RefineError> {
        let domain = basis.domain();
        let mut new = Vec::with_capacity(xs.len());
        for &x in xs {
            let value = oracle.sample(x);
            if !value.is_finite() {
                return Err(RefineError::NonFiniteValue { x, value });
            }
            new.push(Sample {
                x,
                t: domain.to_unit(x),
                value,
                round,
            });
        }
        let ts: Vec<f64> = new.iter().map(|s| s.t).collect();
        self.rows.push(basis, &ts);
        self.sorted.extend(new.iter().map(|s| s.t));
        self.sorted.sort_by(f64::total_cmp);
        self.samples.extend(new);
        Ok(())
    }

    /// Samples in `leaf` (by the cell convention of [`cell_of`]).
    pub fn count_in(&self, leaf: &Leaf) -> usize {
        self.range_in(leaf).len()
    }

    /// Unit positions of every sample, ascending.
    pub fn sorted(&self) -> &[f64] {
        &self.sorted
    }

    /// The sorted unit positions inside `leaf`.
    pub fn range_in(&self, leaf: &Leaf) -> &[f64] {
        range_in(&self.sorted, leaf)
    }
}

/// New unit positions that bring every leaf to `need` samples: each short leaf is cut into
/// `need` equal strata and every empty stratum gets one jittered point (middle 80 %) until the
/// leaf is full. Positions are returned in the domain, checked to map back into their leaf.
pub(crate) fn fill_leaves(
    sorted: &[f64],
    leaves: &[Leaf],
    need: usize,
    domain: Domain,
    rng: &mut Pcg64,
) -> Result<Vec<f64>, RefineError> {
    let mut out = Vec::new();
    for leaf in leaves {
        let have = range_in(sorted, leaf);
        if have.len() >= need {
            continue;
        }
        let mut missing = need - have.len();
        let (lo, hi) = leaf.unit_bounds();
        let w = (hi - lo) / need as f64;
        for s in 0..need {
            if missing == 0 {
                break;
            }
            let (a, b) = (lo + s as f64 * w, lo + (s + 1) as f64 * w);
            if have.iter().any(|&t| t >= a && t < b) {
                continue;
            }
            let u: f64 = rng.random();
            let t = a + (0.1 + 0.8 * u) * (b - a);
            let x = domain.from_unit(t);
            if !leaf.contains(domain.to_unit(x)) {
                return Err(RefineError::Unresolvable {
                    level: leaf.level,
                    x: domain.from_unit(lo),
                });
            }
            out.push(x);
            missing -= 1;
        }
    }
    Ok(out)
}

/// Samples the leaves would still need (`sum max(0, need - samples(C))`).
pub(crate) fn shortfall(store: &SampleStore, leaves: &[Leaf], need: usize) -> usize {
    leaves
        .iter()
        .map(|l| need.saturating_sub(store.count_in(l)))
        .sum()
}

/// `probes` jittered points per leaf (one per stratum), in the domain.
pub(crate) fn probe_points(
    leaves: &[Leaf],
    probes: usize,
    domain: Domain,
    rng: &mut Pcg64,
) -> Vec<(usize, f64)> {
    let mut out = Vec::with_capacity(leaves.len() * probes);
    for (i, leaf) in leaves.iter().enumerate() {
        let (lo, hi) = leaf.unit_bounds();
        let w = (hi - lo) / probes as f64;
        for s in 0..probes {
            let u: f64 = rng.random();
            let t = lo + (s as f64 + 0.1 + 0.8 * u) * w;
            let x = domain.from_unit(t);
            if leaf.contains(domain.to_unit(x)) {
                out.push((i, x));
            }
        }
    }
    out
}
