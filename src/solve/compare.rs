//! Element-wise comparison `E = A - B` of an approximation `A` with a reference `B` (both
//! `P x m`, or vectors): `max |E_ij|`, `sqrt(mean E_ij^2)` and `||E||_F / ||B||_F`.

use faer::MatRef;
use serde::Serialize;
use sprs::CsMat;

use super::SolveError;

/// Error figures of `A` against the reference `B`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Comparison {
    /// `max_ij |A_ij - B_ij|`.
    pub max_abs: f64,
    /// `sqrt(sum (A_ij - B_ij)^2 / (rows * cols))`.
    pub rms: f64,
    /// `||A - B||_F / ||B||_F` (`||A - B||_F` itself when `B = 0`).
    pub rel_frobenius: f64,
    /// Position `(row, col)` of the largest difference.
    pub argmax: (usize, usize),
    /// Rows compared.
    pub rows: usize,
    /// Columns compared.
    pub cols: usize,
}

/// The comparison from the RMS of the differences and of the reference (both by
/// [`crate::norms::rms`], without overflow): `||A - B||_F / ||B||_F` is their ratio, and
/// `||A - B||_F = sqrt(rows cols) rms` when `B = 0`.
fn finish(
    rms: f64,
    ref_rms: f64,
    max_abs: f64,
    argmax: (usize, usize),
    rows: usize,
    cols: usize,
) -> Comparison {
    let n = (rows * cols).max(1) as f64;
    Comparison {
        max_abs,
        rms,
        rel_frobenius: if ref_rms > 0.0 {
            rms / ref_rms
        } else {
            rms * n.sqrt()
        },
        argmax,
        rows,
        cols,
    }
}

fn check_shape(a: (usize, usize), b: (usize, usize)) -> Result<(), SolveError> {
    if a.0 != b.0 {
        return Err(SolveError::DimensionMismatch {
            what: "rows of the compared matrices",
            expected: b.0,
            found: a.0,
        });
    }
    if a.1 != b.1 {
        return Err(SolveError::DimensionMismatch {
            what: "columns of the compared matrices",
            expected: b.1,
            found: a.1,
        });
    }
    Ok(())
}

/// Compares two dense matrices (`a` approximation, `b` reference).
pub fn compare_dense(a: MatRef<'_, f64>, b: MatRef<'_, f64>) -> Result<Comparison, SolveError> {
    check_shape(a.shape(), b.shape())?;
    let (mut max, mut arg) = (0.0f64, (0, 0));
    for j in 0..a.ncols() {
        for i in 0..a.nrows() {
            let e = (a[(i, j)] - b[(i, j)]).abs();
            if e > max || e.is_nan() {
                max = e;
                arg = (i, j);
            }
        }
    }
    let approx: Vec<f64> = column_major(a);
    let reference: Vec<f64> = column_major(b);
    let rms = crate::norms::rms_difference(&approx, &reference);
    let ref_rms = crate::norms::rms(reference);
    Ok(finish(rms, ref_rms, max, arg, a.nrows(), a.ncols()))
}

/// The entries of `m` in column-major order.
fn column_major(m: MatRef<'_, f64>) -> Vec<f64> {
    (0..m.ncols())
        .flat_map(|j| (0..m.nrows()).map(move |i| m[(i, j)]))
        .collect()
}

/// Compares a sparse approximation (CSR or CSC) with a dense reference; entries not
/// stored in `a` count as zeros.
pub fn compare_sparse_dense(a: &CsMat<f64>, b: MatRef<'_, f64>) -> Result<Comparison, SolveError> {
    check_shape(a.shape(), b.shape())?;
    let mut dense = faer::Mat::<f64>::zeros(a.rows(), a.cols());
    for (v, (i, j)) in a.iter() {
        dense[(i, j)] += *v;
    }
    compare_dense(dense.as_ref(), b)
}

/// Compares two vectors (`a` approximation, `b` reference) as `n x 1` matrices.
pub fn compare_vectors(a: &[f64], b: &[f64]) -> Result<Comparison, SolveError> {
    compare_dense(
        MatRef::from_column_major_slice(a, a.len(), 1),
        MatRef::from_column_major_slice(b, b.len(), 1),
    )
}
