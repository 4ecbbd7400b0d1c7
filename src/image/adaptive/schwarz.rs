//! An additive Schwarz preconditioner for the tree's normal equations: overlapping spatial
//! tiles, every level of the tree in each.
//!
//! Jacobi-preconditioned CG on `G = K_T^T K_T` needs 200-400 iterations a round (condition
//! estimates `3e3` at `rho = 2`): the slow directions are local but span levels (measured on
//! the refiner's second round at 32² and 64², `shapes`, 8 spp: the smallest eigenvectors of
//! `D^{-1/2} G D^{-1/2}` sit at the image border and mix the coarse and the next two levels).
//! Blocks that hold *every* level of a small region remove them:
//!
//! ```text
//! M^{-1} = sum_t R_t^T G_tt^{-1} R_t,     G_tt = R_t G R_t^T,
//! ```
//!
//! `R_t` the restriction to the functions whose cell, grown by the halo `h` on each side,
//! meets tile `t` (`T x T` pixels). With exact principal submatrices `G_tt`, measured with
//! dense eigenvalues: `kappa(M^{-1} G)` 3,031 (Jacobi) → 12.5 (`T = 4`, `h = 1`) and 6.0
//! (`T = 8`, `h = 2`) at 32²; 2,995 → 13.0 (`T = 8`, `h = 2`) and 5.4 (`T = 16`) at 64².
//! Blocks of one level alone (or the coarse levels split off into a block of their own) leave
//! it above 1,000.
//!
//! Here the blocks are read from an assembled `G` (the direct path's, [`super::gram`]) and
//! factored densely (faer's Cholesky, blocked triangular solves for all channels at once; a function without samples has a zero row and is pinned by a
//! unit diagonal; a block that is still singular gets a relative ridge, counted). That is the
//! reference for a matrix-free assembly of the same blocks, which the 512² target needs: `G`
//! itself, built from the kernel rows, does not fit at 512² (see the README).

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::solve::solve_in_place_with_conj;
use faer::linalg::solvers::Llt;
use faer::{Conj, Mat, Par, Side};
use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMat;

use super::pcg::{deinterleave, dot};
use super::tree::{Cell, QuadTree};
use crate::solve::csr_raw as raw;

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

/// One tile's block: its functions (columns of `G`, ascending) and the Cholesky factor of
/// `G_tt`.
struct Block {
    columns: Vec<usize>,
    factor: Llt<f64>,
}

/// `M^{-1} = sum_t R_t^T G_tt^{-1} R_t` over overlapping tiles.
pub struct Schwarz {
    blocks: Vec<Block>,
    size: usize,
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
        members.retain(|m| !m.is_empty());
        let (gp, gi, gd) = raw(g);
        let built: Vec<(Block, bool)> = members
            .into_par_iter()
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
        let total: usize = built.iter().map(|(b, _)| b.columns.len()).sum();
        let report = SchwarzReport {
            blocks: built.len(),
            largest: built
                .iter()
                .map(|(b, _)| b.columns.len())
                .max()
                .unwrap_or(0),
            overlap: total as f64 / functions.len().max(1) as f64,
            ridged: built.iter().filter(|(_, r)| *r).count(),
        };
        Self {
            blocks: built.into_iter().map(|(b, _)| b).collect(),
            size: functions.len(),
            report,
        }
    }

    /// What it holds.
    pub fn report(&self) -> SchwarzReport {
        self.report
    }

    /// `z_c = M^{-1} r_c` for every vector `r_c` over the columns of `G`: each block solved
    /// once for all of them (a matrix of right-hand sides), blocks in parallel, added in block
    /// order (the bits do not depend on the thread count).
    pub fn apply_many(&self, rs: &[&[f64]]) -> Vec<Vec<f64>> {
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
        let mut z = vec![vec![0.0; self.size]; k];
        for (b, x) in self.blocks.iter().zip(&parts) {
            for (c, zc) in z.iter_mut().enumerate() {
                for (i, &a) in b.columns.iter().enumerate() {
                    zc[a] += x[(i, c)];
                }
            }
        }
        z
    }
}

/// What one assembled-`G` PCG solve did.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct SchwarzPcgReport {
    /// Iterations.
    pub iterations: usize,
    /// Final relative residual `||b - G x|| / ||b||` (recomputed).
    pub relative_residual: f64,
    /// Whether the tolerance was reached.
    pub converged: bool,
}

