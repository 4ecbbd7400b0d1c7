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
/// output's PSNR is the same at `1e-4` and `1e-6` (docs/measurements/plan-speed.md, "The iterative
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

impl TreeSolver {
    /// PCG to a relative residual of `3e-4`: the solver of a renderer's plan (`rkwave plan`,
    /// Python's `Plan`) and of its fits whose direct solve does not fit in memory (the
    /// stopping round's fit is continued to it from the round's `1e-2`). `1e-4` gave the
    /// final image of `1e-6` to the hundredth of a dB in about half the final fit's iterations
    /// (docs/measurements/plan-speed.md, "The renderer loop on PCG"); `3e-4` takes 8 of the
    /// 128² loop's 14 iterations there, chosen on the suite's tuning half
    /// (docs/measurements/plan-speed.md, "The rounds' fits: PCG's iterations").
    pub fn plan_pcg() -> Self {
        Self::Pcg {
            tolerance: 3e-4,
            max_iterations: 400,
        }
    }
}

/// Largest tree the direct solve takes over from a stalled PCG.
pub const DIRECT_FALLBACK_MAX: usize = 40_000;

/// The solver of a plan's fit of `samples` (`channels` channels, `next` positions to hand
/// out after it) on `plane` with a tree of at most `levels` levels: `wanted`, or, when that
/// is an assembled solve whose estimate ([`crate::resources::ImageRequest`]) exceeds the
/// memory limit, matrix-free PCG ([`TreeSolver::plan_pcg`]) with the note saying so. Refused
/// when PCG does not fit either.
pub(crate) fn fitting_solver(
    wanted: TreeSolver,
    plane: crate::image::ImagePlane,
    (p, levels, rho): (usize, u32, f64),
    (samples, channels, next): (usize, usize, usize),
) -> Result<(TreeSolver, Option<String>), crate::resources::ResourceError> {
    use crate::resources::{ImageRequest, ImageSolve};
    let check = |solver: TreeSolver| {
        let solve = match solver {
            TreeSolver::Pcg { .. } => ImageSolve::TreePcg { p, levels, rho },
            _ => ImageSolve::TreeDirect { p, levels, rho },
        };
        let request = ImageRequest {
            pixels: plane.pixels() as f64,
            channels,
            samples: samples as f64,
            from_file: false,
            positions: next as f64,
            solve,
            images: 2,
        };
        request.estimate().check(
            || {
                format!(
                    "the plan's fit of {samples} samples on a tree of {levels} levels ({plane})"
                )
            },
            || {
                format!(
                    "a smaller budget ({}) or depth limit ({}) for a new plan",
                    crate::error::Fix::Set(crate::error::Param::Budget),
                    crate::error::Fix::Set(crate::error::Param::BelowPixel)
                )
            },
        )
    };
    match check(wanted) {
        Err(e) if !matches!(wanted, TreeSolver::Pcg { .. }) => {
            let pcg = TreeSolver::plan_pcg();
            check(pcg)?;
            Ok((pcg, Some(fallback_note(&e))))
        }
        checked => checked.map(|()| (wanted, None)),
    }
}

/// The note of a fit that takes matrix-free PCG because the assembled solve does not fit in
/// memory (`refused`: the assembled solve's refusal).
pub(crate) fn fallback_note(refused: &crate::resources::ResourceError) -> String {
    use crate::resources::{format_bytes, ResourceError};
    let TreeSolver::Pcg { tolerance, .. } = TreeSolver::plan_pcg() else {
        unreachable!("the plan's PCG")
    };
    let why = match refused {
        ResourceError::TooLarge {
            what,
            needed,
            limit,
            ..
        } => format!(
            "{what} would need about {} against the memory limit of {}",
            format_bytes(*needed),
            format_bytes(*limit as f64)
        ),
        e => e.to_string(),
    };
    format!(
        "the direct solve does not fit in memory ({why}): this fit uses the matrix-free PCG \
         solve instead (to a relative residual of {tolerance:e}; `{}` for the whole plan)",
        crate::error::Fix::SolverPcg
    )
}
