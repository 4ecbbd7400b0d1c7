//! Knobs of the refiner: each field says what it costs and what it buys.

use serde::ser::SerializeStruct;
use serde::{Serialize, Serializer};

use super::RefineError;
use crate::adaptive::{MarkingParams, StopParams, TreeParams};
use crate::basis::{minimum_level, FilterFamily, MAX_VANISHING_MOMENTS};
use crate::sampling::{Domain, Layout};
use crate::solve::GlobalLsParams;

pub use crate::adaptive::tree::interval::MAX_DEPTH_LIMIT;

/// How the refiner decides where the signal is not yet resolved.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Indicator {
    /// Predicted coefficients of the missing children of every active wavelet, from the
    /// coefficients near the parent and their decay across levels. Free (no extra samples);
    /// blind to detail that falls between samples.
    Coefficients,
    /// Residual `f - f~` at `probes` jittered probe points per leaf (which then join the
    /// sample set). Measures the error directly, catches detail the coefficients miss, but
    /// spends `probes` samples per leaf and round, also where the signal is smooth.
    Residual {
        /// Probe points per leaf and round.
        probes: usize,
    },
    /// Both: the union of their marks, the larger of their error estimates.
    Both {
        /// Probe points per leaf and round.
        probes: usize,
    },
}

/// Parameters of `refine::refine`, in groups: the local space ([`TreeParams`],
/// shared with the image refiner), the interval tree's levels ([`IntervalTreeParams`]), the
/// base sampling ([`BaseSampling`]), the indicator, the marking ([`MarkingParams`]) and the
/// stop ([`StopParams`]), both shared, and the solve of each round.
///
/// Serialized flat, one key a field, as before the grouping (`domain`, `p`, `coarse`, ...).
#[derive(Clone, Copy, Debug)]
pub struct RefineParams {
    /// The domain `[a, b]`.
    pub domain: Domain,
    /// Vanishing moments `p` and local oversampling `rho` (every leaf holds `ceil(rho)`
    /// samples).
    pub tree: TreeParams,
    /// The levels of the interval tree: filters, coarse level, base depth, depth limit.
    pub interval: IntervalTreeParams,
    /// The base sampling of the whole domain and the seed.
    pub sampling: BaseSampling,
    /// Refinement indicator.
    pub indicator: Indicator,
    /// Dörfler fraction `theta`.
    pub marking: MarkingParams,
    /// Target RMS error `sqrt(int (f - f~)^2 / (b - a))` (positive), sample budget, round
    /// limit.
    pub stop: StopParams,
    /// The global least-squares solve of each round.
    pub solve: GlobalLsParams,
    /// Diagnostics: points of a uniform grid on which each round's error against the oracle is
    /// measured (0 = off). These oracle calls are not samples.
    pub reference_grid: usize,
}

/// The levels of the 1D tree (what the image refiner's quadtree counts differently, in steps
/// below the pixel).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IntervalTreeParams {
    /// Interior filter family; `None` is CDV's choice for `p`.
    pub family: Option<FilterFamily>,
    /// Coarse scaling level `n`; `None` is `j_min(p)`. Larger makes everything more local.
    pub coarse: Option<u32>,
    /// Depth of the uniform base tree; `None` is the deepest level whose leaves the base
    /// samples fill with `rho` each (`rho 2^{d+1} <= m0`, at least `n`).
    pub base_depth: Option<u32>,
    /// Depth limit `D`: finest wavelet level the tree may reach (at most [`MAX_DEPTH_LIMIT`]).
    /// Deeper resolves singularities further at ~`4 (2p - 1) rho` samples per level and
    /// singularity.
    pub max_depth: u32,
}

impl Default for IntervalTreeParams {
    fn default() -> Self {
        Self {
            family: None,
            coarse: None,
            base_depth: None,
            max_depth: 32,
        }
    }
}

/// The base sampling of the 1D refiner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BaseSampling {
    /// Base samples `m0`: the sampling of the whole domain before any refinement.
    pub base_samples: usize,
    /// Layout of the base samples (seeded); leaves it leaves short are topped up.
    pub base_layout: Layout,
    /// Seed of every random choice (base layout, jitter): the same seed gives the same result.
    pub seed: u64,
}

