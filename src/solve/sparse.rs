//! Sparse plumbing shared by the solvers: `K = 2^e K_s` (exact power-of-two scaling),
//! `K^T` as CSR, the normal matrix `G = K^T K`, and row-parallel products `Y = K X`.
//!
//! Scaling by a power of two is exact and `K^+ = 2^-e K_s^+`, so every solver works on
//! `K_s` with `max |K_s| ∈ [1, 2)`: entries of magnitude `1e300` or `1e-300` neither
//! overflow in `K^T K` nor underflow in the factorizations.

use rayon::prelude::*;
use sprs::CsMat;

use super::SolveError;

/// `K` prepared for the solvers: CSR, finite, scaled into `[1, 2)`, with its transpose.
pub(crate) struct Prepared {
    /// `K_s = 2^-e K`, CSR (`m x P`).
    pub k: CsMat<f64>,
    /// `K_s^T` as CSR (`P x m`): row `a` lists the samples where basis function `a` lives.
    pub kt: CsMat<f64>,
    /// The exponent `e`: `K = 2^e K_s`.
    pub exponent: i32,
}

/// `x * 2^e` without intermediate overflow or underflow for `|e| <= 2100`.
pub(crate) fn ldexp(x: f64, e: i32) -> f64 {
    let h = e / 2;
    x * 2f64.powi(h) * 2f64.powi(e - h)
}

/// Checks `K` (finite entries, CSR or converted to CSR), scales it and builds `K^T`.
pub(crate) fn prepare(k: &CsMat<f64>) -> Result<Prepared, SolveError> {
    if let Some((index, &value)) = k.data().iter().enumerate().find(|(_, v)| !v.is_finite()) {
        return Err(SolveError::NonFiniteInput {
            what: "kernel matrix".into(),
            index,
            value,
        });
    }
    let max = k.data().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    // frexp-like exponent: max = f * 2^e with f in [1, 2).
    let exponent = if max > 0.0 {
        max.log2().floor() as i32
    } else {
        0
    };
    let mut ks = if k.is_csr() {
        k.clone()
    } else {
        k.to_other_storage()
    };
    if exponent != 0 {
        ks.data_mut()
            .par_iter_mut()
            .for_each(|v| *v = ldexp(*v, -exponent));
    }
    if !ks.indptr().is_proper() {
        let shape = ks.shape();
        let indptr = ks.indptr().to_proper().into_owned();
        let (_, indices, data) = ks.into_raw_storage();
        ks = CsMat::new(shape, indptr, indices, data);
    }
    let kt = ks.transpose_view().to_csr();
    Ok(Prepared {
        k: ks,
        kt,
        exponent,
    })
}

/// Raw CSR/CSC arrays of a matrix with a proper (zero-based) `indptr`, as built by
/// [`prepare`] and the solvers.
pub(crate) fn raw(a: &CsMat<f64>) -> (&[usize], &[usize], &[f64]) {
    (a.indptr().into_raw_storage(), a.indices(), a.data())
}

/// Checks the channels: each must have `rows` finite values.
pub(crate) fn check_values(values: &[&[f64]], rows: usize) -> Result<(), SolveError> {
    for (c, v) in values.iter().enumerate() {
        if v.len() != rows {
            return Err(SolveError::DimensionMismatch {
                what: "values channel length (must equal the rows of K)",
                expected: rows,
                found: v.len(),
            });
        }
        if let Some((index, &value)) = v.iter().enumerate().find(|(_, x)| !x.is_finite()) {
            return Err(SolveError::NonFiniteInput {
                what: format!("values channel {c}"),
                index,
                value,
            });
        }
    }
    Ok(())
}

/// Errors out if any entry is non-finite.
pub(crate) fn check_finite_output(x: &[f64], what: &str) -> Result<(), SolveError> {
    if x.par_iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(SolveError::NonFiniteOutput { what: what.into() })
    }
}

