//! Why an adaptive run stops, the same reasons in 1D and 2D: the estimated error
//! `sqrt(sum eta^2 / |Omega|)` at most the tolerance, nothing markable left above the depth
//! limit, the sample budget, the resolution of `f64` (1D), the round limit.

use serde::{Deserialize, Serialize};

/// Why the refiner stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StopReason {
    /// The estimated RMS error is below the tolerance.
    Tolerance,
    /// What is left of the estimated error sits at the depth limit.
    DepthLimit,
    /// The next marked refinement would exceed the sample budget.
    Budget,
    /// What is left of the estimated error sits where a deeper leaf could not hold `ceil(rho)`
    /// distinct `f64` positions (the resolution of `f64` near that position).
    Resolution,
    /// The safety limit on rounds.
    MaxRounds,
}
