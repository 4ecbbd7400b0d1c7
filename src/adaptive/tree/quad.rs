//! The 2D wavelet tree: an active subset of the non-standard tensor basis, closed under
//! "parent present", organised as a quadtree of dyadic cells.
//!
//! The [`TensorBasis`] at the depth limit `(Jx, Jy)` has coarse levels `(cx, cy)` and `L`
//! non-standard steps. Step `s` (`0 <= s < L`) has `2^(cx+s) x 2^(cy+s)` *cells*; cell
//! `(s, kx, ky)` owns the three detail functions of step `s` at translation `(kx, ky)`:
//!
//! ```text
//! psi_{jx,kx} (x) phi_{jy,ky},   phi_{jx,kx} (x) psi_{jy,ky},   psi_{jx,kx} (x) psi_{jy,ky},
//! jx = cx + s, jy = cy + s,
//! ```
//!
//! at Mallat indices `(2^jx + kx, ky)`, `(kx, 2^jy + ky)`, `(2^jx + kx, 2^jy + ky)` (x, y) of the
//! `ny x nx` coefficient array. The coarse scaling functions `phi_{cx} (x) phi_{cy}` are always
//! active. The parent of cell `(s, kx, ky)` is `(s - 1, kx / 2, ky / 2)`; an active cell has an
//! active parent, so the tree is a forest of quadtrees rooted at the step-0 cells.
//!
//! *Local depth.* A point lies in one cell per step; its depth `d` is the number of leading
//! active steps (`0..=L`), and its local space is that of `V_{cx+d} (x) V_{cy+d}`. The cell of
//! step `d` holding the point is a *leaf*: it is inactive (or at the limit `d = L`) while its
//! parent is active, so all its points have depth `d`, and the leaves partition the image. A
//! leaf holds one tensor function of the local space; the sampling invariant of the refiner
//! is `samples(leaf) >= ceil(rho)` for every leaf. A tree that is full up to step `L` spans
//! `V_Jx (x) V_Jy`, the uniform engine's space.

use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::basis::tensor::TensorBasis;

/// One dyadic cell: step `s` (level `cx + s` in x, `cy + s` in y) and translation `(kx, ky)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Cell {
    /// Non-standard step `s` (0 = the coarse level).
    pub step: u32,
    /// Translation along x, `0..2^(cx+s)`.
    pub kx: usize,
    /// Translation along y, `0..2^(cy+s)`.
    pub ky: usize,
}

impl Cell {
    /// The parent `(s - 1, kx / 2, ky / 2)`, `None` at step 0.
    pub fn parent(self) -> Option<Cell> {
        (self.step > 0).then(|| Cell {
            step: self.step - 1,
            kx: self.kx / 2,
            ky: self.ky / 2,
        })
    }
    /// The four children at step `s + 1`, row-major (`ky`, then `kx`).
    pub fn children(self) -> [Cell; 4] {
        std::array::from_fn(|q| Cell {
            step: self.step + 1,
            kx: 2 * self.kx + (q & 1),
            ky: 2 * self.ky + (q >> 1),
        })
    }
}

/// An active set of the non-standard basis closed under "parent present".
#[derive(Clone, Debug)]
pub struct QuadTree {
    basis: TensorBasis,
    /// Per step `s < L`: active flags of the `2^(cx+s) x 2^(cy+s)` cells, index `ky w + kx`.
    active: Vec<Vec<bool>>,
}

impl QuadTree {
    /// The tree on `basis` (its levels are the depth limit) with every cell of the steps
    /// `0..base_steps` active, i.e. the uniform space `V_{cx+base_steps} (x) V_{cy+base_steps}`.
    ///
    /// Panics if `base_steps > L` (an internal contract: callers validate parameters).
    pub fn uniform(basis: TensorBasis, base_steps: u32) -> Self {
        let steps = basis.steps();
        assert!(base_steps <= steps, "base steps {base_steps} > L = {steps}");
        let (cx, cy) = basis.coarse_levels();
        let active = (0..steps)
            .map(|s| vec![s < base_steps; (1usize << (cx + s)) * (1usize << (cy + s))])
            .collect();
        Self { basis, active }
    }

