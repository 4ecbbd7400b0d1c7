//! What a fit did: the report of the solve that produced the coefficients and every fallback
//! taken on the way, as typed data (printed by the command line as text and JSON).

use std::fmt;

use serde::Serialize;

use super::SingleScaleReport;
use crate::solve::{GlobalReport, LocalStats};

/// The report of the solve that produced a fit's coefficients.
///
/// ```
/// use rkwave::reconstruct::{fit, FitParams, SolveReport};
/// use rkwave::sampling::Domain;
///
/// let xs: Vec<f64> = (0..400).map(|i| (i as f64 + 0.5) / 400.0).collect();
/// let ys: Vec<f64> = xs.iter().map(|x| x * x).collect();
/// let f = fit(&xs, &[&ys], Domain::UNIT, &FitParams::default())?;
/// match &f.solve {
///     SolveReport::SingleScale(rep) => assert_eq!(rep.deficient, 0),
///     other => panic!("the default method is the single-scale solve, got {other:?}"),
/// }
/// # Ok::<(), rkwave::reconstruct::ReconstructError>(())
/// ```
#[derive(Clone, Debug, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum SolveReport {
    /// Global least squares through the single-scale basis `V_{N+1}`.
    SingleScale(SingleScaleReport),
    /// Local inversion (also after a single-scale fallback, see [`Fallback::LocalInversion`]).
    Local(LocalStats),
    /// Global sparse least squares.
    Global(GlobalReport),
    /// Dense SVD pseudo-inverse with relative cut-off `cutoff`.
    Dense {
        /// Relative singular value cut-off.
        cutoff: f64,
    },
    /// The coefficients were given, not solved for (e.g. a fit assembled by a report).
    Given,
}

/// A departure from the requested levels or method, taken so that the result stays
/// determined by the samples.
///
/// ```
/// use rkwave::reconstruct::Fallback;
///
/// let f = Fallback::FinestLevelLowered { by: 2 };
/// assert!(f.to_string().contains("lowered by 2"));
/// ```
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
#[non_exhaustive]
pub enum Fallback {
    /// Automatic levels: the finest level `N` was lowered by `by` because the samples left
    /// single-scale directions undetermined at the automatic level.
    FinestLevelLowered {
        /// Levels dropped.
        by: u32,
    },
    /// The single-scale normal equations had `deficient` undetermined directions
    /// (`unsampled` of them functions without any sample): local inversion's truncated
    /// pseudo-inverses were used instead.
    LocalInversion {
        /// Pivots below [`super::PIVOT_TOLERANCE`].
        deficient: usize,
        /// Single-scale functions without a sample in their support.
        unsampled: usize,
    },
}

impl fmt::Display for Fallback {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::FinestLevelLowered { by } => write!(
                f,
                "finest level lowered by {by}: the samples left single-scale directions \
                 undetermined at the automatic level"
            ),
            Self::LocalInversion {
                deficient,
                unsampled,
            } => write!(
                f,
                "single-scale normal equations have {deficient} undetermined directions \
                 ({unsampled} functions without samples): local inversion used instead"
            ),
        }
    }
}
