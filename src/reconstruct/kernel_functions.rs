//! Reproducing kernels `k_i(x) = sum_a Psi_a(lambda_i) Psi_a(x)` and dual kernels
//! `k~_i(x) = sum_a (K^+)_{a,i} Psi_a(x)` (docs/design.md §3), evaluated at positions.

use sprs::CsMat;

use crate::basis::{BasisError, BasisValue};
use crate::kernel::ActiveSet;

fn combine(
    active: &ActiveSet,
    weights: &[(usize, f64)],
    xs: &[f64],
) -> Result<Vec<f64>, BasisError> {
    let basis = active.basis();
    let mut ev = basis.evaluator();
    let mut out: Vec<BasisValue> = Vec::new();
    let mut dense = vec![0.0; active.len()];
    for &(c, w) in weights {
        dense[c] = w;
    }
    xs.iter()
        .map(|&x| {
            ev.eval_into(x, &mut out)?;
            Ok(out
                .iter()
                .filter_map(|v| active.column(v.index).map(|c| dense[c] * v.value))
                .sum())
        })
        .collect()
}

/// `k_i(x)` for sample `i` (row `i` of `K`) at `xs`.
pub fn reproducing_kernel(
    active: &ActiveSet,
    k: &CsMat<f64>,
    i: usize,
    xs: &[f64],
) -> Result<Vec<f64>, BasisError> {
    let row: Vec<(usize, f64)> = k
        .outer_view(i)
        .map(|r| r.iter().map(|(c, &v)| (c, v)).collect())
        .unwrap_or_default();
    combine(active, &row, xs)
}

/// `k~_i(x)` from column `i` of an approximate or exact pseudo-inverse given as its entries.
pub fn dual_kernel(
    active: &ActiveSet,
    column: &[(usize, f64)],
    xs: &[f64],
) -> Result<Vec<f64>, BasisError> {
    combine(active, column, xs)
}
