//! Building `K` (CSR, `m x P`) in parallel from the one-pass evaluation.

use sprs::CsMat;
use thiserror::Error;

use super::rows::{assemble, evaluate_rows};
use super::ActiveSet;
use crate::domain::Domain;

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
/// (structurally) nonzero at it, in ascending column order. The evaluation at `x_i` stops at
/// the active set's local depth there ([`ActiveSet::local_depth_unit`]).
pub fn kernel_matrix(active: &ActiveSet, positions: &[f64]) -> Result<CsMat<f64>, KernelError> {
    if positions.is_empty() {
        return Err(KernelError::Empty);
    }
    let basis = active.basis();
    let domain = basis.domain();
    check_positions(domain, positions)?;
    let ts: Vec<f64> = positions.iter().map(|&x| domain.to_unit(x)).collect();
    // Levels finer than the active set's local depth at a position contribute nothing there.
    let blocks = evaluate_rows(
        basis,
        &ts,
        |t| active.local_depth_unit(t),
        |a| active.column(a),
    );
    Ok(assemble((positions.len(), active.len()), blocks))
}

impl KernelError {
    /// The kind of this error ([`crate::error`]): always `ErrorKind::InvalidInput`.
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            KernelError::PositionOutside { .. } | KernelError::Empty => {
                crate::error::ErrorKind::InvalidInput
            }
        }
    }
}

crate::error::classified!(KernelError);
