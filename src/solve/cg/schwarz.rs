//! Additive Schwarz: overlapping blocks of unknowns, each solved exactly,
//!
//! ```text
//! M^{-1} = sum_t R_t^T A_tt^{-1} R_t,     A_tt = R_t A R_t^T,
//! ```
//!
//! `R_t` the restriction to block `t`'s unknowns. The blocks (which unknowns go together)
//! are the caller's: the tree fit's are spatial tiles holding every level
//! (the adaptive image fit's Schwarz solve). Each `A_tt` is read from an assembled `A` and
//! factored densely (faer's Cholesky); an unknown without an entry has a zero row and is
//! pinned by a unit diagonal (the block's largest); a block that is still singular gets a
//! relative ridge `1e-12`, times 100 until it factors, counted.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::solve::solve_in_place_with_conj;
use faer::linalg::solvers::Llt;
use faer::{Conj, Mat, Par, Side};
use rayon::prelude::*;
use sprs::CsMat;

use super::Preconditioner;
use crate::solve::sparse::raw;

/// One block: its unknowns (ascending) and the Cholesky factor of `A_tt`.
struct Block {
    columns: Vec<usize>,
    factor: Llt<f64>,
}

/// What the preconditioner holds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SchwarzStats {
    /// Blocks.
    pub blocks: usize,
    /// Largest block (unknowns).
    pub largest: usize,
    /// Unknowns summed over the blocks (the overlap counts each unknown once per block).
    pub members: usize,
    /// Blocks that needed a ridge to factor.
    pub ridged: usize,
}

/// `M^{-1} = sum_t R_t^T A_tt^{-1} R_t` over overlapping blocks.
pub struct AdditiveSchwarz {
    blocks: Vec<Block>,
    size: usize,
    stats: SchwarzStats,
}

impl AdditiveSchwarz {
    /// The blocks of `a` (`n x n` CSR, both triangles, sorted indices) on the unknowns of
    /// `members` (each ascending; empty blocks are skipped), factored in parallel.
    pub fn new(a: &CsMat<f64>, members: Vec<Vec<usize>>) -> Self {
        let (gp, gi, gd) = raw(a);
        let built: Vec<(Block, bool)> = members
            .into_par_iter()
            .filter(|m| !m.is_empty())
            .map(|columns| {
                let n = columns.len();
                let mut m = Mat::<f64>::zeros(n, n);
                for (i, &a) in columns.iter().enumerate() {
                    for t in gp[a]..gp[a + 1] {
                        if let Ok(j) = columns.binary_search(&gi[t]) {
                            m[(i, j)] = gd[t];
                        }
                    }
                }
                let scale = (0..n).map(|i| m[(i, i)]).fold(0.0, f64::max).max(1.0);
                for i in 0..n {
                    if m[(i, i)] <= 0.0 {
                        m[(i, i)] = scale;
                    }
                }
                let mut ridged = false;
                let factor = match Llt::new(m.as_ref(), Side::Lower) {
                    Ok(f) => f,
                    Err(_) => {
                        ridged = true;
                        let mut ridge = 1e-12 * scale;
                        loop {
                            let mut r = m.clone();
                            for i in 0..n {
                                r[(i, i)] += ridge;
                            }
                            if let Ok(f) = Llt::new(r.as_ref(), Side::Lower) {
                                break f;
                            }
                            ridge *= 100.0;
                        }
                    }
                };
                (Block { columns, factor }, ridged)
            })
            .collect();
        let stats = SchwarzStats {
            blocks: built.len(),
            largest: built
                .iter()
                .map(|(b, _)| b.columns.len())
                .max()
                .unwrap_or(0),
            members: built.iter().map(|(b, _)| b.columns.len()).sum(),
            ridged: built.iter().filter(|(_, r)| *r).count(),
        };
        Self {
            blocks: built.into_iter().map(|(b, _)| b).collect(),
            size: a.rows(),
            stats,
        }
    }

    /// What it holds.
    pub fn stats(&self) -> SchwarzStats {
        self.stats
    }

    /// Unknowns `n`.
    pub fn len(&self) -> usize {
        self.size
    }

    /// Whether there are no unknowns.
    pub fn is_empty(&self) -> bool {
        self.size == 0
    }
}

impl Preconditioner for AdditiveSchwarz {
    /// `z_c = M^{-1} r_c` for every vector: each block solved once for all of them (a matrix
    /// of right-hand sides), blocks in parallel, added in block order (the bits do not depend
    /// on the thread count).
    fn apply(&self, rs: &[&[f64]], z: &mut [Vec<f64>]) {
        let k = rs.len();
        let parts: Vec<Mat<f64>> = self
            .blocks
            .par_iter()
            .map(|b| {
                let mut local = Mat::from_fn(b.columns.len(), k, |i, c| rs[c][b.columns[i]]);
                let mut mem = MemBuffer::new(faer::dyn_stack::StackReq::EMPTY);
                solve_in_place_with_conj(
                    b.factor.L(),
                    Conj::No,
                    local.as_mut(),
                    Par::Seq,
                    MemStack::new(&mut mem),
                );
                local
            })
            .collect();
        for zc in z.iter_mut() {
            zc.clear();
            zc.resize(self.size, 0.0);
        }
        for (b, x) in self.blocks.iter().zip(&parts) {
            for (c, zc) in z.iter_mut().enumerate() {
                for (i, &a) in b.columns.iter().enumerate() {
                    zc[a] += x[(i, c)];
                }
            }
        }
    }
}