    /// The tensor basis at the depth limit.
    pub fn basis(&self) -> &TensorBasis {
        &self.basis
    }
    /// Non-standard steps `L` of the basis (the depth limit in steps).
    pub fn steps(&self) -> u32 {
        self.basis.steps()
    }
    /// Cells per axis at step `s`: `(2^(cx+s), 2^(cy+s))`.
    pub fn cell_dims(&self, step: u32) -> (usize, usize) {
        let (cx, cy) = self.basis.coarse_levels();
        (1usize << (cx + step), 1usize << (cy + step))
    }
    /// The cells at `cell`'s step within one cell of it (`|dk| <= 1` per axis, `cell`
    /// included), row by row (`ky` outer, `kx` inner), clipped to the plane.
    pub fn neighbourhood(&self, cell: Cell) -> impl Iterator<Item = Cell> {
        let (w, h) = self.cell_dims(cell.step);
        let xs = cell.kx.saturating_sub(1)..=(cell.kx + 1).min(w - 1);
        (cell.ky.saturating_sub(1)..=(cell.ky + 1).min(h - 1)).flat_map(move |ky| {
            xs.clone().map(move |kx| Cell {
                step: cell.step,
                kx,
                ky,
            })
        })
    }
    /// Whether `cell` is active (cells at step `L` and beyond never are).
    pub fn is_active(&self, cell: Cell) -> bool {
        let Some(flags) = self.active.get(cell.step as usize) else {
            return false;
        };
        let (w, _) = self.cell_dims(cell.step);
        flags[cell.ky * w + cell.kx]
    }

    /// Deepens the tree at `cell` (activates it: adds its three functions). Returns false if
    /// it was active already.
    /// Panics if its parent is inactive or it lies at or beyond the depth limit (a broken
    /// internal contract: only leaves below the limit are offered for refinement).
    pub fn deepen(&mut self, cell: Cell) -> bool {
        assert!(cell.step < self.steps(), "cell {cell:?} at the depth limit");
        if let Some(parent) = cell.parent() {
            assert!(self.is_active(parent), "parent of {cell:?} inactive");
        }
        let (w, _) = self.cell_dims(cell.step);
        !std::mem::replace(
            &mut self.active[cell.step as usize][cell.ky * w + cell.kx],
            true,
        )
    }

    /// Number of active cells.
    pub fn active_cells(&self) -> usize {
        self.active
            .iter()
            .map(|f| f.iter().filter(|&&a| a).count())
            .sum()
    }

    /// Number of active functions: `2^cx 2^cy` coarse ones and three per active cell.
    pub fn len(&self) -> usize {
        let (cx, cy) = self.basis.coarse_levels();
        (1usize << (cx + cy)) + 3 * self.active_cells()
    }
    /// Always false (the coarse functions are always active).
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The active functions as Mallat indices `iy nx + ix` of the basis, ascending.
    pub fn functions(&self) -> Vec<usize> {
        let (nx, _) = self.basis.dims();
        let (cx, cy) = self.basis.coarse_levels();
        let mut out = Vec::with_capacity(self.len());
        for ky in 0..1usize << cy {
            for kx in 0..1usize << cx {
                out.push(ky * nx + kx);
            }
        }
        for (s, flags) in self.active.iter().enumerate() {
            let (w, _) = self.cell_dims(s as u32);
            let (jx, jy) = (cx + s as u32, cy + s as u32);
            for (i, _) in flags.iter().enumerate().filter(|(_, &a)| a) {
                let (kx, ky) = (i % w, i / w);
                out.push(ky * nx + (1usize << jx) + kx);
                out.push(((1usize << jy) + ky) * nx + kx);
                out.push(((1usize << jy) + ky) * nx + (1usize << jx) + kx);
            }
        }
        out.sort_unstable();
        out
    }

    /// The Mallat indices of the three functions of `cell` (`W (x) V`, `V (x) W`, `W (x) W`).
    pub fn cell_functions(&self, cell: Cell) -> [usize; 3] {
        let (nx, _) = self.basis.dims();
        let (cx, cy) = self.basis.coarse_levels();
        let (ox, oy) = (1usize << (cx + cell.step), 1usize << (cy + cell.step));
        [
            cell.ky * nx + ox + cell.kx,
            (oy + cell.ky) * nx + cell.kx,
            (oy + cell.ky) * nx + ox + cell.kx,
        ]
    }

