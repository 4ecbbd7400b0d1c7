//! Matrix-free preconditioned conjugate gradients for the tree fit.
//!
//! The tree's functions are a subset `T` of the orthonormal non-standard basis, and every one
//! of them is a combination of the single-scale functions of `V_Jx (x) V_Jy` through the 2D
//! synthesis `S` ([`TensorBasis::synthesis`], orthogonal: `S^T` is the analysis). So the tree
//! kernel factors as
//!
//! ```text
//! K_T = E S P_T,        E[i, k] = Phi_k(x_i, y_i)   (single-scale rows, (2p - 1)^2 entries),
//! ```
//!
//! with `P_T` the injection of the tree's coefficients into the Mallat layout. One product
//! `G v = K_T^T K_T v = P_T^T S^T E^T E S P_T v` costs two 2D FWTs and two passes over `E`:
//! `O(nx ny + m (2p - 1)^2)`, against the `~300 P` entries of an assembled `G` whose rows mix
//! every level. `E` does not depend on the tree (a round's fit builds it afresh for all
//! samples; [`SingleScaleRows::append`] could continue it).
//!
//! The normal equations `G c = K_T^T f` are solved by conjugate gradients preconditioned by
//! `diag G`, `G_aa = sum_i Psi_a(x_i, y_i)^2`, from one pass of the multilevel evaluator over
//! the samples (it removes the `4^depth` spread of the sample density between deep and
//! shallow regions; measured at 128², `shapes`, 8 spp, it lowers the condition estimate from
//! 5e3-2e4 to 2e3-5e3 against the count estimate `G_aa ~ n_a / |supp_a|`, `n_a` the samples
//! in the `(2p - 1)^2` cells around the function's own, which is kept for reporting unsampled
//! functions). A function with no sample in its support has a zero column in `K_T`: its
//! residual is always 0, so it keeps its start value (0 for a new function), as the direct
//! solve's ridge pins it near 0.
//!
//! *Measured limit.* At `rho = 2` samples per slot the least-squares problem itself is not well
//! conditioned (jittered pairs of samples leave local near-null directions): the condition
//! estimate of the Jacobi-preconditioned `G` is `~3e3`, and PCG needs 300-400 iterations to a
//! relative residual of `1e-10`, more work than the direct solve at 128². So PCG is opt-in; a
//! stronger (local / Schwarz, or previous-factor) preconditioner is what it lacks.
//!
//! Stopping: the relative residual of the normal equations `||K_T^T (f - K_T c)|| / ||K_T^T
//! f|| <= tol`. Then the coefficient error is at most `kappa(G) tol` relative, `kappa`
//! estimated from the Lanczos tridiagonal of the iteration (its extreme eigenvalues are
//! those of the preconditioned `G` from inside).

use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::tree::QuadTree;
use crate::basis::tensor::TensorBasis;

/// Positions evaluated per parallel work item.
const CHUNK: usize = 4096;

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
    /// Matrix-free preconditioned conjugate gradients ([`self`](crate::image::adaptive::pcg)).
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

/// PCG to a relative residual of `1e-6` (`rkwave image --adaptive --solver pcg`). Measured
/// (`shapes`, 8 spp, rounds at `1e-2`): the output's PSNR is the same to 0.01 dB at `1e-4`
/// and `1e-6` at 256² (53.75 / 53.74) and to 0.03 dB at 512² (59.55 / 59.52), the final fit
/// taking 22 against 96 iterations at 512²; `1e-6` keeps two orders of margin (the earlier
/// default, `1e-10`, only added iterations).
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

/// The single-scale rows `E` (`m x nx ny`), stored as their two 1D factors per sample.
#[derive(Clone, Debug, Default)]
pub struct SingleScaleRows {
    nx: usize,
    /// What the rows depend on ([`basis_key`]).
    basis_key: [usize; 7],
    /// The bits of the last row's position (a check that a continued prefix is one).
    last: (u64, u64),
    ptr_x: Vec<u32>,
    ix: Vec<u32>,
    vx: Vec<f64>,
    ptr_y: Vec<u32>,
    iy: Vec<u32>,
    vy: Vec<f64>,
}

/// The single-scale space's order, image size, levels and layout: what [`SingleScaleRows`]
/// depend on besides the filters (a state continued on the same tree's basis has the same
/// ones).
fn basis_key(basis: &TensorBasis) -> [usize; 7] {
    let (jx, jy) = basis.levels();
    let (nx, ny) = basis.dims();
    [
        basis.p(),
        basis.width(),
        basis.height(),
        jx as usize,
        jy as usize,
        nx,
        ny,
    ]
}

impl SingleScaleRows {
    /// Rows of the positions `(xs[i], ys[i])` (checked to lie in the image).
    pub fn new(basis: &TensorBasis, xs: &[f64], ys: &[f64]) -> Self {
        let mut rows = Self {
            nx: basis.dims().0,
            basis_key: basis_key(basis),
            ptr_x: vec![0],
            ptr_y: vec![0],
            ..Self::default()
        };
        rows.append(basis, xs, ys);
        rows
    }