/// `K^T` as CSR (rows sorted: samples ascending) and, for each of its entries `t`, the
/// position of the same entry in `K`'s arrays (`positions_in_rows[t]`: row `j = kt.indices[t]`
/// of `K` holds column `a` at that position), so that a product reading the rest of row `j`
/// from column `a` on needs no search. A counting transpose: `O(nnz + cols)`.
pub(crate) fn transpose_with_positions(k: &CsMat<f64>) -> (CsMat<f64>, Vec<usize>) {
    let (m, p) = k.shape();
    let (kp, ki, kd) = raw(k);
    let nnz = ki.len();
    let mut indptr = vec![0usize; p + 1];
    for &a in ki {
        indptr[a + 1] += 1;
    }
    for a in 0..p {
        indptr[a + 1] += indptr[a];
    }
    let mut next = indptr[..p].to_vec();
    let mut indices = vec![0usize; nnz];
    let mut data = vec![0.0f64; nnz];
    let mut positions_in_rows = vec![0usize; nnz];
    for j in 0..m {
        for s in kp[j]..kp[j + 1] {
            let t = next[ki[s]];
            next[ki[s]] += 1;
            indices[t] = j;
            data[t] = kd[s];
            positions_in_rows[t] = s;
        }
    }
    (CsMat::new((p, m), indptr, indices, data), positions_in_rows)
}

/// The full symmetric normal matrix `G = K^T K` as CSR (sorted indices, both triangles):
/// row `a` is `G[a, b] = sum_j K[j, a] K[j, b]`, summed over the samples `j` in ascending
/// order ([`csr_by_rows`]).
pub(crate) fn normal_matrix(k: &CsMat<f64>, kt: &CsMat<f64>) -> CsMat<f64> {
    let p = k.cols();
    let chunks = (rayon::current_num_threads() * 8).max(1);
    let (kp, ki, kd) = raw(k);
    let (tp, ti, td) = raw(kt);
    csr_by_rows((p, p), p.div_ceil(chunks).max(1), |a, row| {
        for t in tp[a]..tp[a + 1] {
            let (j, kja) = (ti[t], td[t]);
            for s in kp[j]..kp[j + 1] {
                row.add(ki[s], kja * kd[s]);
            }
        }
    })
}

/// One row of a sparse product at a time: `row[b] += v` for each entry added, summed in the
/// order added (a dense accumulator with a mark per column, so a row costs its entries, not
/// its width), then emitted in ascending column order. Every normal matrix assembled from
/// the rows of `K` (the global solve's `K^T K`, the adaptive image fit's Gram matrix and its
/// continuation) sums through this, so the same entries in the same order give the same bits.
pub(crate) struct RowAccumulator {
    sum: Vec<f64>,
    mark: Vec<usize>,
    touched: Vec<usize>,
    row: usize,
}

impl RowAccumulator {
    /// An accumulator for rows of `width` columns.
    pub(crate) fn new(width: usize) -> Self {
        Self {
            sum: vec![0.0; width],
            mark: vec![usize::MAX; width],
            touched: Vec::new(),
            row: usize::MAX,
        }
    }

    /// Starts row `row` (empty).
    fn start(&mut self, row: usize) {
        self.touched.clear();
        self.row = row;
    }

    /// Adds `v` to column `b` of the current row.
    #[inline]
    pub(crate) fn add(&mut self, b: usize, v: f64) {
        if self.mark[b] != self.row {
            self.mark[b] = self.row;
            self.sum[b] = 0.0;
            self.touched.push(b);
        }
        self.sum[b] += v;
    }

    /// Adds `scale * vals[t]` to column `cols[t]` for each `t` in order: a scaled slice of a
    /// sparse row (the same sums as [`RowAccumulator::add`] entry by entry).
    #[inline]
    pub(crate) fn add_scaled(&mut self, scale: f64, cols: &[usize], vals: &[f64]) {
        for (&b, &v) in cols.iter().zip(vals) {
            self.add(b, scale * v);
        }
    }

