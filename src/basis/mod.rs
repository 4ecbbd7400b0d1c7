//! The CDV interval wavelet basis: Daubechies filters, the Cohen–Daubechies–Vial edge
//! construction, exact pointwise evaluation and the interval fast wavelet transform.
//!
//! On `[0, 1]`, `V_j` has `2^j` orthonormal scaling functions: `p` left edge functions
//! `phi^L_{j,k}(x) = 2^{j/2} phi^L_k(2^j x)`, the interior translates
//! `phi_{j,m}(x) = 2^{j/2} phi(2^j x - m)`, `m = p..2^j-p-1`, and `p` right edge functions;
//! `W_j` likewise with wavelets. The localized basis of the paper supplement (eq. 11) is
//! `Psi(n, N) = {phi_{n,k}} U {psi_{j,k} : n <= j <= N}`, of dimension `2^{N+1}`.
//! Haar (`p = 1`) needs no edge functions and is usable from level 0.

pub mod bank;
mod byte_tables;
pub mod cdv;
pub mod eval;
pub mod facts;
pub mod filters;
pub mod fwt;
mod index;
pub mod integral;
pub mod single_level;
pub mod tensor;

pub use bank::FilterBank;
pub use eval::{BasisValue, Evaluator};
pub use filters::{FilterFamily, MAX_VANISHING_MOMENTS};
pub use index::{cell_of, support_cells, FunctionId, FunctionKind, Side};
pub use single_level::SingleLevelEvaluator;

use std::sync::Arc;

pub use crate::domain::Domain;

use thiserror::Error;

/// Finest wavelet level the evaluator supports (positions are `f64`, levels beyond ~50 carry
/// no information).
pub const MAX_LEVEL: u32 = 60;

/// Errors of basis construction and evaluation: each names the value at fault and the fix.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum BasisError {
    /// `p` outside the supported range.
    #[error("p = {p} vanishing moments is not supported: choose p in 1..={max}")]
    UnsupportedOrder {
        /// Requested `p`.
        p: usize,
        /// Largest supported `p`.
        max: usize,
    },
    /// `coarse > fine`.
    #[error(
        "coarse level n = {coarse} is above the finest wavelet level N = {fine}: choose n <= N"
    )]
    CoarseAboveFine {
        /// Coarse level `n`.
        coarse: u32,
        /// Finest wavelet level `N`.
        fine: u32,
    },
    /// The coarse level is too small for `p` (edge blocks would overlap).
    #[error(
        "coarse level n = {coarse} is too small for p = {p}: the left and right edge functions \
         overlap below level {minimum}; choose n >= {minimum}"
    )]
    CoarseLevelTooSmall {
        /// Vanishing moments.
        p: usize,
        /// Requested coarse level.
        coarse: u32,
        /// `j_min(p)`.
        minimum: u32,
    },
    /// The fine level is beyond what `f64` positions resolve.
    #[error("fine level N = {fine} is too deep: choose N <= {max}")]
    FineLevelTooDeep {
        /// Requested level.
        fine: u32,
        /// Maximum level.
        max: u32,
    },
    /// A position outside the domain or not finite.
    #[error(
        "position {} is outside the domain [{}, {}] (or not finite): give positions within \
         the domain",
        crate::norms::show(*.x),
        crate::norms::show(*.a),
        crate::norms::show(*.b)
    )]
    PositionOutside {
        /// The position.
        x: f64,
        /// Left end.
        a: f64,
        /// Right end.
        b: f64,
    },
    /// A numerical step of the construction failed (an internal error).
    #[error("CDV construction failed at {step}: {detail}")]
    Construction {
        /// The step.
        step: &'static str,
        /// What went wrong.
        detail: String,
    },
}

/// `j_min(p) = ceil(log2(4p - 2))`: the coarsest level at which the left and right edge blocks
/// of `V_j` do not overlap (`0` for Haar, which has no edge functions).
pub fn minimum_level(p: usize) -> u32 {
    if p <= 1 {
        return 0;
    }
    // ceil(log2(t)) = bits of (t - 1); saturating, so an absurd p (which `CdvBasis::new`
    // refuses) gives a level instead of overflowing.
    let target = p.saturating_mul(4).saturating_sub(2);
    usize::BITS - (target - 1).leading_zeros()
}