impl Default for BaseSampling {
    fn default() -> Self {
        Self {
            base_samples: 256,
            base_layout: Layout::Jittered,
            seed: 1,
        }
    }
}

impl Default for RefineParams {
    fn default() -> Self {
        Self {
            domain: Domain::UNIT,
            tree: TreeParams { p: 3, rho: 2.0 },
            interval: IntervalTreeParams::default(),
            sampling: BaseSampling::default(),
            indicator: Indicator::Coefficients,
            marking: MarkingParams::default(),
            stop: StopParams {
                tolerance: 1e-4,
                budget: 100_000,
                max_rounds: 1000,
            },
            solve: GlobalLsParams::default(),
            reference_grid: 0,
        }
    }
}

impl Serialize for RefineParams {
    /// The flat form of the ungrouped parameters (the filter family is not serialized).
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut m = serializer.serialize_struct("RefineParams", 16)?;
        m.serialize_field("domain", &self.domain)?;
        m.serialize_field("p", &self.tree.p)?;
        m.serialize_field("coarse", &self.interval.coarse)?;
        m.serialize_field("base_samples", &self.sampling.base_samples)?;
        m.serialize_field("base_layout", &self.sampling.base_layout)?;
        m.serialize_field("base_depth", &self.interval.base_depth)?;
        m.serialize_field("max_depth", &self.interval.max_depth)?;
        m.serialize_field("rho", &self.tree.rho)?;
        m.serialize_field("tolerance", &self.stop.tolerance)?;
        m.serialize_field("budget", &self.stop.budget)?;
        m.serialize_field("indicator", &self.indicator)?;
        m.serialize_field("theta", &self.marking.theta)?;
        m.serialize_field("max_rounds", &self.stop.max_rounds)?;
        m.serialize_field("seed", &self.sampling.seed)?;
        m.serialize_field("solve", &self.solve)?;
        m.serialize_field("reference_grid", &self.reference_grid)?;
        m.end()
    }
}

impl RefineParams {
    /// The filter family (CDV's choice when not given).
    pub fn family(&self) -> FilterFamily {
        self.interval
            .family
            .unwrap_or_else(|| FilterFamily::cdv_default(self.tree.p.max(1)))
    }

    /// The coarse level (`j_min(p)` when not given).
    pub fn coarse(&self) -> u32 {
        self.interval
            .coarse
            .unwrap_or_else(|| minimum_level(self.tree.p.clamp(1, MAX_VANISHING_MOMENTS)))
    }

    /// Samples per leaf, `ceil(rho)`.
    pub fn per_leaf(&self) -> usize {
        self.tree.rho.ceil().max(1.0) as usize
    }

    /// The base depth (given, or from the base samples).
    pub fn base_depth(&self) -> u32 {
        let n = self.coarse();
        self.interval.base_depth.unwrap_or_else(|| {
            let need = self.per_leaf() as f64;
            let mut d = n;
            while d < MAX_DEPTH_LIMIT
                && need * 2f64.powi(d as i32 + 2) <= self.sampling.base_samples as f64
            {
                d += 1;
            }
            d
        })
    }

    /// Samples the leaves of a uniform base tree of depth `depth` need at the least:
    /// `ceil(rho) 2^{depth + 1}` (as `f64`: no overflow at any depth).
    pub fn base_leaf_samples(&self, depth: u32) -> f64 {
        self.per_leaf() as f64 * 2f64.powi(depth as i32 + 1)
    }

    /// The way out of a max depth below the base depth: a value that works.
    fn depth_fix(&self, base: u32) -> String {
        if base <= MAX_DEPTH_LIMIT {
            let mut fix = format!("raise the max depth to at least {base}");
            if self.interval.base_depth.is_none() && self.coarse() <= self.interval.max_depth {
                // The base depth came from the base samples: fewer make it shallower.
                let most = self.base_leaf_samples(self.interval.max_depth) * 2.0 - 1.0;
                fix.push_str(&format!(" or give at most {most} base samples"));
            }
            fix
        } else if self.interval.base_depth.is_some() && self.coarse() <= self.interval.max_depth {
            format!(
                "lower the base depth to at most {}",
                self.interval.max_depth
            )
        } else {
            format!(
                "lower the coarse level n to at most {}",
                self.interval.max_depth.min(MAX_DEPTH_LIMIT)
            )
        }
    }