    /// Samples (rows).
    pub fn len(&self) -> usize {
        self.ptr_x.len() - 1
    }
    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The rows of `(xs, ys)` continuing `previous`, the rows of a prefix of them on the
    /// same basis (a round's samples are the previous ones plus new ones): only the new
    /// positions are evaluated. Anything else (`None`, another basis, more rows than
    /// positions, a last row at another position) is evaluated afresh.
    pub fn continued(previous: Option<Self>, basis: &TensorBasis, xs: &[f64], ys: &[f64]) -> Self {
        let usable = previous.filter(|r| {
            let old = r.len();
            r.basis_key == basis_key(basis)
                && old <= xs.len()
                && (old == 0 || r.last == (xs[old - 1].to_bits(), ys[old - 1].to_bits()))
        });
        match usable {
            Some(mut rows) => {
                let old = rows.len();
                rows.append(basis, &xs[old..], &ys[old..]);
                rows
            }
            None => Self::new(basis, xs, ys),
        }
    }

    /// Appends the rows of new positions (a round's new samples).
    pub fn append(&mut self, basis: &TensorBasis, xs: &[f64], ys: &[f64]) {
        type Part = (Vec<u32>, Vec<u32>, Vec<f64>, Vec<u32>, Vec<u32>, Vec<f64>);
        let parts: Vec<Part> = xs
            .par_chunks(CHUNK)
            .zip(ys.par_chunks(CHUNK))
            .map(|(cx, cy)| {
                let mut ev = basis.evaluator();
                let mut part: Part = Default::default();
                for (&x, &y) in cx.iter().zip(cy) {
                    let (fx, fy) = ev.factors_unchecked(x, y);
                    part.0.push(fx.len() as u32);
                    part.1.extend(fx.iter().map(|v| v.index as u32));
                    part.2.extend(fx.iter().map(|v| v.value));
                    part.3.push(fy.len() as u32);
                    part.4.extend(fy.iter().map(|v| v.index as u32));
                    part.5.extend(fy.iter().map(|v| v.value));
                }
                part
            })
            .collect();
        if let (Some(&x), Some(&y)) = (xs.last(), ys.last()) {
            self.last = (x.to_bits(), y.to_bits());
        }
        for (cx, ix, vx, cy, iy, vy) in parts {
            for c in cx {
                self.ptr_x.push(self.ptr_x.last().unwrap() + c);
            }
            for c in cy {
                self.ptr_y.push(self.ptr_y.last().unwrap() + c);
            }
            self.ix.extend(ix);
            self.vx.extend(vx);
            self.iy.extend(iy);
            self.vy.extend(vy);
        }
    }

    fn factors(&self, i: usize) -> (&[u32], &[f64], &[u32], &[f64]) {
        let (a, b) = (self.ptr_x[i] as usize, self.ptr_x[i + 1] as usize);
        let (c, d) = (self.ptr_y[i] as usize, self.ptr_y[i + 1] as usize);
        (
            &self.ix[a..b],
            &self.vx[a..b],
            &self.iy[c..d],
            &self.vy[c..d],
        )
    }

    /// `out = E s` (single-scale coefficients `s` to values at the samples).
    pub fn apply(&self, s: &[f64], out: &mut [f64]) {
        self.apply_many(s, 1, out);
    }

    /// `out = E s` for `k` vectors at once, interleaved: `s[j k + c]` is coefficient `j` of
    /// vector `c`, `out[i k + c]` the value of vector `c` at sample `i` (one pass over the
    /// rows for every vector).
    pub fn apply_many(&self, s: &[f64], k: usize, out: &mut [f64]) {
        // The channel count as a constant for the counts the refiner uses (3 image channels,
        // and 4 probes beside them): the same sums in the same order, unrolled.
        match k {
            1 => self.apply_fixed::<1>(s, out),
            3 => self.apply_fixed::<3>(s, out),
            4 => self.apply_fixed::<4>(s, out),
            7 => self.apply_fixed::<7>(s, out),
            _ => self.apply_dynamic(s, k, out),
        }
    }

    fn apply_fixed<const K: usize>(&self, s: &[f64], out: &mut [f64]) {
        let nx = self.nx;
        out.par_chunks_mut(CHUNK * K)
            .enumerate()
            .for_each(|(chunk, o)| {
                for (j, v) in o.chunks_exact_mut(K).enumerate() {
                    let (ix, vx, iy, vy) = self.factors(chunk * CHUNK + j);
                    let mut acc = [0.0; K];
                    for (&ky, &wy) in iy.iter().zip(vy) {
                        let mut inner = [0.0; K];
                        for (&kx, &wx) in ix.iter().zip(vx) {
                            let at = (ky as usize * nx + kx as usize) * K;
                            let sv: &[f64; K] = s[at..at + K].try_into().expect("K values");
                            for c in 0..K {
                                inner[c] += wx * sv[c];
                            }
                        }
                        for c in 0..K {
                            acc[c] += wy * inner[c];
                        }
                    }
                    v.copy_from_slice(&acc);
                }
            });
    }

