//! The 2D normal equations of the single-scale space, accumulated sample by sample.
//!
//! With `K[i, (ky, kx)] = phi_{Jx,kx}(x_i) phi_{Jy,ky}(y_i)` (no `K` stored),
//! `G = K^T K = sum_i (phi(x_i) phi(x_i)^T) (x) (phi(y_i) phi(y_i)^T)` and `b_c = K^T f_c`.
//! Its pattern is the Kronecker product of the two 1D patterns: `(kx, kx')` is structurally
//! nonzero when some cell of `[0, W]` carries both `phi_{Jx,kx}` and `phi_{Jx,kx'}` (a
//! contiguous range around `kx`, within the 1D half-bandwidth `3p - 3`), likewise in y. The
//! symbolic pattern (lower triangle, CSC, rows sorted) is built once from the 1D ranges. A
//! sample adds only to the columns `(ky, kx)` of its own functions, so the columns are cut
//! into bands of [`BAND_ROWS`] grid rows `ky`, filled in parallel: a band takes, in sample
//! order, the samples whose y cell carries a function of the band, and adds their terms in
//! its columns only. Every entry thus sums its samples in sample order, as one thread would:
//! the same bits whatever the number of threads, and no private copies of `G` to sum.
//! Each column's entries are addressed directly (no search):
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

/// `(first, last)` index of the 1D single-scale functions nonzero in each cell
/// `[c, c + 1) / 2^J` of `[0, 1]`, from one evaluation at each cell centre (the functions
/// nonzero at `t` depend only on its cell, [`unit_cell`]); `None` for a cell without any.
fn cell_spans(scale: &CdvBasis) -> Vec<Option<(usize, usize)>> {
    let n = 1usize << scale.coarse();
    let mut ev = scale.evaluator();
    let mut out = Vec::new();
    (0..n)
        .map(|c| {
            ev.eval_scaling_unit_into((c as f64 + 0.5) / n as f64, &mut out);
            out.first().zip(out.last()).map(|(f, l)| (f.index, l.index))
        })
        .collect()
}

/// The cell `floor(2^J t)` of `t` in `[0, 1]` at level `J` (`2^J t` is exact), the last
/// cell at `t = 1`: the cell the evaluator walks from.
fn unit_cell(t: f64, level: u32) -> usize {
    let cells = 1usize << level;
    if t >= 1.0 {
        cells - 1
    } else if t <= 0.0 {
        0
    } else {
        ((t * cells as f64).floor() as usize).min(cells - 1)
    }
}

impl Ranges {
    fn of(scale: &CdvBasis) -> Self {
        let n = 1usize << scale.coarse();
        let mut lo: Vec<usize> = (0..n).collect();
        let mut hi = lo.clone();
        for (first, last) in cell_spans(scale).into_iter().flatten() {
            for k in first..=last {
                lo[k] = lo[k].min(first);
                hi[k] = hi[k].max(last);
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
    /// Nested-dissection order of the unknowns (`nested_dissection` with separators one
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
        let mut all = Band {
            rows: (0, pattern.ny),
            first_column: 0,
            first_value: 0,
            values: &mut self.values,
            rhs: self.rhs.iter_mut().map(|r| r.as_mut_slice()).collect(),
            support_samples: &mut self.support_samples,
        };
        all.add_sample(pattern, fx, fy, values, i, prod);
    }
}

/// Grid rows `ky` of a band of columns of `G` in [`accumulate`].
pub const BAND_ROWS: usize = 32;

/// The columns `(ky, kx)`, `rows.0 <= ky < rows.1`, of `G`, `b_c` and the support counts:
/// `values[0]` is entry `first_value = col_ptr[first_column]` of the whole array, `rhs[c][0]`
/// and `support_samples[0]` are column `first_column = rows.0 nx`.
struct Band<'a> {
    rows: (usize, usize),
    first_column: usize,
    first_value: usize,
    values: &'a mut [f64],
    rhs: Vec<&'a mut [f64]>,
    support_samples: &'a mut [u32],
}

impl Band<'_> {
    /// The terms of sample `i` in the band's columns (see [`NormalEquations2d::add_sample`]).
    fn add_sample(
        &mut self,
        pattern: &StencilPattern,
        fx: &[crate::basis::BasisValue],
        fy: &[crate::basis::BasisValue],
        values: &[&[f64]],
        i: usize,
        prod: &mut Vec<f64>,
    ) {
        let wx = fx.len();
        let (c0, v0) = (self.first_column, self.first_value);
        prod.clear();
        for vy in fy {
            for vx in fx {
                prod.push(vy.value * vx.value);
            }
        }
        for (b_y, vyb) in fy.iter().enumerate() {
            if vyb.index < self.rows.0 || vyb.index >= self.rows.1 {
                continue;
            }
            for (b_x, vxb) in fx.iter().enumerate() {
                let vb = prod[b_y * wx + b_x];
                let col = vyb.index * pattern.nx + vxb.index - c0;
                self.support_samples[col] += 1;
                for (c, f) in values.iter().enumerate() {
                    self.rhs[c][col] += vb * f[i];
                }
                // same y row: kx2 >= kx
                let base = pattern.offset(vyb.index, vxb.index, vyb.index, vxb.index) - v0;
                for (a_x, vxa) in fx.iter().enumerate().skip(b_x) {
                    self.values[base + (vxa.index - vxb.index)] += prod[b_y * wx + a_x] * vb;
                }
                // rows above in y: every kx2
                for (a_y, vya) in fy.iter().enumerate().skip(b_y + 1) {
                    let row = pattern.offset(vyb.index, vxb.index, vya.index, fx[0].index) - v0;
                    for a_x in 0..wx {
                        self.values[row + a_x] += prod[a_y * wx + a_x] * vb;
                    }
                }
            }
        }
    }
}

