//! What a global least-squares solve returns: the coefficients `c[ch] = argmin ||K c -
//! f[ch]||` per channel and the report of the method that found them (the Cholesky of
//! `solve::global_ls` and `solve::normal_ls`, or CGLS).

use serde::Serialize;

use super::params::GlobalMethod;

/// What the global solve did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GlobalReport {
    /// Method used.
    pub method: GlobalMethod,
    /// CGLS iterations per channel (0 for Cholesky).
    pub iterations: Vec<usize>,
    /// Relative normal-equation residual `||K^T (f - K c)|| / ||K^T f||` per channel
    /// (computed on the equilibrated system).
    pub residuals: Vec<f64>,
    /// Ridge added to the unit diagonal of the equilibrated normal matrix (0 = none).
    pub ridge: f64,
    /// Smallest pivot `L_ii^2` of the equilibrated Cholesky factor (Cholesky only; a lower
    /// bound proxy for `1 / cond(K)^2`), 0 for CGLS.
    pub min_pivot: f64,
    /// Stored entries of `K^T K` (both triangles), 0 for CGLS.
    pub normal_nnz: usize,
    /// Stored entries of the Cholesky factor `L`, 0 for CGLS.
    pub factor_nnz: usize,
}

/// Coefficients of the global least-squares fit.
#[derive(Debug, Clone)]
pub struct GlobalLs {
    /// `c[ch] = argmin ||K c - f[ch]||`, `P` values per channel.
    pub coefficients: Vec<Vec<f64>>,
    /// Report.
    pub report: GlobalReport,
}

impl GlobalLs {
    /// The answer of an empty problem (no channel, no function or no sample): zero
    /// coefficients, nothing solved.
    pub fn empty(functions: usize, channels: usize, method: GlobalMethod) -> Self {
        Self {
            coefficients: vec![vec![0.0; functions]; channels],
            report: GlobalReport {
                method,
                iterations: vec![],
                residuals: vec![],
                ridge: 0.0,
                min_pivot: 0.0,
                normal_nnz: 0,
                factor_nnz: 0,
            },
        }
    }
}
