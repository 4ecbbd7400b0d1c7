//! The job of the lab's basis commands (`basis`, the demo's first table): a basis's measured
//! facts ([`crate::report::basis`]), checked against the memory limit before they are
//! measured.
//!
//! The facts multiply the sparse synthesis matrices of all `P = 2^{N+1}` functions: about
//! `256 (N - n + 2) 2p` bytes per function at their peak, and `8 G (1 + 1)` bytes for the
//! `G` positions of the polynomial check ([`crate::resources::grid_bytes`]).

use std::time::Instant;

use crate::basis::{minimum_level, BasisError, CdvBasis, Domain, FilterFamily};
use crate::error::{Fix, Param};
use crate::report::basis::{basis_report, BasisReport};
use crate::resources::{check_advised, dimension, grid_bytes, Advice, ResourceError};

/// Why the facts of a basis were not measured.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum BasisFactsError {
    /// The basis was refused (its `p`, family or levels).
    #[error(transparent)]
    Basis(#[from] BasisError),
    /// The facts would need more memory than the limit.
    #[error(transparent)]
    Resources(#[from] ResourceError),
}

impl BasisFactsError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            BasisFactsError::Basis(e) => e.kind(),
            BasisFactsError::Resources(e) => e.kind(),
        }
    }
}

crate::error::classified!(BasisFactsError);

/// Bytes the facts of `basis` hold at their peak with `points` positions (module docs).
pub fn facts_bytes(basis: &CdvBasis, points: usize) -> f64 {
    let (n, fine) = (basis.coarse(), basis.fine());
    256.0 * dimension(fine) * (fine.saturating_sub(n) as f64 + 2.0) * (2 * basis.p()) as f64
        + grid_bytes(points, 1)
}

/// The facts of `basis` ([`basis_report`]: polynomial reproduction at `points` positions
/// drawn from `seed`, the time counted from `started`), refused above the memory limit
/// before they are measured.
pub fn basis_facts(
    basis: &CdvBasis,
    points: usize,
    seed: u64,
    started: Instant,
) -> Result<BasisReport, ResourceError> {
    let (n, fine) = (basis.coarse(), basis.fine());
    check_advised(
        || format!("the basis facts of levels {n}..{fine} (P = 2^{})", fine + 1),
        facts_bytes(basis, points),
        || {
            Advice::Fixes(
                "lower {} (evaluating the basis alone works up to level 60)",
                vec![Fix::Set(Param::Fine)],
            )
        },
    )?;
    Ok(basis_report(basis, points, seed, started))
}

/// The facts of the default basis of `p` vanishing moments up to level `fine`: the default
/// family of `p` ([`FilterFamily::cdv_default`]) from the coarsest orthonormal level
/// `j_min(p)` ([`minimum_level`]) on `[0, 1]`; the time includes building the basis.
pub fn default_basis_facts(
    p: usize,
    fine: u32,
    points: usize,
    seed: u64,
) -> Result<BasisReport, BasisFactsError> {
    let started = Instant::now();
    let basis = CdvBasis::new(
        p,
        FilterFamily::cdv_default(p),
        minimum_level(p),
        fine,
        Domain::UNIT,
    )?;
    Ok(basis_facts(&basis, points, seed, started)?)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ErrorKind;

    /// The default basis starts at `j_min(p)`; a fine level whose facts need more than any
    /// limit (`P = 2^61` functions, about `2^78` bytes) is refused as a resource limit,
    /// naming the fine level and no flag; `p = 0` is refused as the basis's input.
    #[test]
    fn default_facts_and_refusals() {
        let r = default_basis_facts(2, 6, 100, 1).unwrap();
        assert_eq!(r.coarse, minimum_level(2));
        assert!(r.facts.orthonormality_error < 1e-10, "{r:?}");
        let e = default_basis_facts(2, 60, 100, 1).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::ResourceLimit, "{e}");
        let text = e.to_string();
        assert!(
            text.contains("fine level N") && !text.contains("--"),
            "{text}"
        );
        assert_eq!(
            default_basis_facts(0, 6, 100, 1).unwrap_err().kind(),
            ErrorKind::InvalidInput
        );
    }
}