/// Accumulates the normal equations; positions must already be checked to lie in the image.
/// Bands of [`BAND_ROWS`] grid rows in parallel, each over the samples whose y cell carries
/// one of its functions (one comparison a sample for the cell, the factors evaluated only
/// for those): a sample whose functions straddle two bands is evaluated in both.
pub fn accumulate(
    basis: &TensorBasis,
    pattern: &StencilPattern,
    xs: &[f64],
    ys: &[f64],
    values: &[&[f64]],
) -> NormalEquations2d {
    let n = pattern.len();
    let (nx, ny) = (pattern.nx, pattern.ny);
    let mut ne = NormalEquations2d {
        values: vec![0.0; pattern.nnz()],
        rhs: vec![vec![0.0; n]; values.len()],
        support_samples: vec![0; n],
    };
    let scale_y = basis.scale_y();
    let (level, domain) = (scale_y.coarse(), scale_y.domain());
    let spans = cell_spans(scale_y);
    let cells: Vec<u32> = ys
        .par_iter()
        .map(|&y| unit_cell(domain.to_unit(y), level) as u32)
        .collect();
    // the bands, each with the (contiguous) range of cells carrying one of its functions
    let mut bands = Vec::with_capacity(ny.div_ceil(BAND_ROWS));
    {
        let mut values_rest = ne.values.as_mut_slice();
        let mut rhs_rest: Vec<&mut [f64]> = ne.rhs.iter_mut().map(|r| r.as_mut_slice()).collect();
        let mut support_rest = ne.support_samples.as_mut_slice();
        for ky0 in (0..ny).step_by(BAND_ROWS) {
            let ky1 = (ky0 + BAND_ROWS).min(ny);
            let (c0, c1) = (ky0 * nx, ky1 * nx);
            let (v0, v1) = (pattern.col_ptr[c0], pattern.col_ptr[c1]);
            let (v, rest) = std::mem::take(&mut values_rest).split_at_mut(v1 - v0);
            values_rest = rest;
            let mut rhs = Vec::with_capacity(rhs_rest.len());
            for r in rhs_rest.iter_mut() {
                let (a, rest) = std::mem::take(r).split_at_mut(c1 - c0);
                rhs.push(a);
                *r = rest;
            }
            let (sup, rest) = std::mem::take(&mut support_rest).split_at_mut(c1 - c0);
            support_rest = rest;
            let carrying = |c: &usize| spans[*c].is_some_and(|(f, l)| l >= ky0 && f < ky1);
            let first_cell = (0..spans.len()).find(carrying);
            let last_cell = (0..spans.len()).rev().find(carrying);
            let band = Band {
                rows: (ky0, ky1),
                first_column: c0,
                first_value: v0,
                values: v,
                rhs,
                support_samples: sup,
            };
            bands.push((first_cell.zip(last_cell), band));
        }
    }
    bands.into_par_iter().for_each(|(cell_range, mut band)| {
        let Some((lo, hi)) = cell_range else {
            return;
        };
        let (lo, width) = (lo as u32, (hi - lo) as u32);
        let mut ev = basis.evaluator();
        let mut prod: Vec<f64> = Vec::with_capacity(64);
        for (i, &c) in cells.iter().enumerate() {
            if c.wrapping_sub(lo) > width {
                continue;
            }
            let (fx, fy) = ev.factors_unchecked(xs[i], ys[i]);
            debug_assert!(
                spans[c as usize] == fy.first().zip(fy.last()).map(|(f, l)| (f.index, l.index))
            );
            band.add_sample(pattern, fx, fy, values, i, &mut prod);
        }
    });
    ne
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

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    use super::*;
    use crate::basis::FilterFamily;

    /// The banded parallel accumulation against one sequential pass of
    /// [`NormalEquations2d::add_sample`] over all samples in order: every entry of `G`, every
    /// `b_c` and every support count equal to the bit (both sum each entry's terms in sample
    /// order). Random positions plus the image's corners and edges and positions on the cell
    /// boundaries of both axes (where a sample's functions change), several bands (`ny`
    /// above [`BAND_ROWS`]), `p = 2` and `3`, a width and height that are not powers of two.
    #[test]
    fn banded_accumulation_equals_the_sequential_sum_bit_for_bit() {
        for (p, (w, h), levels) in [(2, (40, 100), (6, 7)), (3, (23, 70), (5, 7))] {
            let basis = TensorBasis::new(p, FilterFamily::cdv_default(p), w, h, levels).unwrap();
            let pattern = StencilPattern::new(&basis);
            assert!(pattern.ny > 2 * BAND_ROWS, "several bands");
            let mut rng = Pcg64::seed_from_u64(7);
            let (wf, hf) = (w as f64, h as f64);
            let mut xs: Vec<f64> = (0..5000).map(|_| rng.random::<f64>() * wf).collect();
            let mut ys: Vec<f64> = (0..5000).map(|_| rng.random::<f64>() * hf).collect();
            let (cx, cy) = (1usize << levels.0, 1usize << levels.1);
            for k in 0..=cy {
                // on every y cell boundary, and both corners of the x axis
                for x in [0.0, wf, rng.random::<f64>() * wf] {
                    xs.push(x);
                    ys.push(hf * k as f64 / cy as f64);
                }
            }
            for k in 0..=cx {
                for y in [0.0, hf, rng.random::<f64>() * hf] {
                    xs.push(wf * k as f64 / cx as f64);
                    ys.push(y);
                }
            }
            let m = xs.len();
            let channels: Vec<Vec<f64>> = (0..3)
                .map(|_| (0..m).map(|_| rng.random::<f64>() - 0.5).collect())
                .collect();
            let values: Vec<&[f64]> = channels.iter().map(|c| c.as_slice()).collect();

            let banded = accumulate(&basis, &pattern, &xs, &ys, &values);

            let n = pattern.len();
            let mut serial = NormalEquations2d {
                values: vec![0.0; pattern.nnz()],
                rhs: vec![vec![0.0; n]; 3],
                support_samples: vec![0; n],
            };
            let mut ev = basis.evaluator();
            let mut prod = Vec::new();
            let mut terms = 0;
            for i in 0..m {
                let (fx, fy) = ev.factors_unchecked(xs[i], ys[i]);
                terms += fx.len() * fy.len();
                serial.add_sample(&pattern, fx, fy, &values, i, &mut prod);
            }
            assert!(banded
                .values
                .iter()
                .zip(&serial.values)
                .all(|(a, b)| a.to_bits() == b.to_bits()));
            for (a, b) in banded.rhs.iter().zip(&serial.rhs) {
                assert!(a.iter().zip(b).all(|(a, b)| a.to_bits() == b.to_bits()));
            }
            assert_eq!(banded.support_samples, serial.support_samples);
            assert_eq!(
                serial
                    .support_samples
                    .iter()
                    .map(|&s| s as usize)
                    .sum::<usize>(),
                terms,
                "every sample counted once for each of its functions"
            );
        }
    }
}
