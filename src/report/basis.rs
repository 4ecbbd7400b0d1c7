//! Reports on a basis alone: its measured identities ([`BasisReport`], see
//! [`crate::basis::facts`]) and every nonzero basis function at given positions
//! ([`BasisValues`]: `ψ_a(x)` for all `a` with `x` in the support of `ψ_a`).

use std::time::Instant;

use serde::Serialize;

use crate::basis::facts::BasisFacts;
use crate::basis::{minimum_level, BasisError, CdvBasis, FunctionKind, Side};

/// The measured facts of one basis.
#[derive(Clone, Debug, Serialize)]
pub struct BasisReport {
    /// Vanishing moments.
    pub p: usize,
    /// "db" or "sym".
    pub family: &'static str,
    /// Coarse level n.
    pub coarse: u32,
    /// Finest wavelet level N.
    pub fine: u32,
    /// `j_min(p)`.
    pub minimum_level: u32,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// `2^{N+1}`.
    pub dimension: usize,
    /// The measured identities.
    #[serde(flatten)]
    pub facts: BasisFacts,
    /// Seconds to build the filter bank (counted from `started`) and measure.
    pub time_s: f64,
}

/// Measures the facts of `basis` (polynomial reproduction at `points` random positions drawn
/// from `seed`); the time is counted from `started`, so that building the basis can be
/// included.
pub fn basis_report(basis: &CdvBasis, points: usize, seed: u64, started: Instant) -> BasisReport {
    let facts = BasisFacts::measure(basis, points, seed);
    BasisReport {
        p: basis.p(),
        family: basis.bank().family().short_name(),
        coarse: basis.coarse(),
        fine: basis.fine(),
        minimum_level: minimum_level(basis.p()),
        domain: [basis.domain().a(), basis.domain().b()],
        dimension: basis.dimension(),
        facts,
        time_s: started.elapsed().as_secs_f64(),
    }
}

/// One basis function's value at a position.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BasisValue {
    /// "scaling" or "wavelet".
    pub kind: FunctionKind,
    /// "left", "interior" or "right".
    pub side: Side,
    /// Level j.
    pub level: u32,
    /// Index within the level (`0..2^j`).
    pub index: usize,
    /// Global index in `Psi(n, N)`.
    pub global: usize,
    /// The value.
    pub value: f64,
}

/// All nonzero functions at one position.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BasisValuesAt {
    /// The position.
    pub x: f64,
    /// The nonzero functions, ascending global index.
    pub functions: Vec<BasisValue>,
}

/// Every nonzero basis function at each of a list of positions.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BasisValues {
    /// Vanishing moments.
    pub p: usize,
    /// "db" or "sym".
    pub family: &'static str,
    /// Coarse level n.
    pub coarse: u32,
    /// Finest wavelet level N.
    pub fine: u32,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// One entry per position, in the order given.
    pub points: Vec<BasisValuesAt>,
}

/// Every nonzero function of `basis` at each of `xs`; every position is validated before any
/// is evaluated.
pub fn basis_values(basis: &CdvBasis, xs: &[f64]) -> Result<BasisValues, BasisError> {
    for &x in xs {
        basis.to_unit(x)?;
    }
    let mut ev = basis.evaluator();
    let mut points = Vec::with_capacity(xs.len());
    for &x in xs {
        let functions = ev
            .eval(x)?
            .iter()
            .map(|v| {
                let id = basis.function(v.index);
                BasisValue {
                    kind: id.kind,
                    side: id.side,
                    level: id.level,
                    index: id.index,
                    global: v.index,
                    value: v.value,
                }
            })
            .collect();
        points.push(BasisValuesAt { x, functions });
    }
    Ok(BasisValues {
        p: basis.p(),
        family: basis.bank().family().short_name(),
        coarse: basis.coarse(),
        fine: basis.fine(),
        domain: [basis.domain().a(), basis.domain().b()],
        points,
    })
}