    fn apply_dynamic(&self, s: &[f64], k: usize, out: &mut [f64]) {
        let nx = self.nx;
        out.par_chunks_mut(CHUNK * k)
            .enumerate()
            .for_each(|(chunk, o)| {
                let mut acc = vec![0.0; k];
                let mut inner = vec![0.0; k];
                for (j, v) in o.chunks_mut(k).enumerate() {
                    let (ix, vx, iy, vy) = self.factors(chunk * CHUNK + j);
                    acc.iter_mut().for_each(|a| *a = 0.0);
                    for (&ky, &wy) in iy.iter().zip(vy) {
                        inner.iter_mut().for_each(|a| *a = 0.0);
                        for (&kx, &wx) in ix.iter().zip(vx) {
                            let at = (ky as usize * nx + kx as usize) * k;
                            for (a, &sv) in inner.iter_mut().zip(&s[at..at + k]) {
                                *a += wx * sv;
                            }
                        }
                        for (a, &b) in acc.iter_mut().zip(&inner) {
                            *a += wy * b;
                        }
                    }
                    v.copy_from_slice(&acc);
                }
            });
    }

    /// `out = E^T r` (sample residuals to single-scale coefficients), `out` overwritten.
    pub fn apply_transpose(&self, r: &[f64], out: &mut [f64]) {
        let t = self.apply_transpose_many(r, 1, out.len());
        out.copy_from_slice(&t);
    }

    /// `E^T r` for `k` vectors at once, interleaved as in [`Self::apply_many`] (`r[i k + c]`
    /// in, `n k` coefficients out, `n` the single-scale functions), through the columns
    /// ([`SingleScaleColumns`]).
    pub fn apply_transpose_many(&self, r: &[f64], k: usize, n: usize) -> Vec<f64> {
        self.columns(n).apply_many(r, k)
    }

    /// `E` by columns: for each single-scale function, its samples (ascending) and values.
    pub fn columns(&self, n: usize) -> SingleScaleColumns {
        let m = self.len();
        let nx = self.nx;
        let mut ptr = vec![0usize; n + 1];
        for i in 0..m {
            let (ix, _, iy, _) = self.factors(i);
            for &ky in iy {
                for &kx in ix {
                    ptr[ky as usize * nx + kx as usize + 1] += 1;
                }
            }
        }
        for j in 0..n {
            ptr[j + 1] += ptr[j];
        }
        let mut next = ptr.clone();
        let mut sample = vec![0u32; ptr[n]];
        let mut weight = vec![0.0; ptr[n]];
        for i in 0..m {
            let (ix, vx, iy, vy) = self.factors(i);
            for (&ky, &wy) in iy.iter().zip(vy) {
                for (&kx, &wx) in ix.iter().zip(vx) {
                    let j = ky as usize * nx + kx as usize;
                    sample[next[j]] = i as u32;
                    weight[next[j]] = wy * wx;
                    next[j] += 1;
                }
            }
        }
        SingleScaleColumns {
            ptr,
            sample,
            weight,
        }
    }
}

/// `E` stored by columns (CSC): `E^T r` as a gather, in parallel over the functions, each
/// summed over its samples in ascending order (the bits do not depend on the thread count,
/// and no per-thread copy of the output is needed).
#[derive(Clone, Debug, Default)]
pub struct SingleScaleColumns {
    ptr: Vec<usize>,
    sample: Vec<u32>,
    weight: Vec<f64>,
}

impl SingleScaleColumns {
    /// `E^T r` for `k` interleaved vectors (`r[i k + c]`), `n k` interleaved coefficients out.
    pub fn apply_many(&self, r: &[f64], k: usize) -> Vec<f64> {
        match k {
            1 => self.apply_fixed::<1>(r),
            3 => self.apply_fixed::<3>(r),
            4 => self.apply_fixed::<4>(r),
            7 => self.apply_fixed::<7>(r),
            _ => self.apply_dynamic(r, k),
        }
    }

    /// [`Self::apply_many`] for `K` vectors, a constant (the same sums in the same order).
    fn apply_fixed<const K: usize>(&self, r: &[f64]) -> Vec<f64> {
        let n = self.ptr.len() - 1;
        let mut out = vec![0.0; n * K];
        out.par_chunks_mut(CHUNK * K)
            .enumerate()
            .for_each(|(chunk, o)| {
                for (t, v) in o.chunks_exact_mut(K).enumerate() {
                    let j = chunk * CHUNK + t;
                    let mut acc = [0.0; K];
                    for q in self.ptr[j]..self.ptr[j + 1] {
                        let (i, w) = (self.sample[q] as usize, self.weight[q]);
                        let ri: &[f64; K] = r[i * K..(i + 1) * K].try_into().expect("K values");
                        for c in 0..K {
                            acc[c] += w * ri[c];
                        }
                    }
                    v.copy_from_slice(&acc);
                }
            });
        out
    }

