//! Error of a reconstruction against the truth: on a uniform grid (what a plot shows), and by
//! Gauss–Legendre quadrature on a partition (the `L2` norm itself, which a grid misses once the
//! error lives in zones narrower than its spacing, as around a jump resolved to level 20).

use serde::Serialize;

use super::{RefineError, SampleOracle};
use crate::reconstruct::Fit;
use crate::sampling::Domain;

/// A reconstruction that can be evaluated at domain positions: a [`Fit`] (its first channel)
/// or an adaptive `refine::Refinement`. Measurement knows nothing else of them.
pub trait Reconstruction {
    /// `f~(x)` at every `x` of `xs`.
    fn values_at(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError>;
}

impl Reconstruction for Fit {
    fn values_at(&self, xs: &[f64]) -> Result<Vec<f64>, RefineError> {
        let mut v = self.evaluate(xs)?;
        Ok(v.swap_remove(0))
    }
}

/// Error of a reconstruction against the truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ErrorFigures {
    /// RMS error `sqrt(int (f - f~)^2 / (b - a))` (the `L2` norm over `[a, b]` divided by
    /// `sqrt(b - a)`), estimated by the grid mean or the quadrature.
    pub l2: f64,
    /// Largest absolute error at the points used.
    pub max: f64,
    /// Points used.
    pub points: usize,
}

/// Error of `fit` against `oracle` on the uniform grid of `points` positions (both ends
/// included, [`Domain::uniform_grid`]).
pub fn grid_error<R: Reconstruction + ?Sized, O: SampleOracle + ?Sized>(
    fit: &R,
    oracle: &O,
    domain: Domain,
    points: usize,
) -> Result<ErrorFigures, RefineError> {
    let xs = domain.uniform_grid(points.max(1));
    let truth: Vec<f64> = xs.iter().map(|&x| oracle.sample(x)).collect();
    error_against(fit, &xs, &truth)
}

fn error_against<R: Reconstruction + ?Sized>(
    fit: &R,
    xs: &[f64],
    truth: &[f64],
) -> Result<ErrorFigures, RefineError> {
    Ok(ErrorFigures::between(&fit.values_at(xs)?, truth))
}

impl ErrorFigures {
    /// RMS and largest difference of two equally long value lists (grid points).
    pub fn between(got: &[f64], truth: &[f64]) -> Self {
        let (mut sq, mut max) = (0.0f64, 0.0f64);
        for (g, t) in got.iter().zip(truth) {
            let e = (g - t).abs();
            sq += e * e;
            max = max.max(e);
        }
        Self {
            l2: (sq / got.len().max(1) as f64).sqrt(),
            max,
            points: got.len(),
        }
    }
}

/// Nodes and weights of 6-point Gauss–Legendre on `[-1, 1]`.
const GAUSS6: [(f64, f64); 6] = [
    (-0.932_469_514_203_152, 0.171_324_492_379_170_4),
    (-0.661_209_386_466_264_5, 0.360_761_573_048_138_6),
    (-0.238_619_186_083_196_9, 0.467_913_934_572_691),
    (0.238_619_186_083_196_9, 0.467_913_934_572_691),
    (0.661_209_386_466_264_5, 0.360_761_573_048_138_6),
    (0.932_469_514_203_152, 0.171_324_492_379_170_4),
];

/// `sqrt(int (f - f~)^2 / (b - a))` by 6-point Gauss–Legendre on every cell of the partition
/// given by `breaks` (unit coordinates; sorted and completed with 0 and 1 here), each cell cut
/// into `subdivisions` equal parts. Put the signal's singular points and the reconstruction's
/// cells into `breaks`: the rule is accurate where both are smooth.
pub fn quadrature_error<R: Reconstruction + ?Sized, O: SampleOracle + ?Sized>(
    fit: &R,
    oracle: &O,
    domain: Domain,
    breaks: &[f64],
    subdivisions: usize,
) -> Result<ErrorFigures, RefineError> {
    let mut b: Vec<f64> = breaks
        .iter()
        .copied()
        .filter(|t| t.is_finite() && (0.0..=1.0).contains(t))
        .chain([0.0, 1.0])
        .collect();
    b.sort_by(f64::total_cmp);
    b.dedup();
    let sub = subdivisions.max(1);
    let length = domain.length();
    let mut xs = Vec::with_capacity((b.len() - 1) * sub * GAUSS6.len());
    let mut ws = Vec::with_capacity(xs.capacity());
    for w in b.windows(2) {
        let h = (w[1] - w[0]) / sub as f64;
        for s in 0..sub {
            let mid = w[0] + (s as f64 + 0.5) * h;
            for &(node, weight) in &GAUSS6 {
                xs.push(domain.from_unit(mid + 0.5 * h * node));
                ws.push(0.5 * h * weight * length);
            }
        }
    }
    let got = fit.values_at(&xs)?;
    let (mut sq, mut max) = (0.0f64, 0.0f64);
    for ((&x, &w), g) in xs.iter().zip(&ws).zip(&got) {
        let e = (g - oracle.sample(x)).abs();
        sq += w * e * e;
        max = max.max(e);
    }
    Ok(ErrorFigures {
        l2: (sq / length).sqrt(),
        max,
        points: xs.len(),
    })
}
