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
    /// Automatic levels on strongly non-uniform samples: an adaptive tree whose local depth
    /// follows the local sample count replaced the uniform levels
    /// (`crate::adaptive::density`), solved by global least squares.
    DensityTree {
        /// Coarse scaling level of the tree.
        coarse: u32,
        /// Finest wavelet level of the tree.
        fine: u32,
        /// Active functions.
        functions: usize,
        /// Leaves (local slots) of the tree.
        leaves: usize,
        /// Ridge the solve added on numerically singular directions (0 = none).
        ridge: f64,
        /// Functions of the tree left out (coefficient 0): less than half of their mass
        /// `int Psi^2` lies where samples are.
        unseen: usize,
        /// Sample-free intervals `[a, b]` (between the neighbouring samples) holding a whole
        /// leaf without samples: the reconstruction there is the coarse functions' bridge.
        empty: Vec<[f64; 2]>,
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
            Self::DensityTree {
                coarse,
                fine,
                functions,
                leaves,
                ridge,
                unseen,
                empty,
            } => {
                write!(
                    f,
                    "sample density is strongly non-uniform: adaptive tree on levels \
                     {coarse}..{fine} ({functions} functions, {leaves} leaves, local depth \
                     following the sample count) instead of uniform levels"
                )?;
                if *unseen > 0 {
                    write!(f, ", {unseen} functions the samples do not see left out")?;
                }
                if *ridge > 0.0 {
                    write!(f, ", ridge {ridge:e} on singular directions")?;
                }
                if !empty.is_empty() {
                    write!(f, "; no samples in {}", widest_gaps(empty))?;
                }
                Ok(())
            }
        }
    }
}

/// How many sample-free intervals a warning lists by name.
pub const LISTED_GAPS: usize = 5;

/// The sample-free intervals `gaps` in words: all of them when there are at most
/// [`LISTED_GAPS`], else their count and the [`LISTED_GAPS`] widest, in position order.
fn widest_gaps(gaps: &[[f64; 2]]) -> String {
    let show = |g: &[[f64; 2]]| -> String {
        g.iter()
            .map(|r| format!("[{}, {}]", significant(r[0]), significant(r[1])))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if gaps.len() <= LISTED_GAPS {
        return show(gaps);
    }
    let mut widest = gaps.to_vec();
    widest.sort_by(|a, b| (b[1] - b[0]).total_cmp(&(a[1] - a[0])));
    widest.truncate(LISTED_GAPS);
    widest.sort_by(|a, b| a[0].total_cmp(&b[0]));
    format!(
        "{} intervals, the {LISTED_GAPS} widest {}",
        gaps.len(),
        show(&widest)
    )
}

/// `x` rounded to 6 significant digits, printed shortest.
fn significant(x: f64) -> String {
    format!("{x:.5e}")
        .parse::<f64>()
        .map_or_else(|_| x.to_string(), |v| v.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Many gaps give a count and the widest few, in position order; few are listed whole.
    #[test]
    fn many_gaps_are_counted_not_listed() {
        let gaps: Vec<[f64; 2]> = (0..300)
            .map(|i| {
                let a = i as f64 / 300.0;
                [a, a + if i % 50 == 7 { 2e-3 } else { 1e-3 }]
            })
            .collect();
        let text = widest_gaps(&gaps);
        // Six gaps are twice as wide; which five of those ties win depends on rounding.
        assert!(text.starts_with("300 intervals, the 5 widest ["), "{text}");
        assert_eq!(text.matches('[').count(), 5, "{text}");
        assert!(text.len() < 200, "{text}");
        assert_eq!(
            widest_gaps(&gaps[..2]),
            "[0, 0.001], [0.00333333, 0.00433333]"
        );
    }
}
