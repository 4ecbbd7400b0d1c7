//! A fitted reconstruction: the coefficients over the active set, with how they were made.

use serde::Serialize;

use super::error::ReconstructError;
use super::outcome::{Fallback, SolveReport};
use crate::kernel::{ActiveSet, LevelChoice};

/// Seconds spent in each stage.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct Timings {
    /// Building `K`.
    pub kernel_s: f64,
    /// Solving for the coefficients.
    pub solve_s: f64,
}

/// A fitted reconstruction: `f~(x) = sum_a c_a Psi_a(x)` over the active set, per channel.
///
/// ```
/// use rkwave::reconstruct::{fit, FitParams};
/// use rkwave::sampling::{Domain, Layout};
///
/// let xs = Layout::Random.generate(1000, Domain::UNIT, 3);
/// let line: Vec<f64> = xs.iter().map(|x| 2.0 * x - 1.0).collect();
/// let square: Vec<f64> = xs.iter().map(|x| x * x).collect();
/// let f = fit(&xs, &[&line, &square], Domain::UNIT, &FitParams::default())?;
/// assert_eq!(f.coefficients.len(), 2); // two channels
/// assert_eq!(f.coefficients[0].len(), f.active.len());
/// // p = 3 reproduces polynomials of degree < 3 exactly (up to rounding).
/// let v = f.evaluate(&[0.25])?;
/// assert!((v[0][0] + 0.5).abs() < 1e-9 && (v[1][0] - 0.0625).abs() < 1e-9);
/// # Ok::<(), rkwave::reconstruct::ReconstructError>(())
/// ```
#[derive(Clone, Debug)]
pub struct Fit {
    /// The active basis.
    pub active: ActiveSet,
    /// Coefficients per channel, one per active function.
    pub coefficients: Vec<Vec<f64>>,
    /// The levels used.
    pub levels: LevelChoice,
    /// Stage times.
    pub timings: Timings,
    /// The report of the solve that produced the coefficients.
    pub solve: SolveReport,
    /// Every departure from the requested levels or method, in the order taken (empty when
    /// the fit is exactly what was asked for).
    pub fallbacks: Vec<Fallback>,
}

impl Fit {
    /// Every fallback and warning of the fit, one sentence each, for text and JSON output:
    /// the replaced method or lowered level ([`Fit::fallbacks`]) and the local inversion's
    /// cut directions, solver fallbacks and weakly supported blocks
    /// ([`LocalStats::warnings`](crate::solve::LocalStats::warnings)).
    pub fn warnings(&self) -> Vec<String> {
        let mut w: Vec<String> = self.fallbacks.iter().map(|f| f.to_string()).collect();
        if let SolveReport::Local(local) = &self.solve {
            w.extend(local.warnings());
        }
        w
    }

    /// The reconstruction at `xs`, one vector per channel (see [`Fit::evaluator`] to evaluate
    /// many batches).
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<Vec<f64>>, ReconstructError> {
        self.evaluator()?.evaluate(xs)
    }
}