    /// The cell owning the function at Mallat index `index`, `None` for a coarse scaling
    /// function.
    pub fn cell_of_function(&self, index: usize) -> Option<Cell> {
        let (nx, _) = self.basis.dims();
        let (cx, cy) = self.basis.coarse_levels();
        let (ix, iy) = (index % nx, index / nx);
        // step of one axis index: None for a scaling index below 2^c
        let axis = |i: usize, c: u32| -> Option<u32> { (i >= 1usize << c).then(|| i.ilog2() - c) };
        let step = axis(ix, cx).max(axis(iy, cy))?;
        let off = |i: usize, c: u32| {
            let j = c + step;
            if i >= 1usize << j {
                i - (1usize << j)
            } else {
                i
            }
        };
        Some(Cell {
            step,
            kx: off(ix, cx),
            ky: off(iy, cy),
        })
    }

    /// The cell of step `s` holding the point `(x, y)` (pixel units, inside the image).
    pub fn cell_at(&self, step: u32, x: f64, y: f64) -> Cell {
        let (w, h) = self.cell_dims(step);
        let k = |t: f64, size: usize, n: usize| {
            ((t / size as f64 * n as f64).floor().max(0.0) as usize).min(n - 1)
        };
        Cell {
            step,
            kx: k(x, self.basis.width(), w),
            ky: k(y, self.basis.height(), h),
        }
    }

    /// The leaf holding `(x, y)`: the cell of step `d`, `d` the local depth there.
    pub fn leaf_at(&self, x: f64, y: f64) -> Cell {
        let mut step = 0;
        while step < self.steps() && self.is_active(self.cell_at(step, x, y)) {
            step += 1;
        }
        self.cell_at(step, x, y)
    }

    /// Local depth `d(x, y)` in steps (`0..=L`): the local space is `V_{cx+d} (x) V_{cy+d}`.
    pub fn depth_at(&self, x: f64, y: f64) -> u32 {
        self.leaf_at(x, y).step
    }

    /// Every leaf of the quadtree, in depth-first order from the step-0 cells.
    pub fn leaves(&self) -> Vec<Cell> {
        let (w, h) = self.cell_dims(0);
        let mut out = Vec::new();
        let mut stack: Vec<Cell> = (0..h)
            .rev()
            .flat_map(|ky| (0..w).rev().map(move |kx| Cell { step: 0, kx, ky }))
            .collect();
        while let Some(c) = stack.pop() {
            if self.is_active(c) {
                stack.extend(c.children().into_iter().rev());
            } else {
                out.push(c);
            }
        }
        out
    }

    /// The rectangle `[x0, x1] x [y0, y1]` of a cell, in pixel units.
    pub fn rect(&self, cell: Cell) -> [f64; 4] {
        let (w, h) = self.cell_dims(cell.step);
        let (sx, sy) = (
            self.basis.width() as f64 / w as f64,
            self.basis.height() as f64 / h as f64,
        );
        [
            cell.kx as f64 * sx,
            (cell.kx + 1) as f64 * sx,
            cell.ky as f64 * sy,
            (cell.ky + 1) as f64 * sy,
        ]
    }

    /// Samples per leaf: the leaf of every position, counted.
    pub fn leaf_counts(&self, xs: &[f64], ys: &[f64]) -> HashMap<Cell, usize> {
        let mut counts = HashMap::new();
        for (&x, &y) in xs.iter().zip(ys) {
            *counts.entry(self.leaf_at(x, y)).or_insert(0) += 1;
        }
        counts
    }

    /// The local depth at every pixel centre (`H x W`, row-major), in steps.
    pub fn depth_map(&self) -> Vec<u32> {
        let (w, h) = (self.basis.width(), self.basis.height());
        (0..h)
            .flat_map(|py| (0..w).map(move |px| (px, py)))
            .map(|(px, py)| self.depth_at(px as f64 + 0.5, py as f64 + 0.5))
            .collect()
    }

    /// Active cells per step (a histogram of the tree).
    pub fn cells_per_step(&self) -> Vec<usize> {
        self.active
            .iter()
            .map(|f| f.iter().filter(|&&a| a).count())
            .collect()
    }
}
