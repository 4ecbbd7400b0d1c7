//! Refinement indicators and Dörfler marking.
//!
//! *Coefficients.* For an active wavelet `psi_{j,k}` with a missing child, let
//! `m = max |c_{j,k'}|, |k' - k| <= 1` (the neighbours guard against a coefficient that is small
//! by accident of position) and `r = m / max |c_{j-1,k''}|, |k'' - floor(k/2)| <= 1`, clamped
//! to `[2^{-(p+1/2)}, 0.9]` (from the decay of a smooth function's coefficients to that of
//! an unresolved oscillation; `2^{-1/2}` for a jump, and at `j = n`). The missing child is
//! predicted at `r m` and, with its descendants decaying by `r` per level, its subtree at
//! `eta = r m / sqrt(1 - r^2)`. `sum eta^2` estimates the squared `L2` error
//! (orthonormal basis: `sum c^2 = int f^2`).
//!
//! *Residual.* Probe points in each leaf `C`: `eta_C^2 = |C| mean (f - f~)^2`, a Monte Carlo
//! estimate of `int_C (f - f~)^2`; marking `C` adds the wavelets one level deeper whose support
//! covers it.

use crate::adaptive::marking::dorfler;
use crate::adaptive::tree::interval::{support_cells, Leaf, WaveletTree};
use crate::reconstruct::Fit;

/// Cap of the decay ratio: beyond it the estimate `1 / sqrt(1 - r^2)` would explode.
const MAX_RATIO: f64 = 0.9;

/// One markable refinement: the wavelets it adds and its indicator.
#[derive(Clone, Debug)]
pub(crate) struct Unit {
    pub eta: f64,
    pub wavelets: Vec<usize>,
}

/// The indicator of one fit.
#[derive(Clone, Debug, Default)]
pub(crate) struct Indication {
    /// Markable units (within the depth limit), largest `eta` first.
    pub units: Vec<Unit>,
    /// Estimated squared error, `int (f - f~)^2` over the domain.
    pub total_sq: f64,
    /// The part of it the depth limit lets the refiner reduce.
    pub markable_sq: f64,
    /// Largest indicator.
    pub max: f64,
}

impl Indication {
    fn push(&mut self, eta: f64, wavelets: Vec<usize>, markable: bool) {
        self.total_sq += eta * eta;
        self.max = self.max.max(eta);
        if markable {
            self.markable_sq += eta * eta;
            self.units.push(Unit { eta, wavelets });
        }
    }

    fn sort(&mut self) {
        self.units.sort_by(|a, b| {
            b.eta
                .total_cmp(&a.eta)
                .then_with(|| a.wavelets.cmp(&b.wavelets))
        });
    }

    /// The union of two indications (sorted), the larger of the two error estimates.
    pub fn merge(mut self, other: Indication) -> Indication {
        if other.total_sq > self.total_sq {
            self.total_sq = other.total_sq;
        }
        self.markable_sq = self.markable_sq.max(other.markable_sq);
        self.max = self.max.max(other.max);
        self.units.extend(other.units);
        self.sort();
        self
    }

    /// Dörfler marking ([`dorfler`]): the fewest leading units holding `theta` of the
    /// markable squared indicator (units with `eta = 0` are never marked).
    pub fn dorfler(&self, theta: f64) -> usize {
        let eta: Vec<f64> = self.units.iter().map(|u| u.eta).collect();
        dorfler(&eta, theta)
    }
}

/// Predicted missing coefficients from the decay across levels.
pub(crate) fn coefficient_indication(tree: &WaveletTree, fit: &Fit) -> Indication {
    let (active, coefficients) = (&fit.active, &fit.coefficients[0]);
    let p = tree.p();
    let n = tree.coarse();
    let min_ratio = (-(p as f64 + 0.5)).exp2();
    let jump_ratio = std::f64::consts::FRAC_1_SQRT_2;
    let magnitude = |level: u32, k: usize| -> f64 {
        let size = 1usize << level;
        let lo = k.saturating_sub(1);
        let hi = (k + 1).min(size - 1);
        (lo..=hi)
            .filter_map(|kk| active.column(size + kk).map(|c| coefficients[c].abs()))
            .fold(0.0, f64::max)
    };
    let mut out = Indication::default();
    for a in tree.wavelets() {
        let id = tree.function(a);
        let (j, k) = (id.level, id.index);
        let base = 1usize << (j + 1);
        let missing: Vec<usize> = [base + 2 * k, base + 2 * k + 1]
            .into_iter()
            .filter(|&c| !tree.contains(c))
            .collect();
        if missing.is_empty() {
            continue;
        }
        let m = magnitude(j, k);
        let r = if j > n {
            let coarse = magnitude(j - 1, k / 2);
            if coarse > 0.0 {
                (m / coarse).clamp(min_ratio, MAX_RATIO)
            } else {
                MAX_RATIO
            }
        } else {
            jump_ratio
        };
        let eta = r * m / (1.0 - r * r).sqrt();
        let markable = j < tree.max_level();
        for c in missing {
            out.push(eta, vec![c], markable);
        }
    }
    out.sort();
    out
}

/// Residuals `(leaf index, f - f~)` at probe points, gathered per leaf.
pub(crate) fn residual_indication(
    tree: &WaveletTree,
    leaves: &[Leaf],
    residuals: &[(usize, f64)],
    domain_length: f64,
) -> Indication {
    let mut sum = vec![0.0f64; leaves.len()];
    let mut count = vec![0usize; leaves.len()];
    for &(i, r) in residuals {
        sum[i] += r * r;
        count[i] += 1;
    }
    let p = tree.p();
    let mut out = Indication::default();
    for (i, leaf) in leaves.iter().enumerate() {
        if count[i] == 0 {
            continue;
        }
        let width = (-(leaf.level as f64)).exp2() * domain_length;
        let eta = (width * sum[i] / count[i] as f64).sqrt();
        let level = leaf.level;
        let markable = level <= tree.max_level();
        let wavelets = if markable {
            covering(p, level, leaf.cell)
        } else {
            Vec::new()
        };
        out.push(eta, wavelets, markable);
    }
    out.sort();
    out
}

/// Global indices of the level-`level` wavelets whose support covers cell `cell` of that level.
fn covering(p: usize, level: u32, cell: u64) -> Vec<usize> {
    let size = 1u64 << level;
    let reach = 2 * p as u64;
    let lo = cell.saturating_sub(reach);
    let hi = (cell + reach).min(size - 1);
    (lo..=hi)
        .filter(|&k| {
            let (a, b) = support_cells(p, level, k as usize);
            a <= cell && cell <= b
        })
        .map(|k| (size + k) as usize)
        .collect()
}
