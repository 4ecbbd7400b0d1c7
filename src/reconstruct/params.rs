//! The parameters of a fit: the levels, the method of `c = K^+ f`, the filters.

use serde::Serialize;

use super::single_scale::SingleScaleSolver;
use crate::basis::{BasisError, CdvBasis, FilterFamily};
use crate::kernel::LevelParams;
use crate::sampling::Domain;
use crate::solve::{GlobalLsParams, LocalInversionParams};

/// How the levels are chosen.
#[derive(Clone, Copy, Debug, Serialize)]
pub enum Levels {
    /// From the number of samples ([`LevelChoice::auto`](crate::kernel::LevelChoice::auto)).
    Auto(LevelParams),
    /// Given explicitly.
    Fixed {
        /// Coarse scaling level `n`.
        coarse: u32,
        /// Finest wavelet level `N`.
        fine: u32,
    },
}

/// How `c = K^+ f` is computed.
#[derive(Clone, Copy, Debug, Serialize)]
pub enum Method {
    /// Global least squares through the single-scale basis `V_{N+1}` (banded QR or banded
    /// normal equations, then the FWT): exact, `O(m p^2 + P p^2)`, the fastest path for
    /// uniform levels; `ridge` is the relative diagonal shift of the equilibrated normal matrix.
    SingleScale {
        /// Relative ridge (e.g. 1e-13).
        ridge: f64,
        /// Factorization: QR (accuracy of `cond(K)`, default) or normal equations
        /// (`cond(K)^2`, cheaper per sample).
        solver: SingleScaleSolver,
    },
    /// Local inversion (docs/design.md §4): fast, local, approximate.
    Local(LocalInversionParams),
    /// Global sparse least squares: exact up to the solver tolerance, one large factorization.
    Global(GlobalLsParams),
    /// Dense SVD pseudo-inverse with a relative cut-off: the truth, small problems only.
    Dense {
        /// Relative singular value cut-off.
        cutoff: f64,
    },
}

/// Parameters of a fit.
///
/// The default is `p = 3`, CDV's filter family, automatic levels and the single-scale
/// solve. Change one field and keep the rest:
///
/// ```
/// use rkwave::basis::FilterFamily;
/// use rkwave::reconstruct::{FitParams, Levels, Method};
/// use rkwave::solve::LocalInversionParams;
///
/// let params = FitParams { p: 6, ..FitParams::default() };
/// assert_eq!(params.family(), FilterFamily::LeastAsymmetric); // sym6, CDV's choice
///
/// let fixed = FitParams {
///     levels: Levels::Fixed { coarse: 4, fine: 7 },
///     method: Method::Local(LocalInversionParams::default()),
///     ..FitParams::default()
/// };
/// assert_eq!(fixed.family(), FilterFamily::Extremal); // db3
/// ```
#[derive(Clone, Copy, Debug)]
pub struct FitParams {
    /// Vanishing moments `p`: higher reproduces smoother signals with fewer samples, costs
    /// `O(p^2)` per sample.
    pub p: usize,
    /// Interior filter family; `None` is CDV's choice for `p`
    /// ([`FilterFamily::cdv_default`]: extremal phase for `p <= 3`, least asymmetric above).
    pub family: Option<FilterFamily>,
    /// Levels.
    pub levels: Levels,
    /// Solver.
    pub method: Method,
}

impl FitParams {
    /// The interior filter family: the given one, or CDV's choice for `p`.
    pub fn family(&self) -> FilterFamily {
        self.family
            .unwrap_or_else(|| FilterFamily::cdv_default(self.p))
    }

    /// The CDV basis of these parameters with scaling level `coarse` and wavelets on
    /// `coarse..=fine` on `domain` ([`CdvBasis::new`], with [`FitParams::family`]).
    pub fn basis(&self, coarse: u32, fine: u32, domain: Domain) -> Result<CdvBasis, BasisError> {
        CdvBasis::new(self.p, self.family(), coarse, fine, domain)
    }
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            p: 3,
            family: None,
            levels: Levels::Auto(LevelParams::default()),
            method: Method::SingleScale {
                ridge: 0.0,
                solver: SingleScaleSolver::default(),
            },
        }
    }
}
