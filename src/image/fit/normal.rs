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
        let (nx, ny) = basis.dims();
        let rx = Ranges::of(basis.scale_x());
        let ry = Ranges::of(basis.scale_y());
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
                        acc.support_samples[col] += 1;
                        for (c, f) in values.iter().enumerate() {
                            acc.rhs[c][col] += vb * f[i];
                        }
                        // same y row: kx2 >= kx
                        let base = pattern.offset(vyb.index, vxb.index, vyb.index, vxb.index);
                        for (a_x, vxa) in fx.iter().enumerate().skip(b_x) {
                            acc.values[base + (vxa.index - vxb.index)] += prod[b_y * wx + a_x] * vb;
                        }
                        // rows above in y: every kx2
                        for (a_y, vya) in fy.iter().enumerate().skip(b_y + 1) {
                            let row = pattern.offset(vyb.index, vxb.index, vya.index, fx[0].index);
                            for a_x in 0..wx {
                                acc.values[row + a_x] += prod[a_y * wx + a_x] * vb;
                            }
                        }
                    }
                }
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

/// `y = G x` with `G` given by its lower triangle (symmetric product), parallel over
/// column blocks of `G` with one output per block, summed.
pub fn symmetric_matvec(pattern: &StencilPattern, g: &[f64], x: &[f64], y: &mut [f64]) {
    let n = pattern.len();
    // Row y of the grid touches rows ky..=ky + b of the output: split the columns into
    // contiguous y bands; each band writes a private output, summed afterwards.
    let bands = (rayon::current_num_threads() * 2).clamp(1, pattern.ny);
    let per = pattern.ny.div_ceil(bands);
    let parts: Vec<(usize, Vec<f64>)> = (0..bands)
        .into_par_iter()
        .map(|band| {
            let (ky0, ky1) = (band * per, ((band + 1) * per).min(pattern.ny));
            let c0 = ky0 * pattern.nx;
            let c1 = ky1 * pattern.nx;
            let lo = c0;
            let hi = (c0..c1)
                .map(|j| pattern.row_idx[pattern.col_ptr[j + 1] - 1] + 1)
                .max()
                .unwrap_or(lo);
            let mut out = vec![0.0; hi.saturating_sub(lo)];
            for j in c0..c1 {
                let (s, e) = (pattern.col_ptr[j], pattern.col_ptr[j + 1]);
                let xj = x[j];
                let mut acc = 0.0;
                for (&i, &v) in pattern.row_idx[s..e].iter().zip(&g[s..e]) {
                    out[i - lo] += v * xj;
                    if i != j {
                        acc += v * x[i];
                    }
                }
                out[j - lo] += acc;
            }
            (lo, out)
        })
        .collect();
    y[..n].iter_mut().for_each(|v| *v = 0.0);
    for (lo, out) in parts {
        y[lo..lo + out.len()]
            .iter_mut()
            .zip(&out)
            .for_each(|(a, b)| *a += b);
    }
}
