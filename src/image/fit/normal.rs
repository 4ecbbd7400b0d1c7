//! The 2D normal equations of the single-scale space, accumulated sample by sample.
//!
//! With `K[i, (ky, kx)] = phi_{Jx,kx}(x_i) phi_{Jy,ky}(y_i)` (no `K` stored),
//! `G = K^T K = sum_i (phi(x_i) phi(x_i)^T) (x) (phi(y_i) phi(y_i)^T)` and `b_c = K^T f_c`.
//! Its pattern is the Kronecker product of the two 1D patterns: `(kx, kx')` is structurally
//! nonzero when some cell of `[0, W]` carries both `phi_{Jx,kx}` and `phi_{Jx,kx'}` (a
//! contiguous range around `kx`, within the 1D half-bandwidth `3p - 3`), likewise in y. The
//! symbolic pattern (lower triangle, CSC, rows sorted) is built once from the 1D ranges; each
//! thread accumulates its share of the samples into its own value array on that pattern,
//! then the arrays are summed. Each column's entries are addressed directly (no search):
//! column `(ky, kx)` holds first the rows `(ky, kx'..)`, `kx' >= kx`, then for each
//! `ky' > ky` in range the whole x range of `kx`.

use rayon::prelude::*;

use crate::basis::tensor::TensorBasis;
use crate::basis::CdvBasis;
use crate::solve::vectors::interleave;

/// Structural range `lo[k]..=hi[k]` of the 1D single-scale functions sharing a cell with
/// `phi_{J,k}` (from one evaluation at each of the `2^J` cell centres).
#[derive(Clone, Debug)]
pub(crate) struct Ranges {
    pub lo: Vec<usize>,
    pub hi: Vec<usize>,
}

impl Ranges {
    fn of(scale: &CdvBasis) -> Self {
        let n = 1usize << scale.coarse();
        let mut lo: Vec<usize> = (0..n).collect();
        let mut hi = lo.clone();
        let mut ev = scale.evaluator();
        let mut out = Vec::new();
        for c in 0..n {
            ev.eval_scaling_unit_into((c as f64 + 0.5) / n as f64, &mut out);
            if let (Some(first), Some(last)) = (out.first(), out.last()) {
                for v in &out {
                    lo[v.index] = lo[v.index].min(first.index);
                    hi[v.index] = hi[v.index].max(last.index);
                }
            }
        }
        Self { lo, hi }
    }
    fn width(&self, k: usize) -> usize {
        self.hi[k] - self.lo[k] + 1
    }
}

/// The lower-triangle CSC pattern of `G` and the direct addressing of its entries.
#[derive(Clone, Debug)]
pub struct StencilPattern {
    pub(crate) nx: usize,
    pub(crate) ny: usize,
    pub(crate) rx: Ranges,
    /// Column pointers (`nx ny + 1`).
    pub col_ptr: Vec<usize>,
    /// Row indices, sorted within each column; the diagonal comes first.
    pub row_idx: Vec<usize>,
}

impl StencilPattern {
    /// The pattern of `G` for the basis.
    pub fn new(basis: &TensorBasis) -> Self {
        Self::from_ranges(Ranges::of(basis.scale_x()), Ranges::of(basis.scale_y()))
    }

    /// The pattern of the `nx x ny` grid of functions with the 1D structural ranges `rx`
    /// and `ry` (`nx = rx.lo.len()`): also a window of a larger basis (image tiles).
    pub(crate) fn from_ranges(rx: Ranges, ry: Ranges) -> Self {
        let (nx, ny) = (rx.lo.len(), ry.lo.len());
        let mut col_ptr = Vec::with_capacity(nx * ny + 1);
        col_ptr.push(0);
        let mut total = 0;
        for ky in 0..ny {
            for kx in 0..nx {
                total += (rx.hi[kx] - kx + 1) + (ry.hi[ky] - ky) * rx.width(kx);
                col_ptr.push(total);
            }
        }
        let mut row_idx = vec![0usize; total];
        // one block of columns per grid row ky, filled in parallel
        let blocks: Vec<(usize, &mut [usize])> = {
            let mut rest = row_idx.as_mut_slice();
            let mut v = Vec::with_capacity(ny);
            for ky in 0..ny {
                let len = col_ptr[(ky + 1) * nx] - col_ptr[ky * nx];
                let (a, b) = rest.split_at_mut(len);
                v.push((ky, a));
                rest = b;
            }
            v
        };
        blocks.into_par_iter().for_each(|(ky, out)| {
            let mut t = 0;
            for kx in 0..nx {
                for kx2 in kx..=rx.hi[kx] {
                    out[t] = ky * nx + kx2;
                    t += 1;
                }
                for ky2 in ky + 1..=ry.hi[ky] {
                    for kx2 in rx.lo[kx]..=rx.hi[kx] {
                        out[t] = ky2 * nx + kx2;
                        t += 1;
                    }
                }
            }
        });
        Self {
            nx,
            ny,
            rx,
            col_ptr,
            row_idx,
        }
    }

