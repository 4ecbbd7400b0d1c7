//! How the tree fit solves its normal equations `G c = K_T^T f`: the direct sparse Cholesky
//! of the assembled `G`, conjugate gradients on the same `G` with an additive Schwarz
//! preconditioner, or matrix-free conjugate gradients with the exact Jacobi diagonal
//! (`image::adaptive::pcg`), each stopping at a relative normal-equation residual.

use serde::{Deserialize, Serialize};

/// How the tree fit solves its normal equations.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum TreeSolver {
    /// The assembled `G` and the equilibrated sparse Cholesky of [`crate::solve::normal_ls`]
    /// (the reference: cost grows with `G`'s ~300 entries per column).
    Direct,
    /// Conjugate gradients on the assembled `G` of the direct path, preconditioned by
    /// additive Schwarz on overlapping tiles with every level ([`super::schwarz`]; opt-in,
    /// experimental: the reference for a matrix-free assembly of the same blocks).
    Schwarz {
        /// Relative residual of the normal equations to reach.
        tolerance: f64,
        /// Most iterations (past them the coefficients are used as they are, reported).
        max_iterations: usize,
        /// Tile side in pixels.
        tile: f64,
        /// Halo in pixels: a function belongs to every tile its cell, grown by the halo, meets.
        halo: f64,
    },
    /// Matrix-free preconditioned conjugate gradients (`image::adaptive::pcg`).
    Pcg {
        /// Relative residual of the normal equations to reach.
        tolerance: f64,
        /// Most iterations; past them the direct solve takes over if the tree has at most
        /// [`DIRECT_FALLBACK_MAX`] functions (reported either way).
        max_iterations: usize,
    },
}

impl TreeSolver {
    /// The same iterative solver stopping at relative residual `tolerance` (`None` for the
    /// direct solve, which has no tolerance).
    pub fn with_tolerance(self, tolerance: f64) -> Option<Self> {
        match self {
            Self::Direct => None,
            Self::Pcg { max_iterations, .. } => Some(Self::Pcg {
                tolerance,
                max_iterations,
            }),
            Self::Schwarz {
                max_iterations,
                tile,
                halo,
                ..
            } => Some(Self::Schwarz {
                tolerance,
                max_iterations,
                tile,
                halo,
            }),
        }
    }
}

/// PCG to a relative residual of `1e-6` (`rkwave image --adaptive --solver pcg`): the
/// output's PSNR is the same at `1e-4` and `1e-6` (docs/measurements.md, "The iterative
/// solvers"), so `1e-6` keeps two orders of margin (the earlier default, `1e-10`, only added
/// iterations).
impl Default for TreeSolver {
    fn default() -> Self {
        Self::Pcg {
            tolerance: 1e-6,
            max_iterations: 400,
        }
    }
}

/// Largest tree the direct solve takes over from a stalled PCG.
pub const DIRECT_FALLBACK_MAX: usize = 40_000;