    fn apply_dynamic(&self, r: &[f64], k: usize) -> Vec<f64> {
        let n = self.ptr.len() - 1;
        let mut out = vec![0.0; n * k];
        out.par_chunks_mut(CHUNK * k)
            .enumerate()
            .for_each(|(chunk, o)| {
                for (t, v) in o.chunks_mut(k).enumerate() {
                    let j = chunk * CHUNK + t;
                    for q in self.ptr[j]..self.ptr[j + 1] {
                        let (i, w) = (self.sample[q] as usize, self.weight[q]);
                        for (a, &ri) in v.iter_mut().zip(&r[i * k..(i + 1) * k]) {
                            *a += w * ri;
                        }
                    }
                }
            });
        out
    }
}

/// `K v_c = E S v_c` for `k` multilevel vectors `v_c` (full Mallat layout of `basis`) at the
/// samples of `rows`, interleaved (`out[i k + c]`): each synthesized to single scale, then one
/// pass over the rows for all of them.
pub(super) fn multilevel_values(
    basis: &TensorBasis,
    rows: &SingleScaleRows,
    vs: &[&[f64]],
) -> Vec<f64> {
    let s: Vec<Vec<f64>> = vs.par_iter().map(|v| basis.synthesis(v)).collect();
    let k = vs.len();
    let mut out = vec![0.0; rows.len() * k];
    rows.apply_many(&interleave(&s), k, &mut out);
    out
}

/// Entries per parallel work item of [`interleave`] and [`deinterleave`].
const SHUFFLE_BLOCK: usize = 1 << 14;

/// `k` vectors of equal length interleaved: `out[j k + c] = vs[c][j]` (in parallel over
/// blocks of `j`, each block's rows written in order: a pure copy, so the bits are the
/// inputs'; measured at 512², 8 spp, 7 channels, the serial channel-by-channel version and
/// its inverse took 9.4 s of a run's 33 s of operator products).
fn interleave(vs: &[Vec<f64>]) -> Vec<f64> {
    let k = vs.len();
    let n = vs.first().map_or(0, |v| v.len());
    let mut out = vec![0.0; n * k];
    if k == 0 {
        return out;
    }
    out.par_chunks_mut(SHUFFLE_BLOCK * k)
        .enumerate()
        .for_each(|(b, block)| {
            let j0 = b * SHUFFLE_BLOCK;
            for (jj, row) in block.chunks_exact_mut(k).enumerate() {
                for (c, v) in row.iter_mut().enumerate() {
                    *v = vs[c][j0 + jj];
                }
            }
        });
    out
}

/// The inverse of [`interleave`] for `k` vectors (in parallel over blocks of `j`).
pub(super) fn deinterleave(v: &[f64], k: usize) -> Vec<Vec<f64>> {
    if k == 0 {
        return Vec::new();
    }
    let n = v.len() / k;
    let mut outs = vec![vec![0.0; n]; k];
    // per block of `j`, the block's slice of every channel
    let mut blocks: Vec<Vec<&mut [f64]>> = (0..n.div_ceil(SHUFFLE_BLOCK))
        .map(|_| Vec::with_capacity(k))
        .collect();
    for out in outs.iter_mut() {
        for (b, part) in out.chunks_mut(SHUFFLE_BLOCK).enumerate() {
            blocks[b].push(part);
        }
    }
    blocks
        .into_par_iter()
        .enumerate()
        .for_each(|(b, mut parts)| {
            let rows = &v[b * SHUFFLE_BLOCK * k..];
            for (c, part) in parts.iter_mut().enumerate() {
                for (jj, x) in part.iter_mut().enumerate() {
                    *x = rows[jj * k + c];
                }
            }
        });
    outs
}

/// The tree's normal operator `G = K_T^T K_T`, matrix-free, on full Mallat-layout vectors
/// (zero off the tree).
pub struct TreeNormalOperator<'a> {
    basis: &'a TensorBasis,
    rows: &'a SingleScaleRows,
    /// `E` by columns, for `E^T r`.
    columns: SingleScaleColumns,
    /// 1 on the tree's functions, 0 elsewhere.
    mask: Vec<bool>,
    /// Inverse of the estimated `diag G` on the tree (0 off it).
    inv_diag: Vec<f64>,
    /// Tree functions without a sample in the cells around them.
    unsampled: usize,
}

impl<'a> TreeNormalOperator<'a> {
    /// The operator of `tree` with the samples `(xs, ys)` whose rows are `rows`.
    pub fn new(tree: &'a QuadTree, rows: &'a SingleScaleRows, xs: &[f64], ys: &[f64]) -> Self {
        let diagonal = DiagonalSums::new(tree, xs, ys, None);
        Self::with_diagonal(tree, rows, xs, ys, &diagonal)
    }

