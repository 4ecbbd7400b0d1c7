//! Automatic choice of the levels `n` and `N` from the number of samples.
//!
//! `dim Psi(n, N) = 2^{N+1}`: for `m` samples and an oversampling target `rho`, `N` is the
//! level with `2^{N+1}` nearest to `m / rho` (in log scale) from below or above, whichever
//! keeps `m / 2^{N+1} >= rho` when possible. A coarse scaling function covers a fraction
//! `(2p - 1) 2^{-n}` of the domain, so about `m (2p - 1) 2^{-n}` samples: `n` is the smallest
//! level (at least `j_min(p)`) that keeps this below `coarse_samples`, which bounds the local
//! submatrices and keeps large problems local.

use serde::Serialize;

use crate::basis::{minimum_level, MAX_LEVEL};

/// Knobs of the automatic level choice.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct LevelParams {
    /// Oversampling target `rho = m / P`; larger is more stable (fewer locally
    /// undersampled functions) but resolves less detail.
    pub rho: f64,
    /// Samples a coarse scaling function may cover; smaller makes local inversion cheaper and
    /// more local, larger keeps coarser (smoother) scaling functions.
    pub coarse_samples: f64,
}

impl Default for LevelParams {
    fn default() -> Self {
        Self {
            rho: 2.0,
            coarse_samples: 256.0,
        }
    }
}

/// A choice of levels and why.
///
/// ```
/// use rkwave::kernel::{LevelChoice, LevelParams};
///
/// // 10_000 samples, p = 3: the finest level N with 2^{N+1} <= m / rho.
/// let l = LevelChoice::auto(10_000, 3, LevelParams::default());
/// assert!(l.coarse <= l.fine);
/// assert!(l.oversampling >= LevelParams::default().rho);
/// ```
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct LevelChoice {
    /// Coarse scaling level `n`.
    pub coarse: u32,
    /// Finest wavelet level `N`.
    pub fine: u32,
    /// Achieved oversampling `m / 2^{N+1}`.
    pub oversampling: f64,
}

impl LevelChoice {
    /// The finest level one lower: `N - 1`, with the oversampling doubled (half the
    /// functions for the same samples). The caller keeps `N > n`.
    pub fn lower_finest(&mut self) {
        self.fine -= 1;
        self.oversampling *= 2.0;
    }

    /// Levels for `m` samples with `p` vanishing moments.
    pub fn auto(m: usize, p: usize, params: LevelParams) -> Self {
        let jmin = minimum_level(p);
        let target = (m as f64 / params.rho.max(1e-12)).max(1.0);
        // 2^{N+1} <= target: the largest such N (at least j_min).
        let mut fine = jmin;
        while fine < MAX_LEVEL && (1u64 << (fine + 2)) as f64 <= target {
            fine += 1;
        }
        let mut coarse = jmin;
        while coarse < fine
            && m as f64 * (2 * p - 1) as f64 / (1u64 << coarse) as f64 > params.coarse_samples
        {
            coarse += 1;
        }
        Self {
            coarse,
            fine,
            oversampling: m as f64 / (1u64 << (fine + 1)) as f64,
        }
    }
}
