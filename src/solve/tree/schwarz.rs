//! An additive Schwarz preconditioner for the tree's normal equations: overlapping spatial
//! tiles, every level of the tree in each.
//!
//! Jacobi-preconditioned CG on `G = K_T^T K_T` needs hundreds of iterations a round at
//! `rho = 2`: the slow directions are local but span levels (the smallest eigenvectors of
//! `D^{-1/2} G D^{-1/2}` sit at the image border and mix the coarse and the next two levels).
//! Blocks that hold *every* level of a small region remove them:
//!
//! ```text
//! M^{-1} = sum_t R_t^T G_tt^{-1} R_t,     G_tt = R_t G R_t^T,
//! ```
//!
//! `R_t` the restriction to the functions whose cell, grown by the halo `h` on each side,
//! meets tile `t` (`T x T` pixels). With exact principal submatrices `G_tt`, `kappa(M^{-1} G)`
//! falls by two orders of magnitude from Jacobi's, while blocks of one level alone (or the
//! coarse levels split off into a block of their own) barely help (dense eigenvalues:
//! docs/measurements/plan-speed.md, "The iterative solvers").
//!
//! Here the tiles' blocks are chosen; they are read from an assembled `G` (the direct path's,
//! [`super::gram`]), factored and applied by the crate's one additive Schwarz preconditioner
//! ([`AdditiveSchwarz`]: dense Cholesky per block, blocked triangular solves for all channels
//! at once), and the conjugate gradient is the crate's one ([`crate::solve::cg::pcg`]). That
//! is the reference for a matrix-free assembly of the same blocks, which the 512² target
//! needs: `G` itself, built from the kernel rows, does not fit at 512²
//! (docs/measurements/plan-speed.md, "512² at 8 spp").

use serde::Serialize;
use sprs::CsMat;

use crate::adaptive::tree::quad::{Cell, QuadTree};
use crate::solve::cg::{
    self, AdditiveSchwarz, CgParams, CgReport, ConditionEstimate, Preconditioner, ResidualReport,
    SparseOperator,
};

/// What the preconditioner holds.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct SchwarzReport {
    /// Tiles (blocks).
    pub blocks: usize,
    /// Largest block (functions).
    pub largest: usize,
    /// Mean functions per block over the tree's functions: the overlap (1: none).
    pub overlap: f64,
    /// Blocks that needed a ridge to factor.
    pub ridged: usize,
}

/// `M^{-1} = sum_t R_t^T G_tt^{-1} R_t` over overlapping tiles.
pub struct Schwarz {
    blocks: AdditiveSchwarz,
    report: SchwarzReport,
}

/// The pixel rectangle `[x0, x1, y0, y1]` of the cell owning each function (a coarse scaling
/// function: its cell at step 0).
fn function_rects(tree: &QuadTree, functions: &[usize]) -> Vec<[f64; 4]> {
    let nx = tree.basis().dims().0;
    functions
        .iter()
        .map(|&f| {
            let cell = tree.cell_of_function(f).unwrap_or(Cell {
                step: 0,
                kx: f % nx,
                ky: f / nx,
            });
            tree.rect(cell)
        })
        .collect()
}

impl Schwarz {
    /// The blocks of `g` (`P x P` CSR, both triangles, columns = `functions`, ascending
    /// Mallat indices of `tree`'s functions) on tiles of `tile` pixels, each holding the
    /// functions whose cell grown by `halo` pixels meets it.
    pub fn new(tree: &QuadTree, functions: &[usize], g: &CsMat<f64>, tile: f64, halo: f64) -> Self {
        let b = tree.basis();
        let (w, h) = (b.width() as f64, b.height() as f64);
        let (tw, th) = ((w / tile).ceil() as usize, (h / tile).ceil() as usize);
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); tw * th];
        for (a, r) in function_rects(tree, functions).iter().enumerate() {
            let lo = |v: f64| ((v / tile).floor().max(0.0)) as usize;
            let hi = |v: f64, n: usize| (((v / tile).ceil()) as usize).min(n);
            for ty in lo(r[2] - halo)..hi(r[3] + halo, th) {
                for tx in lo(r[0] - halo)..hi(r[1] + halo, tw) {
                    members[ty * tw + tx].push(a);
                }
            }
        }
        let blocks = AdditiveSchwarz::new(g, members);
        let stats = blocks.stats();
        let report = SchwarzReport {
            blocks: stats.blocks,
            largest: stats.largest,
            overlap: stats.members as f64 / functions.len().max(1) as f64,
            ridged: stats.ridged,
        };
        Self { blocks, report }
    }

    /// What it holds.
    pub fn report(&self) -> SchwarzReport {
        self.report
    }
}

impl Preconditioner for Schwarz {
    fn apply(&self, r: &[&[f64]], z: &mut [Vec<f64>]) {
        self.blocks.apply(r, z);
    }
}

/// Solves `G x_c = b_c` for every right-hand side by conjugate gradients preconditioned by
/// `pre`, from 0, each to a relative residual `tolerance` (recomputed at the end) or
/// `max_iterations`: the runs go in lockstep so that each iteration's products with `G` and
/// `M^{-1}` serve all of them ([`crate::solve::cg::pcg`]).
pub fn schwarz_pcg(
    g: &CsMat<f64>,
    bs: &[Vec<f64>],
    pre: &Schwarz,
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<Vec<f64>>, CgReport) {
    let params = CgParams {
        tolerance,
        max_iterations,
        residual: ResidualReport::Recomputed,
        condition: ConditionEstimate::Skip,
        forward_error: None,
    };
    let b: Vec<&[f64]> = bs.iter().map(|b| b.as_slice()).collect();
    cg::pcg(&SparseOperator::new(g), pre, &b, None, &params)
}