    /// [`Self::new`] with the exact diagonal `G_aa` given ([`DiagonalSums`] of the same tree
    /// and samples).
    pub fn with_diagonal(
        tree: &'a QuadTree,
        rows: &'a SingleScaleRows,
        xs: &[f64],
        ys: &[f64],
        diagonal: &DiagonalSums,
    ) -> Self {
        let basis = tree.basis();
        let n = basis.len();
        let mask = diagonal.mask.clone();
        debug_assert_eq!(diagonal.samples, xs.len());
        let p = basis.p() as i64;
        let radius = p - 1;
        // samples per cell of the deepest step, summed up step by step
        let steps = tree.steps();
        let mut counts: Vec<Vec<u32>> = Vec::with_capacity(steps as usize + 1);
        let (w, h) = tree.cell_dims(steps);
        let mut finest = vec![0u32; w * h];
        for (&x, &y) in xs.iter().zip(ys) {
            let c = tree.cell_at(steps, x, y);
            finest[c.ky * w + c.kx] += 1;
        }
        counts.push(finest);
        for s in (0..steps).rev() {
            let (w, h) = tree.cell_dims(s);
            let fine = counts.last().unwrap();
            let fw = 2 * w;
            let mut coarse = vec![0u32; w * h];
            for ky in 0..h {
                for kx in 0..w {
                    coarse[ky * w + kx] = fine[2 * ky * fw + 2 * kx]
                        + fine[2 * ky * fw + 2 * kx + 1]
                        + fine[(2 * ky + 1) * fw + 2 * kx]
                        + fine[(2 * ky + 1) * fw + 2 * kx + 1];
                }
            }
            counts.push(coarse);
        }
        counts.reverse();
        let near = |s: u32, kx: usize, ky: usize| -> (u64, f64) {
            let (w, h) = tree.cell_dims(s);
            let grid = &counts[s as usize];
            let mut total = 0u64;
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (x, y) = (kx as i64 + dx, ky as i64 + dy);
                    if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                        total += grid[y as usize * w + x as usize] as u64;
                    }
                }
            }
            (total, (w * h) as f64)
        };
        let mut inv_diag = vec![0.0; n];
        let mut unsampled = 0;
        let (nx, _) = basis.dims();
        let (cx, cy) = basis.coarse_levels();
        let exact = &diagonal.sums;
        for (f, _) in mask.iter().enumerate().filter(|(_, &m)| m) {
            let (s, kx, ky) = match tree.cell_of_function(f) {
                Some(cell) => (cell.step, cell.kx, cell.ky),
                None => {
                    let (ix, iy) = (f % nx, f / nx);
                    debug_assert!(ix < 1 << cx && iy < 1 << cy);
                    (0, ix, iy)
                }
            };
            let (count, cells) = near(s, kx, ky);
            if count == 0 {
                unsampled += 1;
            }
            inv_diag[f] = if exact[f] > 0.0 {
                1.0 / exact[f]
            } else {
                1.0 / (count.max(1) as f64 * cells)
            };
        }
        Self {
            basis,
            rows,
            columns: rows.columns(n),
            mask,
            inv_diag,
            unsampled,
        }
    }

    /// Tree functions without a sample in the `(2p - 1)^2` cells around them.
    pub fn unsampled(&self) -> usize {
        self.unsampled
    }

    /// `K_T^T f` (zero off the tree).
    pub fn rhs(&self, f: &[f64]) -> Vec<f64> {
        self.rhs_many(f, 1).pop().expect("one vector")
    }

    /// `K_T^T f_c` for `k` sample vectors interleaved (`f[i k + c]`), one pass over the rows.
    pub fn rhs_many(&self, f: &[f64], k: usize) -> Vec<Vec<f64>> {
        let n = self.basis.len();
        debug_assert_eq!(self.columns.ptr.len(), n + 1);
        let u = deinterleave(&self.columns.apply_many(f, k), k);
        u.par_iter()
            .map(|u| {
                let mut b = self.basis.analysis(u);
                self.restrict(&mut b);
                b
            })
            .collect()
    }

    /// `K_T v` for `v` zero off the tree: the fit's values at the samples.
    pub fn values(&self, v: &[f64]) -> Vec<f64> {
        self.values_many(&[v])
    }

    /// `K_T v_c` for `k` vectors zero off the tree, interleaved (`out[i k + c]`).
    pub fn values_many(&self, vs: &[&[f64]]) -> Vec<f64> {
        multilevel_values(self.basis, self.rows, vs)
    }

    /// `G v` for `v` zero off the tree.
    pub fn apply(&self, v: &[f64]) -> Vec<f64> {
        self.apply_many(&[v]).pop().expect("one vector")
    }

    /// `G v_c` for `k` vectors zero off the tree (one pass over the rows each way).
    pub fn apply_many(&self, vs: &[&[f64]]) -> Vec<Vec<f64>> {
        self.rhs_many(&self.values_many(vs), vs.len())
    }

    fn restrict(&self, v: &mut [f64]) {
        for (x, &m) in v.iter_mut().zip(&self.mask) {
            if !m {
                *x = 0.0;
            }
        }
    }
}

