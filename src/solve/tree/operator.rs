//! The tree's normal operator `G = K_T^T K_T = P_T^T S^T E^T E S P_T`, matrix-free: one
//! product costs two 2D FWTs and two passes over the single-scale rows `E`,
//! `O(nx ny + m (2p - 1)^2)`, for any number of vectors at once. It carries the inverse of
//! the exact diagonal `G_aa = sum_i Psi_a(x_i, y_i)^2` ([`DiagonalSums`]) for the Jacobi
//! preconditioner, and the count estimate `G_aa ~ n_a / |supp_a|` (`n_a` the samples in the
//! `(2p - 1)^2` cells around the function's own) where the exact one is 0.

use rayon::prelude::*;

use super::diagonal::DiagonalSums;
use super::single_scale::{multilevel_values, SingleScaleColumns, SingleScaleRows};
use crate::adaptive::tree::quad::QuadTree;
use crate::basis::tensor::TensorBasis;
use crate::solve::cg::SymmetricOperator;
use crate::solve::vectors::deinterleave;

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
        let exact = diagonal.sums();
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

    /// The basis (full Mallat layout).
    pub(crate) fn basis(&self) -> &TensorBasis {
        self.basis
    }

    /// The inverse of `diag G` on the tree (0 off it): the Jacobi preconditioner.
    pub(crate) fn inverse_diagonal(&self) -> &[f64] {
        &self.inv_diag
    }

    /// Zeroes `v` off the tree.
    pub(crate) fn restrict(&self, v: &mut [f64]) {
        for (x, &m) in v.iter_mut().zip(&self.mask) {
            if !m {
                *x = 0.0;
            }
        }
    }
}

impl SymmetricOperator for TreeNormalOperator<'_> {
    fn dim(&self) -> usize {
        self.basis.len()
    }
    fn apply(&self, p: &[&[f64]], q: &mut [Vec<f64>]) {
        for (q, g) in q.iter_mut().zip(self.apply_many(p)) {
            *q = g;
        }
    }
}
