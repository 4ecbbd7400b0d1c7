//! The condition estimate of a conjugate-gradient run: its `alpha_j, beta_j` are the Lanczos
//! tridiagonal of `M^{-1} A` in disguise (Golub & Van Loan 11.3),
//!
//! ```text
//! T_jj = 1/alpha_j + beta_{j-1}/alpha_{j-1},     T_{j,j+1} = sqrt(beta_j)/alpha_j,
//! ```
//!
//! whose extreme eigenvalues approach those of `M^{-1} A` from inside: `lambda_max(T) /
//! lambda_min(T)` is a lower estimate of `cond(M^{-1} A)`.

use nalgebra::DMatrix;

/// Most iterations the tridiagonal keeps (a dense eigenvalue problem of that size).
const MAX_ORDER: usize = 300;

/// `lambda_max / lambda_min` of the Lanczos tridiagonal of a CG run (1 with fewer than two
/// iterations, infinite if `lambda_min <= 0`).
pub fn lanczos_condition(alphas: &[f64], betas: &[f64]) -> f64 {
    let k = alphas.len().min(MAX_ORDER);
    if k < 2 {
        return 1.0;
    }
    let mut t = DMatrix::<f64>::zeros(k, k);
    for i in 0..k {
        t[(i, i)] = 1.0 / alphas[i]
            + if i > 0 {
                betas[i - 1] / alphas[i - 1]
            } else {
                0.0
            };
        if i + 1 < k {
            let e = betas[i].sqrt() / alphas[i];
            t[(i, i + 1)] = e;
            t[(i + 1, i)] = e;
        }
    }
    let eig = nalgebra::linalg::SymmetricEigen::new(t).eigenvalues;
    let (lo, hi) = eig.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
        (lo.min(e), hi.max(e))
    });
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}