    /// Number of unknowns `nx ny`.
    pub fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Always false.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Stored entries (lower triangle with the diagonal).
    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Position in the value array of `G[(ky2, kx2), (ky, kx)]`, `(ky2, kx2) >= (ky, kx)`
    /// in the layout order and within the pattern.
    #[inline]
    pub(crate) fn offset(&self, ky: usize, kx: usize, ky2: usize, kx2: usize) -> usize {
        let base = self.col_ptr[ky * self.nx + kx];
        if ky2 == ky {
            base + (kx2 - kx)
        } else {
            base + (self.rx.hi[kx] - kx + 1)
                + (ky2 - ky - 1) * self.rx.width(kx)
                + (kx2 - self.rx.lo[kx])
        }
    }
}

/// Nested dissection of the `nx x ny` grid of unknowns `ky * nx + kx` (George 1973): split the
/// longer side by a strip of `sep` grid lines (no coupling crosses it when `sep` is the 1D
/// half-bandwidth), order both halves recursively, then the strip. Returns `fwd` with
/// `fwd[new] = old`. On a 2D stencil this keeps the fill at `O(N log N)` and the factor flops
/// at `O(N^{3/2})`, whatever the ordering heuristic would find.
pub(crate) fn nested_dissection(nx: usize, ny: usize, sep_x: usize, sep_y: usize) -> Vec<usize> {
    let mut out = Vec::with_capacity(nx * ny);
    dissect(nx, (0, nx), (0, ny), (sep_x.max(1), sep_y.max(1)), &mut out);
    out
}

fn dissect(
    nx: usize,
    (x0, x1): (usize, usize),
    (y0, y1): (usize, usize),
    (sx, sy): (usize, usize),
    out: &mut Vec<usize>,
) {
    let (w, h) = (x1 - x0, y1 - y0);
    let block = |out: &mut Vec<usize>, xr: (usize, usize), yr: (usize, usize)| {
        for ky in yr.0..yr.1 {
            for kx in xr.0..xr.1 {
                out.push(ky * nx + kx);
            }
        }
    };
    if w * h <= LEAF || (w < 2 * sx + 2 && h < 2 * sy + 2) {
        block(out, (x0, x1), (y0, y1));
        return;
    }
    if (w >= h && w >= 2 * sx + 2) || h < 2 * sy + 2 {
        let mid = x0 + (w - sx) / 2;
        dissect(nx, (x0, mid), (y0, y1), (sx, sy), out);
        dissect(nx, (mid + sx, x1), (y0, y1), (sx, sy), out);
        block(out, (mid, mid + sx), (y0, y1));
    } else {
        let mid = y0 + (h - sy) / 2;
        dissect(nx, (x0, x1), (y0, mid), (sx, sy), out);
        dissect(nx, (x0, x1), (mid + sy, y1), (sx, sy), out);
        block(out, (x0, x1), (mid, mid + sy));
    }
}

/// Grids at most this large are ordered row by row (a dense leaf front).
const LEAF: usize = 64;

impl StencilPattern {
    /// Nested-dissection order of the unknowns ([`nested_dissection`] with separators one
    /// 1D half-bandwidth wide, the same on both axes: it depends on `p` only).
    pub fn nested_dissection(&self) -> Vec<usize> {
        let b = (0..self.nx).map(|k| self.rx.hi[k] - k).max().unwrap_or(1);
        nested_dissection(self.nx, self.ny, b, b)
    }
}

/// `G` (lower triangle on [`StencilPattern`]), `b_c = K^T f_c` per channel, and the number
/// of samples in each function's support.
#[derive(Clone, Debug)]
pub struct NormalEquations2d {
    /// Values of `G` on the pattern.
    pub values: Vec<f64>,
    /// Right-hand sides, one per channel.
    pub rhs: Vec<Vec<f64>>,
    /// Samples whose cell lies in the support of each function.
    pub support_samples: Vec<u32>,
}

impl NormalEquations2d {
    /// Adds sample `i` (values `values[c][i]`) with the 1D factors `fx`, `fy` of its tensor
    /// row (ascending indices in the layout of `pattern`); `prod` is scratch.
    pub(crate) fn add_sample(
        &mut self,
        pattern: &StencilPattern,
        fx: &[crate::basis::BasisValue],
        fy: &[crate::basis::BasisValue],
        values: &[&[f64]],
        i: usize,
        prod: &mut Vec<f64>,
    ) {
        let wx = fx.len();
        prod.clear();
        for vy in fy {
            for vx in fx {
                prod.push(vy.value * vx.value);
            }
        }
        for (b_y, vyb) in fy.iter().enumerate() {
            for (b_x, vxb) in fx.iter().enumerate() {
                let vb = prod[b_y * wx + b_x];
                let col = vyb.index * pattern.nx + vxb.index;
                self.support_samples[col] += 1;
                for (c, f) in values.iter().enumerate() {
                    self.rhs[c][col] += vb * f[i];
                }
                // same y row: kx2 >= kx
                let base = pattern.offset(vyb.index, vxb.index, vyb.index, vxb.index);
                for (a_x, vxa) in fx.iter().enumerate().skip(b_x) {
                    self.values[base + (vxa.index - vxb.index)] += prod[b_y * wx + a_x] * vb;
                }
                // rows above in y: every kx2
                for (a_y, vya) in fy.iter().enumerate().skip(b_y + 1) {
                    let row = pattern.offset(vyb.index, vxb.index, vya.index, fx[0].index);
                    for a_x in 0..wx {
                        self.values[row + a_x] += prod[a_y * wx + a_x] * vb;
                    }
                }
            }
        }
    }
}

