//! The data of the basis and kernel figures, as plain curves (drawn by `plot::figures`).
//!
//! - [`basis_functions`]: the scaling functions `φ_{n,k}` and wavelets `ψ_{n,k}` of the coarse
//!   level `n` (the edge functions, at most four per side, and one interior translate) on a
//!   grid of 2401 points.
//! - [`kernels`]: for a few samples `λ_i` near the left edge, in the interior and near the
//!   right edge, the dual kernels `k~_i(x) = sum_a (K^+)_{a i} ψ_a(x)` from the dense
//!   pseudo-inverse `K^+` and the reproducing kernels `k_i(x) = sum_a K_{i a} ψ_a(x)` (the
//!   paper's figure of dual kernels).

use serde::Serialize;

use crate::basis::{BasisError, CdvBasis, FunctionKind, Side};
use crate::kernel::{kernel_matrix, ActiveSet};
use crate::reconstruct::{dual_kernel, reproducing_kernel, ReconstructError};
use crate::solve::dense_pinv;

/// One labelled curve `(x, y)`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Curve {
    /// Legend label.
    pub label: String,
    /// Points in increasing `x`.
    pub points: Vec<(f64, f64)>,
}

/// Scaling functions and wavelets of one level.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BasisFunctionsData {
    /// Vanishing moments.
    pub p: usize,
    /// "db" or "sym".
    pub family: &'static str,
    /// The level `n` drawn.
    pub level: u32,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// `φ_{n,k}` for the chosen `k`.
    pub scaling: Vec<Curve>,
    /// `ψ_{n,k}` for the same `k`.
    pub wavelets: Vec<Curve>,
}

/// Points of the basis function curves (plus one).
const BASIS_POINTS: usize = 2400;

/// Which translates of one level to draw: the edge functions (at most four per side) and one
/// interior translate in the middle.
fn chosen(basis: &CdvBasis, level: u32) -> Vec<usize> {
    let p = basis.p();
    let e = basis.bank().edge_count();
    let size = 1usize << level;
    let edges: Vec<usize> = if p <= 4 {
        (0..e).collect()
    } else {
        vec![0, 1, 2, p - 1]
    };
    let mut out: Vec<usize> = edges.clone();
    out.push(size / 2);
    out.extend(edges.iter().map(|k| size - 1 - k));
    out.sort_unstable();
    out.dedup();
    out
}

/// Legend label of a basis function: `φ left 0`, `ψ interior m=8`, `φ right 1`, ...
fn label(basis: &CdvBasis, global: usize) -> String {
    let id = basis.function(global);
    let symbol = match id.kind {
        FunctionKind::Scaling => "φ",
        FunctionKind::Wavelet => "ψ",
    };
    let size = 1usize << id.level;
    match id.side {
        Side::Left => format!("{symbol} left {}", id.index),
        Side::Right => format!("{symbol} right {}", size - 1 - id.index),
        Side::Interior => format!("{symbol} interior m={}", id.index),
    }
}

/// The scaling functions and wavelets of the coarse level of `basis`.
pub fn basis_functions(basis: &CdvBasis) -> Result<BasisFunctionsData, BasisError> {
    let n = basis.coarse();
    let single = CdvBasis::with_bank(basis.bank().clone(), n, n, basis.domain())?;
    let size = 1usize << n;
    let scaling = chosen(&single, n);
    let wavelets: Vec<usize> = scaling.iter().map(|k| size + k).collect();
    let domain = basis.domain();
    let mut curves: Vec<Curve> = scaling
        .iter()
        .chain(&wavelets)
        .map(|&a| Curve {
            label: label(&single, a),
            points: Vec::with_capacity(BASIS_POINTS + 1),
        })
        .collect();
    let mut ev = single.evaluator();
    let mut out = Vec::new();
    for i in 0..=BASIS_POINTS {
        let x = domain.from_unit(i as f64 / BASIS_POINTS as f64);
        ev.eval_into(x, &mut out)?;
        for (curve, &a) in curves.iter_mut().zip(scaling.iter().chain(&wavelets)) {
            let v = out.iter().find(|v| v.index == a).map_or(0.0, |v| v.value);
            curve.points.push((x, v));
        }
    }
    let wavelet_curves = curves.split_off(scaling.len());
    Ok(BasisFunctionsData {
        p: basis.p(),
        family: basis.bank().family().short_name(),
        level: n,
        domain: [domain.a(), domain.b()],
        scaling: curves,
        wavelets: wavelet_curves,
    })
}

/// Dual and reproducing kernels of a few samples.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct KernelsData {
    /// Vanishing moments.
    pub p: usize,
    /// Coarse level `n`.
    pub coarse: u32,
    /// Finest level `N`.
    pub fine: u32,
    /// Samples `m`.
    pub samples: usize,
    /// `[a, b]`.
    pub domain: [f64; 2],
    /// The samples drawn (indices into the positions).
    pub picks: Vec<usize>,
    /// `k~_i` of each pick.
    pub dual: Vec<Curve>,
    /// `k_i` of each pick.
    pub reproducing: Vec<Curve>,
}

/// Relative singular value cut-off of the dense pseudo-inverse of [`kernels`].
pub const KERNELS_CUTOFF: f64 = 1e-12;

/// Points of the kernel curves (plus one).
const KERNEL_POINTS: usize = 2000;

/// The dual kernels (dense `K^+`, cut-off [`KERNELS_CUTOFF`]) and reproducing kernels of the
/// samples `0, 3, m/2, m-4, m-1` (those that exist) for `basis` and `positions`.
pub fn kernels(basis: &CdvBasis, positions: &[f64]) -> Result<KernelsData, ReconstructError> {
    let active = ActiveSet::uniform(basis.clone());
    let k = kernel_matrix(&active, positions)?;
    let dense = dense_pinv(&k, KERNELS_CUTOFF)?;
    let m = positions.len();
    let mut picks: Vec<usize> = [0, 3, m / 2, m.saturating_sub(4), m.saturating_sub(1)]
        .into_iter()
        .filter(|&i| i < m)
        .collect();
    picks.sort_unstable();
    picks.dedup();
    let domain = basis.domain();
    let grid: Vec<f64> = (0..=KERNEL_POINTS)
        .map(|i| domain.from_unit(i as f64 / KERNEL_POINTS as f64))
        .collect();
    let mut dual = Vec::new();
    let mut reproducing = Vec::new();
    for &i in &picks {
        let column: Vec<(usize, f64)> = (0..active.len())
            .map(|a| (a, dense.pinv[(a, i)]))
            .filter(|(_, v)| *v != 0.0)
            .collect();
        let d = dual_kernel(&active, &column, &grid)?;
        let r = reproducing_kernel(&active, &k, i, &grid)?;
        let label = format!("λ_{i} = {:.4}", positions[i]);
        dual.push(Curve {
            label: label.clone(),
            points: grid.iter().copied().zip(d).collect(),
        });
        reproducing.push(Curve {
            label,
            points: grid.iter().copied().zip(r).collect(),
        });
    }
    Ok(KernelsData {
        p: basis.p(),
        coarse: basis.coarse(),
        fine: basis.fine(),
        samples: m,
        domain: [domain.a(), domain.b()],
        picks,
        dual,
        reproducing,
    })
}