/// What one PCG solve did.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct PcgReport {
    /// Iterations.
    pub iterations: usize,
    /// Final relative residual `||K^T (f - K c)|| / ||K^T f||` (recomputed, not recursive).
    pub relative_residual: f64,
    /// Estimated condition number of the preconditioned `G` (Lanczos extremes; 1 with fewer
    /// than two iterations).
    pub condition: f64,
    /// Whether the tolerance was reached.
    pub converged: bool,
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solves `G c = K_T^T f` by PCG from `start` (zero off the tree; `None`: zero).
pub fn pcg(
    op: &TreeNormalOperator<'_>,
    f: &[f64],
    start: Option<&[f64]>,
    tolerance: f64,
    max_iterations: usize,
) -> (Vec<f64>, PcgReport) {
    let starts = start.map(|s| vec![s.to_vec()]);
    pcg_many(op, &[f], starts.as_deref(), tolerance, max_iterations)
        .pop()
        .expect("one channel")
}

/// One channel's conjugate-gradient state.
struct Channel {
    x: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    rz: f64,
    bnorm: f64,
    alphas: Vec<f64>,
    betas: Vec<f64>,
    active: bool,
}

impl Channel {
    /// One conjugate-gradient step with `q = G p` (Jacobi `inv_diag`): `x += alpha p`,
    /// `r -= alpha q`, `z = D^{-1} r`, `p = z + beta p`, stopping at `||r|| <= tolerance
    /// ||b||`. The sums run in index order, so the bits do not depend on the thread.
    /// Whether it stepped (not when `p^T G p <= 0`, which stops the channel).
    fn step(&mut self, q: &[f64], inv_diag: &[f64], tolerance: f64) -> bool {
        let pq = dot(&self.p, q);
        if pq <= 0.0 {
            self.active = false;
            return false;
        }
        let alpha = self.rz / pq;
        for ((x, r), (p, q)) in self
            .x
            .iter_mut()
            .zip(self.r.iter_mut())
            .zip(self.p.iter().zip(q))
        {
            *x += alpha * p;
            *r -= alpha * q;
        }
        for ((z, r), d) in self.z.iter_mut().zip(&self.r).zip(inv_diag) {
            *z = r * d;
        }
        let rz_new = dot(&self.r, &self.z);
        let beta = rz_new / self.rz;
        for (p, z) in self.p.iter_mut().zip(&self.z) {
            *p = z + beta * *p;
        }
        self.rz = rz_new;
        self.alphas.push(alpha);
        self.betas.push(beta);
        self.active = rz_new > 0.0 && dot(&self.r, &self.r).sqrt() > tolerance * self.bnorm;
        true
    }
}