    /// Appends the current row's entries, by ascending column, to `indices` and `values`;
    /// returns their count.
    fn finish(&mut self, indices: &mut Vec<usize>, values: &mut Vec<f64>) -> usize {
        self.touched.sort_unstable();
        for &b in &self.touched {
            indices.push(b);
            values.push(self.sum[b]);
        }
        self.touched.len()
    }
}

/// The CSR matrix of `shape` whose row `a` holds what `row(a, accumulator)` adds, rows
/// computed in parallel tasks of `rows_per_task` (at least 1; the result does not depend on
/// it: each row is summed on its own).
pub(crate) fn csr_by_rows(
    shape: (usize, usize),
    rows_per_task: usize,
    row: impl Fn(usize, &mut RowAccumulator) + Sync,
) -> CsMat<f64> {
    let starts: Vec<usize> = (0..shape.0).step_by(rows_per_task.max(1)).collect();
    let parts: Vec<(Vec<usize>, Vec<usize>, Vec<f64>)> = starts
        .par_iter()
        .map(|&start| {
            let end = (start + rows_per_task.max(1)).min(shape.0);
            let mut acc = RowAccumulator::new(shape.1);
            let mut lens = Vec::with_capacity(end - start);
            let (mut idx, mut val) = (Vec::new(), Vec::new());
            for a in start..end {
                acc.start(a);
                row(a, &mut acc);
                lens.push(acc.finish(&mut idx, &mut val));
            }
            (lens, idx, val)
        })
        .collect();
    csr_from_row_parts(shape, parts)
}

/// A CSR matrix of `shape` from consecutive blocks of rows, each `(row lengths, column
/// indices, values)` in row order (the output of a row-parallel sparse product).
pub(crate) fn csr_from_row_parts(
    shape: (usize, usize),
    parts: Vec<(Vec<usize>, Vec<usize>, Vec<f64>)>,
) -> CsMat<f64> {
    let nnz: usize = parts.iter().map(|part| part.1.len()).sum();
    let mut indptr = Vec::with_capacity(shape.0 + 1);
    let mut indices = Vec::with_capacity(nnz);
    let mut data = Vec::with_capacity(nnz);
    indptr.push(0);
    for (lens, idx, val) in parts {
        for l in lens {
            let last = *indptr.last().expect("indptr starts with 0");
            indptr.push(last + l);
        }
        indices.extend_from_slice(&idx);
        data.extend_from_slice(&val);
    }
    CsMat::new(shape, indptr, indices, data)
}

/// `Y = A X` for CSR `A` (`r x c`) and row-major blocks `X` (`c x ch`), `Y` (`r x ch`).
pub(crate) fn spmm(a: &CsMat<f64>, x: &[f64], y: &mut [f64], ch: usize) {
    let (indptr, indices, data) = raw(a);
    y.par_chunks_mut(ch * 256)
        .enumerate()
        .for_each(|(block, yb)| {
            let first = block * 256;
            for (r, yr) in yb.chunks_mut(ch).enumerate() {
                let i = first + r;
                yr.iter_mut().for_each(|v| *v = 0.0);
                for t in indptr[i]..indptr[i + 1] {
                    let (c, v) = (indices[t], data[t]);
                    let xr = &x[c * ch..(c + 1) * ch];
                    for (yv, xv) in yr.iter_mut().zip(xr) {
                        *yv += v * xv;
                    }
                }
            }
        });
}

/// Column scaling `d_a = 1 / ||K_s[:, a]||` (1 for an empty column in Cholesky, where the
/// zero pivot is then detected; 0 in CGLS, which keeps that coefficient at 0).
pub(crate) fn column_scaling(
    normal_diag: impl Fn(usize) -> f64 + Sync,
    p: usize,
    empty: f64,
) -> Vec<f64> {
    (0..p)
        .into_par_iter()
        .map(|a| {
            let g = normal_diag(a);
            if g > 0.0 {
                1.0 / g.sqrt()
            } else {
                empty
            }
        })
        .collect()
}
