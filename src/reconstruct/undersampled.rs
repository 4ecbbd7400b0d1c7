//! What to change when `m` samples cannot determine `P > m` basis functions: only changes
//! that can work. At the smallest basis `p` allows (fine level `N = j_min(p)`, `P = 2^N`)
//! no level or oversampling rate lowers `P`, so only more samples or a smaller `p` help;
//! above it, fewer functions also help, through the parameter that sets them.

use std::fmt;

use crate::error::Fix;

/// The fix of `ReconstructError::Undersampled`, as data (its `Display` is the advice).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum UndersampledFix {
    /// The basis is already the smallest for `p`: more samples, or a smaller `p`.
    SmallestBasis {
        /// Basis functions `P`.
        functions: usize,
        /// Vanishing moments.
        p: usize,
        /// The smallest level for `p`, `j_min(p)`.
        level: u32,
        /// Samples the smallest basis of `p = 1` needs (`None` for `p = 1`).
        haar_functions: Option<usize>,
    },
    /// Automatic levels: more samples, or a larger oversampling rate `rho`.
    AutoLevels {
        /// Basis functions `P`.
        functions: usize,
        /// The oversampling rate asked for.
        rho: f64,
    },
    /// Fixed levels: more samples, a smaller fine level (at least `level`) or automatic levels.
    FixedLevels {
        /// Basis functions `P`.
        functions: usize,
        /// Vanishing moments.
        p: usize,
        /// The smallest fine level for `p`, `j_min(p)`.
        level: u32,
    },
    /// An active set given by the caller: more samples, or fewer functions in it.
    ActiveSet {
        /// Basis functions `P`.
        functions: usize,
    },
}

impl fmt::Display for UndersampledFix {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            UndersampledFix::SmallestBasis {
                functions,
                p,
                level,
                haar_functions,
            } => {
                write!(
                    f,
                    "{functions} functions is the smallest basis for p = {p} (level {level}), \
                     so give at least {functions} samples"
                )?;
                match haar_functions {
                    Some(n) => write!(f, ", or a smaller p (p = 1 needs {n} samples)"),
                    None => Ok(()),
                }
            }
            UndersampledFix::AutoLevels { functions, rho } => write!(
                f,
                "give at least {functions} samples, or let the automatic levels choose fewer \
                 functions with a larger oversampling rate ({} = {}; 2 gives about samples / 2 \
                 functions)",
                Fix::Rho,
                crate::norms::show(rho)
            ),
            UndersampledFix::FixedLevels {
                functions,
                p,
                level,
            } => write!(
                f,
                "give at least {functions} samples, or fewer functions: a smaller fine level N \
                 ({}; at least {level} for p = {p}) or automatic levels ({})",
                Fix::FixedLevels,
                Fix::AutoLevels
            ),
            UndersampledFix::ActiveSet { functions } => write!(
                f,
                "give at least {functions} samples, or an active set with fewer functions"
            ),
        }
    }
}
