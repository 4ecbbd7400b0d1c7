//! Building `K` (CSR, `m x P`) in parallel from the one-pass evaluation.

use rayon::prelude::*;
use sprs::CsMat;
use thiserror::Error;

use super::ActiveSet;
use crate::basis::BasisValue;
use crate::domain::Domain;

/// Samples per parallel work item.
const CHUNK: usize = 4096;

/// Errors of kernel matrix construction.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum KernelError {
    /// A sample position is outside the domain or not finite.
    #[error(
        "sample {row} (1-based) at x = {} is outside the domain [{}, {}] or not finite: \
         remove it or widen the domain",
        crate::norms::show(*.x),
        crate::norms::show(*.a),
        crate::norms::show(*.b)
    )]
    PositionOutside {
        /// 1-based sample number.
        row: usize,
        /// Its position.
        x: f64,
        /// Left end.
        a: f64,
        /// Right end.
        b: f64,
    },
    /// No samples.
    #[error("no samples: give at least one sample position")]
    Empty,
}

/// Every position lies in the domain (and is finite), or the first that does not, 1-based.
pub fn check_positions(domain: Domain, positions: &[f64]) -> Result<(), KernelError> {
    match positions
        .iter()
        .enumerate()
        .find(|(_, x)| !domain.contains(**x))
    {
        Some((i, &x)) => Err(KernelError::PositionOutside {
            row: i + 1,
            x,
            a: domain.a(),
            b: domain.b(),
        }),
        None => Ok(()),
    }
}

/// `K[i, c] = Psi_{active(c)}(x_i)`: one row per sample, the active functions that are
/// (structurally) nonzero at it, in ascending column order.
pub fn kernel_matrix(active: &ActiveSet, positions: &[f64]) -> Result<CsMat<f64>, KernelError> {
    if positions.is_empty() {
        return Err(KernelError::Empty);
    }
    let basis = active.basis();
    let domain = basis.domain();
    check_positions(domain, positions)?;
    let blocks: Vec<(Vec<usize>, Vec<usize>, Vec<f64>)> = positions
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut ev = basis.evaluator();
            let mut out: Vec<BasisValue> = Vec::with_capacity(256);
            let mut counts = Vec::with_capacity(chunk.len());
            let mut indices = Vec::with_capacity(chunk.len() * 40);
            let mut data = Vec::with_capacity(chunk.len() * 40);
            for &x in chunk {
                ev.eval_unit_into(domain.to_unit(x), &mut out);
                let before = indices.len();
                for v in &out {
                    if let Some(c) = active.column(v.index) {
                        indices.push(c);
                        data.push(v.value);
                    }
                }
                counts.push(indices.len() - before);
            }
            (counts, indices, data)
        })
        .collect();
    let nnz: usize = blocks.iter().map(|b| b.1.len()).sum();
    let mut indptr = Vec::with_capacity(positions.len() + 1);
    let mut indices = Vec::with_capacity(nnz);
    let mut data = Vec::with_capacity(nnz);
    indptr.push(0);
    for (counts, idx, val) in blocks {
        for c in counts {
            indptr.push(indptr.last().copied().unwrap_or(0) + c);
        }
        indices.extend(idx);
        data.extend(val);
    }
    Ok(CsMat::new(
        (positions.len(), active.len()),
        indptr,
        indices,
        data,
    ))
}
