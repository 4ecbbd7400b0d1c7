//! The localized basis `Psi(n, N) = {phi_{n,k}} U {psi_{j,k} : n <= j <= N}` (paper
//! supplement, eq. 11) on a domain `[a, b]`, and the levels it may take.

use std::sync::Arc;

use super::bank::FilterBank;
use super::error::BasisError;
use super::filters::FilterFamily;
use super::index::FunctionId;
use crate::domain::Domain;

/// Finest wavelet level the evaluator supports (positions are `f64`, levels beyond ~50 carry
/// no information).
pub const MAX_LEVEL: u32 = 60;

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
    /// Describes global function index `a` of `Psi(n, N)`.
    pub fn function(&self, a: usize) -> FunctionId {
        FunctionId::from_index(a, self.coarse, self.bank.edge_count())
    }
}