/// Solves `G c_c = K_T^T f_c` for every channel `c` by PCG from `starts` (per channel, zero
/// off the tree; `None`: zero): independent conjugate-gradient runs in lockstep, whose
/// products `G p_c` share one pass over the rows per iteration ([`TreeNormalOperator::apply_many`]).
/// A channel stops at its own tolerance; the others go on.
pub fn pcg_many(
    op: &TreeNormalOperator<'_>,
    fs: &[&[f64]],
    starts: Option<&[Vec<f64>]>,
    tolerance: f64,
    max_iterations: usize,
) -> Vec<(Vec<f64>, PcgReport)> {
    let k = fs.len();
    let m = op.rows.len();
    let mut f = vec![0.0; m * k];
    for (c, fc) in fs.iter().enumerate() {
        for (i, &v) in fc.iter().enumerate() {
            f[i * k + c] = v;
        }
    }
    let b = op.rhs_many(&f, k);
    let n = op.basis.len();
    let xs: Vec<Vec<f64>> = (0..k)
        .map(|c| match starts.and_then(|s| s.get(c)) {
            Some(s) => {
                let mut x = s.clone();
                op.restrict(&mut x);
                x
            }
            None => vec![0.0; n],
        })
        .collect();
    let warm: Vec<bool> = xs.iter().map(|x| x.iter().any(|&v| v != 0.0)).collect();
    let gx = if warm.iter().any(|&w| w) {
        let refs: Vec<&[f64]> = xs.iter().map(|x| x.as_slice()).collect();
        op.apply_many(&refs)
    } else {
        vec![vec![0.0; n]; k]
    };
    let mut ch: Vec<Channel> = xs
        .into_iter()
        .zip(b.iter().zip(&gx))
        .map(|(x, (b, gx))| {
            let r: Vec<f64> = b.iter().zip(gx).map(|(b, g)| b - g).collect();
            let z: Vec<f64> = r.iter().zip(&op.inv_diag).map(|(r, d)| r * d).collect();
            let rz = dot(&r, &z);
            let bnorm = dot(b, b).sqrt();
            let active = bnorm > 0.0 && rz > 0.0 && dot(&r, &r).sqrt() > tolerance * bnorm;
            Channel {
                p: z.clone(),
                x,
                r,
                z,
                rz,
                bnorm,
                alphas: Vec::new(),
                betas: Vec::new(),
                active,
            }
        })
        .collect();
    let mut iterations = vec![0usize; k];
    for _ in 0..max_iterations {
        let live: Vec<usize> = (0..k).filter(|&c| ch[c].active).collect();
        if live.is_empty() {
            break;
        }
        let ps: Vec<&[f64]> = live.iter().map(|&c| ch[c].p.as_slice()).collect();
        let mut qs = op.apply_many(&ps).into_iter();
        // the live channels' updates in parallel, each channel's sums in index order
        let mut work: Vec<(&mut Channel, Vec<f64>)> = ch
            .iter_mut()
            .filter(|s| s.active)
            .map(|s| (s, qs.next().expect("one product per live channel")))
            .collect();
        let stepped: Vec<bool> = work
            .par_iter_mut()
            .map(|(s, q)| s.step(q, &op.inv_diag, tolerance))
            .collect();
        for (&c, stepped) in live.iter().zip(stepped) {
            iterations[c] += usize::from(stepped);
        }
    }
    let refs: Vec<&[f64]> = ch.iter().map(|s| s.x.as_slice()).collect();
    let gx = op.apply_many(&refs);
    ch.into_iter()
        .zip(gx.iter().zip(&b))
        .zip(iterations)
        .map(|((s, (gx, b)), iterations)| {
            if s.bnorm == 0.0 {
                let report = PcgReport {
                    converged: true,
                    condition: 1.0,
                    ..PcgReport::default()
                };
                return (vec![0.0; n], report);
            }
            let res: f64 = b
                .iter()
                .zip(gx)
                .map(|(b, g)| (b - g) * (b - g))
                .sum::<f64>()
                .sqrt();
            let relative_residual = res / s.bnorm;
            let report = PcgReport {
                iterations,
                relative_residual,
                condition: lanczos_condition(&s.alphas, &s.betas),
                converged: relative_residual <= tolerance,
            };
            (s.x, report)
        })
        .collect()
}

/// `lambda_max / lambda_min` of the Lanczos tridiagonal of a CG run: diagonal `1/alpha_k +
/// beta_{k-1}/alpha_{k-1}`, off-diagonal `sqrt(beta_k)/alpha_k` (Golub & Van Loan 11.3).
fn lanczos_condition(alphas: &[f64], betas: &[f64]) -> f64 {
    let k = alphas.len().min(300);
    if k < 2 {
        return 1.0;
    }
    let mut t = DMatrix::<f64>::zeros(k, k);
    for i in 0..k {
        t[(i, i)] = 1.0 / alphas[i]
            + if i > 0 {
                betas[i - 1] / alphas[i - 1]
            } else {
                0.0
            };
        if i + 1 < k {
            let e = betas[i].sqrt() / alphas[i];
            t[(i, i + 1)] = e;
            t[(i + 1, i)] = e;
        }
    }
    let eig = nalgebra::linalg::SymmetricEigen::new(t).eigenvalues;
    let (lo, hi) = eig.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
        (lo.min(e), hi.max(e))
    });
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

/// The exact diagonal `G_aa = sum_i Psi_a(x_i, y_i)^2` of a tree's normal matrix over the
/// first `samples` samples, kept so that the next round continues it: a round's samples are
/// the previous ones plus new ones and its tree holds the previous tree, so
///
/// ```text
/// G'_aa = G_aa + sum_{new i} Psi_a(x_i)^2                         (a in the previous tree),
/// G'_aa = sum_{old i in supp a} Psi_a(x_i)^2 + sum_{new i} ...     (a new function),
/// ```
///
/// the old samples evaluated only where a new function's support covers them (new functions
/// sit in the marked cells). The sums are added in another order than a rebuild's, so the
/// bits differ by rounding; the diagonal only preconditions CG.
#[derive(Clone, Debug)]
pub struct DiagonalSums {
    samples: usize,
    mask: Vec<bool>,
    sums: Vec<f64>,
}

