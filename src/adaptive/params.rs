//! The parameter groups both refiners read the same way: the tree's local space
//! ([`TreeParams`]: `p`, `rho`), the Dörfler marking ([`MarkingParams`]: `theta`) and when to
//! stop ([`StopParams`]: tolerance, budget, rounds).
//!
//! A round keeps `samples(C) >= ceil(rho)` on every leaf `C` of the tree, marks the fewest
//! leading units holding `theta` of `sum eta^2`, and stops once
//! `sqrt(sum eta^2 / |Omega|) <= tolerance`, at the sample budget or at the round limit
//! (module docs of [`crate::adaptive`]). The ranges each refiner accepts, and the messages
//! that name a fix, are its own (`refine::RefineParams::validate`,
//! `image::adaptive::AdaptiveParams::validate`): the 1D refiner allows `p` up to 10 and `rho`
//! up to 64, the image refiner `p` up to 8 and `rho` up to 256.

use serde::{Deserialize, Serialize};

/// The local space of the tree: vanishing moments and local oversampling.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TreeParams {
    /// Vanishing moments `p`: higher resolves smooth parts with fewer samples; supports (and
    /// so the refined zone around a singularity) are `2p - 1` cells wide.
    pub p: usize,
    /// Local oversampling `rho`: every leaf (one slot of the local space) holds at least
    /// `ceil(rho)` samples. Larger is better conditioned and costs samples everywhere.
    pub rho: f64,
}

impl TreeParams {
    /// Samples per leaf, `ceil(rho)` (at least one).
    pub fn per_leaf(&self) -> usize {
        self.rho.ceil().max(1.0) as usize
    }
}

/// Dörfler marking.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MarkingParams {
    /// Dörfler fraction `theta` in `(0, 1]`: each round marks the largest indicators holding
    /// `theta` of the estimated squared error. Smaller is more selective (fewer samples per
    /// round, more rounds); 1 marks everything that is not yet zero.
    pub theta: f64,
}

impl Default for MarkingParams {
    fn default() -> Self {
        Self { theta: 0.5 }
    }
}

/// When the refinement stops.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StopParams {
    /// Target RMS error per unit measure of the domain, as estimated by the indicator: the
    /// refiner stops once the estimate is at most this.
    pub tolerance: f64,
    /// Sample budget (base samples included): a round adds only as many marks as it can
    /// sample.
    pub budget: usize,
    /// Most refinement rounds (a safety limit).
    pub max_rounds: usize,
}