    /// The way out of a base sampling above the budget: a value that works.
    fn budget_fix(&self, base: u32) -> String {
        let n = self.coarse();
        let jmin = minimum_level(self.tree.p.clamp(1, MAX_VANISHING_MOMENTS));
        let budget = self.stop.budget as f64;
        if self.base_leaf_samples(n) > budget {
            // Even the coarsest base tree this coarse level allows does not fit.
            let fits = (jmin..n)
                .rev()
                .find(|&c| self.base_leaf_samples(c) <= budget);
            return match fits {
                Some(c) => format!("lower the coarse level n to at most {c}"),
                None => format!(
                    "raise the budget to at least {}",
                    self.base_leaf_samples(jmin)
                        .max(self.sampling.base_samples as f64)
                ),
            };
        }
        if self.sampling.base_samples > self.stop.budget {
            return format!("lower the base samples to at most {}", self.stop.budget);
        }
        // A given base depth too deep for the budget.
        let fits = (n..base)
            .rev()
            .find(|&d| self.base_leaf_samples(d) <= budget);
        match fits {
            Some(d) => format!("lower the base depth to at most {d}"),
            None => format!(
                "raise the budget to at least {}",
                self.base_leaf_samples(base)
            ),
        }
    }

    /// Checks every range; called by the refiner.
    pub fn validate(&self) -> Result<(), RefineError> {
        let bad =
            |name, value: String, fix| Err(RefineError::InvalidParameter { name, value, fix });
        if self.tree.p == 0 || self.tree.p > MAX_VANISHING_MOMENTS {
            return bad("p", self.tree.p.to_string(), "choose p in 1..=10");
        }
        if !(self.stop.tolerance.is_finite() && self.stop.tolerance > 0.0) {
            return bad(
                "tolerance",
                self.stop.tolerance.to_string(),
                "give a positive target RMS error, e.g. 1e-4",
            );
        }
        if self.stop.budget == 0 {
            return bad(
                "budget",
                "0".into(),
                "give a positive sample budget, e.g. 4096",
            );
        }
        if self.sampling.base_samples == 0 {
            return bad(
                "base samples",
                "0".into(),
                "give at least one base sample, e.g. 256",
            );
        }
        if !(self.tree.rho.is_finite() && self.tree.rho >= 1.0 && self.tree.rho <= 64.0) {
            return bad(
                "rho",
                self.tree.rho.to_string(),
                "give a local oversampling in [1, 64], e.g. 2",
            );
        }
        if !(self.marking.theta.is_finite()
            && self.marking.theta > 0.0
            && self.marking.theta <= 1.0)
        {
            return bad(
                "theta",
                self.marking.theta.to_string(),
                "give a marking fraction in (0, 1], e.g. 0.5",
            );
        }
        if let Indicator::Residual { probes } | Indicator::Both { probes } = self.indicator {
            if probes == 0 {
                return bad(
                    "probes",
                    "0".into(),
                    "give at least one probe point per leaf",
                );
            }
        }
        if self.interval.max_depth > MAX_DEPTH_LIMIT {
            return bad(
                "max depth",
                self.interval.max_depth.to_string(),
                "choose a depth limit of at most 52 (MAX_DEPTH_LIMIT)",
            );
        }
        let n = self.coarse();
        let base = self.base_depth();
        // The base tree has 2^{base+1} leaves of ceil(rho) samples each: refused here, before
        // a tree or a sample of that size is allocated.
        let required = self.base_leaf_samples(base);
        if required > self.stop.budget as f64 || self.sampling.base_samples > self.stop.budget {
            return Err(RefineError::BudgetBelowBase {
                budget: self.stop.budget,
                required: required
                    .max(self.sampling.base_samples as f64)
                    .min(u64::MAX as f64) as u64,
                fix: self.budget_fix(base),
            });
        }
        if self.interval.max_depth < base {
            return Err(RefineError::MaxDepthBelowBase {
                max_depth: self.interval.max_depth,
                base_depth: base,
                fix: self.depth_fix(base),
            });
        }
        if base < n {
            return bad(
                "base depth",
                base.to_string(),
                "the base tree needs every wavelet of the coarse level: choose base depth >= n",
            );
        }
        self.solve.validate()?;
        Ok(())
    }
}