impl DiagonalSums {
    /// The diagonal of `tree` over the samples `(xs, ys)`, continuing `previous` when it is
    /// a prefix of them on a subtree (otherwise summed afresh).
    pub fn new(tree: &QuadTree, xs: &[f64], ys: &[f64], previous: Option<&Self>) -> Self {
        let basis = tree.basis();
        let mut mask = vec![false; basis.len()];
        for f in tree.functions() {
            mask[f] = true;
        }
        let usable = previous.filter(|d| {
            d.samples <= xs.len()
                && d.mask.len() == mask.len()
                && d.mask.iter().zip(&mask).all(|(&was, &is)| !was || is)
        });
        let Some(previous) = usable else {
            let sums = exact_diagonal(basis, &mask, xs, ys);
            return Self {
                samples: xs.len(),
                mask,
                sums,
            };
        };
        let old = previous.samples;
        let mut sums = previous.sums.clone();
        let add = |sums: &mut Vec<f64>, part: Vec<f64>| {
            for (s, v) in sums.iter_mut().zip(part) {
                *s += v;
            }
        };
        add(
            &mut sums,
            exact_diagonal(basis, &mask, &xs[old..], &ys[old..]),
        );
        let fresh: Vec<bool> = mask
            .iter()
            .zip(&previous.mask)
            .map(|(&is, &was)| is && !was)
            .collect();
        if fresh.iter().any(|&f| f) {
            let covered = support_cover(tree, &fresh);
            let (w, _) = tree.cell_dims(tree.steps());
            let (cx, cy): (Vec<f64>, Vec<f64>) = xs[..old]
                .iter()
                .zip(&ys[..old])
                .filter(|(&x, &y)| {
                    let c = tree.cell_at(tree.steps(), x, y);
                    covered[c.ky * w + c.kx]
                })
                .map(|(&x, &y)| (x, y))
                .unzip();
            add(&mut sums, exact_diagonal(basis, &fresh, &cx, &cy));
        }
        Self {
            samples: xs.len(),
            mask,
            sums,
        }
    }

    /// `G_aa` per function (full Mallat layout, 0 off the tree).
    pub fn sums(&self) -> &[f64] {
        &self.sums
    }
}

/// The cells of the deepest step (row-major) inside the support of a function of `functions`
/// (a mask over the Mallat layout; no coarse scaling function among them): per axis, the
/// structural support of the function's level ([`crate::basis::support_cells`]).
fn support_cover(tree: &QuadTree, functions: &[bool]) -> Vec<bool> {
    let steps = tree.steps();
    let (w, h) = tree.cell_dims(steps);
    let (cx, cy) = tree.basis().coarse_levels();
    let p = tree.basis().p();
    let mut covered = vec![false; w * h];
    for (f, _) in functions.iter().enumerate().filter(|(_, &m)| m) {
        let cell = tree
            .cell_of_function(f)
            .expect("coarse scaling functions are in every tree");
        let scale = 1usize << (steps - cell.step);
        let (x0, x1) = crate::basis::support_cells(p, cx + cell.step, cell.kx);
        let (y0, y1) = crate::basis::support_cells(p, cy + cell.step, cell.ky);
        for ky in y0 as usize * scale..(y1 as usize + 1) * scale {
            covered[ky * w + x0 as usize * scale..(x1 as usize + 1) * scale + ky * w]
                .iter_mut()
                .for_each(|c| *c = true);
        }
    }
    covered
}

/// Parts of the exact diagonal's sum (fixed, so the sum's order does not depend on threads).
const DIAGONAL_PARTS: usize = 8;

/// `G_aa = sum_i Psi_a(x_i, y_i)^2` on the tree (`mask`), from the multilevel evaluator.
fn exact_diagonal(basis: &TensorBasis, mask: &[bool], xs: &[f64], ys: &[f64]) -> Vec<f64> {
    let part = xs.len().div_ceil(DIAGONAL_PARTS).max(1);
    let parts: Vec<Vec<f64>> = xs
        .par_chunks(part)
        .zip(ys.par_chunks(part))
        .map(|(cx, cy)| {
            let mut ev = basis.multilevel_evaluator();
            let mut row = Vec::new();
            let mut acc = vec![0.0; mask.len()];
            for (&x, &y) in cx.iter().zip(cy) {
                ev.eval_unordered_into(x, y, &mut row)
                    .expect("positions are checked before the solve");
                for v in &row {
                    if mask[v.index] {
                        acc[v.index] += v.value * v.value;
                    }
                }
            }
            acc
        })
        .collect();
    let mut total = vec![0.0; mask.len()];
    for p in parts {
        for (t, v) in total.iter_mut().zip(p) {
            *t += v;
        }
    }
    total
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `interleave` is `out[j k + c] = vs[c][j]` and `deinterleave` its inverse, bit for bit,
    /// for every channel count and lengths around the parallel block.
    #[test]
    fn interleave_and_deinterleave_are_inverse_copies() {
        for k in 1..=8 {
            for n in [0, 1, 7, SHUFFLE_BLOCK, 2 * SHUFFLE_BLOCK + 5] {
                let vs: Vec<Vec<f64>> = (0..k)
                    .map(|c| (0..n).map(|j| (j * 31 + c) as f64 * 0.5 - 3.0).collect())
                    .collect();
                let v = interleave(&vs);
                assert_eq!(v.len(), n * k);
                for (c, vc) in vs.iter().enumerate() {
                    for (j, &x) in vc.iter().enumerate() {
                        assert_eq!(v[j * k + c].to_bits(), x.to_bits());
                    }
                }
                assert_eq!(deinterleave(&v, k), vs);
            }
        }
    }
}
