//! Evaluating a fit: `f(x) = sum_a c_a Psi_a(x)`.
//!
//! A uniform `Psi(n, N)` is evaluated through the single scale: the FWT synthesis gives the
//! `V_{N+1}` coefficients `v` once, then `f(x) = sum_k v_k phi_{N+1,k}(x)` takes the `2p - 1`
//! (plus edge) scaling functions of that one level at `x`
//! ([`crate::basis::SingleLevelEvaluator`]). An adaptive set evaluates the levels of
//! `Psi(n, N)` at `x` down to its local depth there (the finest active function whose support
//! holds `x`; finer levels contribute nothing) and combines its active functions
//! ([`crate::kernel::ActiveSet::combine`]).

use rayon::prelude::*;

use super::{Fit, ReconstructError};
use crate::basis::{fwt, BasisError, BasisValue, CdvBasis};

/// Positions evaluated per parallel work item.
const CHUNK: usize = 8192;

/// A fit prepared for evaluation in batches (e.g. a grid written block by block): the
/// single-scale synthesis is done once.
pub struct FitEvaluator<'a> {
    fit: &'a Fit,
    /// `V_{N+1}` and the synthesized coefficients per channel (uniform sets).
    single: Option<(CdvBasis, Vec<Vec<f64>>)>,
}

impl Fit {
    /// Prepares the fit for evaluation (FWT synthesis to `V_{N+1}` for a uniform set).
    pub fn evaluator(&self) -> Result<FitEvaluator<'_>, ReconstructError> {
        let basis = self.active.basis();
        let single = if self.active.is_uniform() {
            let top = basis.fine() + 1;
            let scale = CdvBasis::with_bank(basis.bank().clone(), top, top, basis.domain())?;
            let v = self
                .coefficients
                .iter()
                .map(|c| fwt::synthesis(basis.bank(), basis.coarse(), basis.fine(), c))
                .collect();
            Some((scale, v))
        } else {
            None
        };
        Ok(FitEvaluator { fit: self, single })
    }
}

impl FitEvaluator<'_> {
    /// The reconstruction at `xs`, one vector per channel. Small batches run on the calling
    /// thread (no thread pool is started for them).
    pub fn evaluate(&self, xs: &[f64]) -> Result<Vec<Vec<f64>>, ReconstructError> {
        let fit = self.fit;
        let basis = fit.active.basis();
        let domain = basis.domain();
        if let Some(&x) = xs.iter().find(|x| !domain.contains(**x)) {
            return Err(BasisError::PositionOutside {
                x,
                a: domain.a(),
                b: domain.b(),
            }
            .into());
        }
        let channels = fit.coefficients.len();
        let per_point: Vec<Vec<f64>> = if let Some((scale, single)) = &self.single {
            let work = |chunk: &[f64]| {
                let mut ev = scale.single_level_evaluator();
                let mut vals = Vec::with_capacity(chunk.len() * channels);
                for &x in chunk {
                    let (first, row) = ev.row_unit(domain.to_unit(x));
                    for s in single {
                        let coef = &s[first..first + row.len()];
                        vals.push(coef.iter().zip(row).map(|(c, v)| c * v).sum::<f64>());
                    }
                }
                vals
            };
            if xs.len() <= CHUNK {
                vec![work(xs)]
            } else {
                xs.par_chunks(CHUNK).map(work).collect()
            }
        } else {
            let work = |chunk: &[f64]| {
                let mut ev = basis.evaluator();
                let mut out: Vec<BasisValue> = Vec::with_capacity(256);
                let mut vals = Vec::with_capacity(chunk.len() * channels);
                for &x in chunk {
                    let t = domain.to_unit(x);
                    let depth = fit.active.local_depth_unit(t);
                    ev.eval_unit_to_depth_into(t, depth, &mut out);
                    for c in &fit.coefficients {
                        vals.push(fit.active.combine(&out, c));
                    }
                }
                vals
            };
            if xs.len() <= CHUNK {
                vec![work(xs)]
            } else {
                xs.par_chunks(CHUNK).map(work).collect()
            }
        };
        let mut result = vec![Vec::with_capacity(xs.len()); channels];
        for block in per_point {
            for (i, v) in block.into_iter().enumerate() {
                result[i % channels].push(v);
            }
        }
        Ok(result)
    }
}