/// `y_c = G x_c` for CSR `G`, one pass over `G` for every vector.
fn times_many(g: &CsMat<f64>, xs: &[&[f64]]) -> Vec<Vec<f64>> {
    let (gp, gi, gd) = raw(g);
    let k = xs.len();
    let mut rows = vec![0.0; g.rows() * k];
    rows.par_chunks_mut(k).enumerate().for_each(|(a, acc)| {
        for t in gp[a]..gp[a + 1] {
            let (j, v) = (gi[t], gd[t]);
            for (s, x) in acc.iter_mut().zip(xs) {
                *s += v * x[j];
            }
        }
    });
    deinterleave(&rows, k)
}

/// Solves `G x_c = b_c` for every right-hand side by conjugate gradients preconditioned by
/// `pre`, from 0, each to a relative residual `tolerance` or `max_iterations`: the runs go in
/// lockstep so that each iteration's products with `G` and `M^{-1}` serve all of them.
pub fn schwarz_pcg(
    g: &CsMat<f64>,
    bs: &[Vec<f64>],
    pre: &Schwarz,
    tolerance: f64,
    max_iterations: usize,
) -> Vec<(Vec<f64>, SchwarzPcgReport)> {
    let k = bs.len();
    let n = g.rows();
    let bnorm: Vec<f64> = bs.iter().map(|b| dot(b, b).sqrt()).collect();
    let mut x = vec![vec![0.0; n]; k];
    let mut r: Vec<Vec<f64>> = bs.to_vec();
    let refs: Vec<&[f64]> = r.iter().map(|v| v.as_slice()).collect();
    let mut p = pre.apply_many(&refs);
    let mut rz: Vec<f64> = r.iter().zip(&p).map(|(r, z)| dot(r, z)).collect();
    let mut iterations = vec![0usize; k];
    let live = |c: usize, r: &[Vec<f64>], rz: &[f64]| {
        bnorm[c] > 0.0 && rz[c] > 0.0 && dot(&r[c], &r[c]).sqrt() > tolerance * bnorm[c]
    };
    let mut active: Vec<bool> = (0..k).map(|c| live(c, &r, &rz)).collect();
    for _ in 0..max_iterations {
        let on: Vec<usize> = (0..k).filter(|&c| active[c]).collect();
        if on.is_empty() {
            break;
        }
        let ps: Vec<&[f64]> = on.iter().map(|&c| p[c].as_slice()).collect();
        let qs = times_many(g, &ps);
        for (&c, q) in on.iter().zip(&qs) {
            let pq = dot(&p[c], q);
            if pq <= 0.0 {
                active[c] = false;
                continue;
            }
            let alpha = rz[c] / pq;
            for ((x, r), (p, q)) in x[c].iter_mut().zip(r[c].iter_mut()).zip(p[c].iter().zip(q)) {
                *x += alpha * p;
                *r -= alpha * q;
            }
        }
        let on: Vec<usize> = on.into_iter().filter(|&c| active[c]).collect();
        let rs: Vec<&[f64]> = on.iter().map(|&c| r[c].as_slice()).collect();
        let zs = pre.apply_many(&rs);
        for (&c, z) in on.iter().zip(&zs) {
            let rz_new = dot(&r[c], z);
            let beta = rz_new / rz[c];
            for (p, z) in p[c].iter_mut().zip(z) {
                *p = z + beta * *p;
            }
            rz[c] = rz_new;
            iterations[c] += 1;
            active[c] = live(c, &r, &rz);
        }
    }
    let xr: Vec<&[f64]> = x.iter().map(|v| v.as_slice()).collect();
    let gx = times_many(g, &xr);
    x.into_iter()
        .enumerate()
        .map(|(c, xc)| {
            if bnorm[c] == 0.0 {
                let report = SchwarzPcgReport {
                    converged: true,
                    ..SchwarzPcgReport::default()
                };
                return (vec![0.0; n], report);
            }
            let res = bs[c]
                .iter()
                .zip(&gx[c])
                .map(|(b, g)| (b - g) * (b - g))
                .sum::<f64>()
                .sqrt();
            let relative_residual = res / bnorm[c];
            let report = SchwarzPcgReport {
                iterations: iterations[c],
                relative_residual,
                converged: relative_residual <= tolerance,
            };
            (xc, report)
        })
        .collect()
}