/// A CDV basis `Psi(n, N)` on a domain `[a, b]` (mapped affinely to `[0, 1]`, values scaled by
/// `(b - a)^{-1/2}` so the basis is orthonormal on `[a, b]`).
#[derive(Clone, Debug)]
pub struct CdvBasis {
    bank: Arc<FilterBank>,
    coarse: u32,
    fine: u32,
    domain: Domain,
}

impl CdvBasis {
    /// Validates the parameters and builds (or reuses) the filter bank.
    pub fn new(
        p: usize,
        family: FilterFamily,
        coarse: u32,
        fine: u32,
        domain: Domain,
    ) -> Result<Self, BasisError> {
        let bank = FilterBank::shared(p, family)?;
        Self::with_bank(bank, coarse, fine, domain)
    }

    /// As [`CdvBasis::new`] with an existing filter bank.
    pub fn with_bank(
        bank: Arc<FilterBank>,
        coarse: u32,
        fine: u32,
        domain: Domain,
    ) -> Result<Self, BasisError> {
        let minimum = minimum_level(bank.p());
        if coarse < minimum {
            return Err(BasisError::CoarseLevelTooSmall {
                p: bank.p(),
                coarse,
                minimum,
            });
        }
        if coarse > fine {
            return Err(BasisError::CoarseAboveFine { coarse, fine });
        }
        if fine > MAX_LEVEL {
            return Err(BasisError::FineLevelTooDeep {
                fine,
                max: MAX_LEVEL,
            });
        }
        Ok(Self {
            bank,
            coarse,
            fine,
            domain,
        })
    }

    /// The filter bank.
    pub fn bank(&self) -> &Arc<FilterBank> {
        &self.bank
    }
    /// Vanishing moments `p`.
    pub fn p(&self) -> usize {
        self.bank.p()
    }
    /// Coarse scaling level `n`.
    pub fn coarse(&self) -> u32 {
        self.coarse
    }
    /// Finest wavelet level `N`.
    pub fn fine(&self) -> u32 {
        self.fine
    }
    /// The domain `[a, b]`.
    pub fn domain(&self) -> Domain {
        self.domain
    }
    /// `dim Psi(n, N) = 2^{N+1}`.
    pub fn dimension(&self) -> usize {
        1usize << (self.fine + 1)
    }
    /// Maps `x` in `[a, b]` to `t` in `[0, 1]`, or reports it outside (NaN included).
    pub fn to_unit(&self, x: f64) -> Result<f64, BasisError> {
        if !self.domain.contains(x) {
            return Err(BasisError::PositionOutside {
                x,
                a: self.domain.a(),
                b: self.domain.b(),
            });
        }
        Ok(self.domain.to_unit(x))
    }
    /// `(b - a)^{-1/2}`: the factor that keeps the basis orthonormal on `[a, b]`.
    pub fn amplitude(&self) -> f64 {
        1.0 / self.domain.length().sqrt()
    }
    /// An evaluator with its own scratch space (one per thread).
    pub fn evaluator(&self) -> Evaluator<'_> {
        Evaluator::new(self)
    }
    /// An evaluator of the scaling functions of `V_n` alone (`n` = the coarse level), one per
    /// thread: the single-scale rows of least squares and of evaluation after FWT synthesis.
    pub fn single_level_evaluator(&self) -> SingleLevelEvaluator<'_> {
        SingleLevelEvaluator::new(self)
    }
    /// Describes global function index `a` of `Psi(n, N)`.
    pub fn function(&self, a: usize) -> FunctionId {
        FunctionId::from_index(a, self.coarse, self.bank.edge_count())
    }
}

impl BasisError {
    /// The kind of this error ([`crate::error`]).
    pub fn kind(&self) -> crate::error::ErrorKind {
        match self {
            BasisError::UnsupportedOrder { .. }
            | BasisError::CoarseAboveFine { .. }
            | BasisError::CoarseLevelTooSmall { .. }
            | BasisError::FineLevelTooDeep { .. }
            | BasisError::PositionOutside { .. } => crate::error::ErrorKind::InvalidInput,
            BasisError::Construction { .. } => crate::error::ErrorKind::Internal,
        }
    }
}

crate::error::classified!(BasisError);