/// Accumulates the normal equations; positions must already be checked to lie in the image.
pub fn accumulate(
    basis: &TensorBasis,
    pattern: &StencilPattern,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> NormalEquations2d {
    let n = pattern.len();
    let nnz = pattern.nnz();
    let channels = values.len();
    let threads = rayon::current_num_threads().max(1);
    let per = xs.len().div_ceil(threads).max(4096);
    let starts: Vec<usize> = (0..xs.len()).step_by(per.max(1)).collect();
    let empty = || NormalEquations2d {
        values: vec![0.0; nnz],
        rhs: vec![vec![0.0; n]; channels],
        support_samples: vec![0; n],
    };
    starts
        .par_iter()
        .map(|&start| {
            let end = (start + per).min(xs.len());
            let mut acc = empty();
            let mut ev = basis.evaluator();
            let mut prod: Vec<f64> = Vec::with_capacity(64);
            for i in start..end {
                let (fx, fy) = ev.factors_unchecked(xs[i], ys[i]);
                acc.add_sample(pattern, fx, fy, values, i, &mut prod);
            }
            acc
        })
        .reduce_with(|mut a, b| {
            a.values
                .par_iter_mut()
                .zip(&b.values)
                .for_each(|(x, y)| *x += y);
            for (x, y) in a.rhs.iter_mut().zip(&b.rhs) {
                x.iter_mut().zip(y).for_each(|(p, q)| *p += q);
            }
            a.support_samples
                .iter_mut()
                .zip(&b.support_samples)
                .for_each(|(p, q)| *p += q);
            a
        })
        .unwrap_or_else(empty)
}

/// `y_c = G x_c` for every vector `c`, with `G` given by its lower triangle (symmetric
/// product): one pass over `G` serves all vectors, held interleaved (`x[j k + c]`) so that each
/// entry of `G` updates the `k` channels of its row and column from adjacent memory. Parallel
/// over contiguous bands of columns, each band writing a private output (rows `j..` of its
/// columns), summed afterwards; within a column the diagonal comes first.
pub fn symmetric_matvec(pattern: &StencilPattern, g: &[f64], x: &[&[f64]], y: &mut [Vec<f64>]) {
    let k = x.len();
    let xi = interleave(x);
    let bands = rayon::current_num_threads().clamp(1, pattern.ny);
    let per = pattern.ny.div_ceil(bands);
    let parts: Vec<(usize, usize, Vec<f64>)> = (0..bands)
        .into_par_iter()
        .map(|band| {
            let (ky0, ky1) = (band * per, ((band + 1) * per).min(pattern.ny));
            let (c0, c1) = (ky0 * pattern.nx, ky1 * pattern.nx);
            let hi = (c0..c1)
                .map(|j| pattern.row_idx[pattern.col_ptr[j + 1] - 1] + 1)
                .max()
                .unwrap_or(c0);
            let len = hi.saturating_sub(c0);
            // out[(i - c0) k + c]
            let mut out = vec![0.0; len * k];
            let mut acc = vec![0.0; k];
            for j in c0..c1 {
                let (s, e) = (pattern.col_ptr[j], pattern.col_ptr[j + 1]);
                let xj = &xi[j * k..(j + 1) * k];
                // the diagonal
                for (a, &v) in acc.iter_mut().zip(xj) {
                    *a = g[s] * v;
                }
                for (&i, &v) in pattern.row_idx[s + 1..e].iter().zip(&g[s + 1..e]) {
                    let o = (i - c0) * k;
                    let (oi, xr) = (&mut out[o..o + k], &xi[i * k..(i + 1) * k]);
                    for c in 0..k {
                        oi[c] += v * xj[c];
                        acc[c] += v * xr[c];
                    }
                }
                let o = (j - c0) * k;
                for (oj, a) in out[o..o + k].iter_mut().zip(&acc) {
                    *oj += a;
                }
            }
            (c0, len, out)
        })
        .collect();
    for yc in y.iter_mut() {
        yc.iter_mut().for_each(|v| *v = 0.0);
    }
    for (c0, len, out) in parts {
        for (c, yc) in y.iter_mut().enumerate() {
            yc[c0..c0 + len]
                .iter_mut()
                .zip(out[c..].iter().step_by(k))
                .for_each(|(a, b)| *a += b);
        }
    }
}
