//! The spectrum seen by a conjugate-gradient run: its `alpha_j, beta_j` are the Lanczos
//! tridiagonal of `M^{-1} A` in disguise (Golub & Van Loan 11.3),
//!
//! ```text
//! T_jj = 1/alpha_j + beta_{j-1}/alpha_{j-1},     T_{j,j+1} = sqrt(beta_j)/alpha_j,
//! ```
//!
//! whose extreme eigenvalues (Ritz values) approach those of `M^{-1} A` from inside:
//! `lambda_max(T) / lambda_min(T)` is a lower estimate of `cond(M^{-1} A)`.
//!
//! The extremes are found by bisection on Sturm counts (Golub & Van Loan 8.4.1): the number
//! of eigenvalues of `T` below `x` is the number of negative pivots of `T - x I`,
//! `q_1 = d_1 - x`, `q_i = d_i - x - e_{i-1}^2 / q_{i-1}`, inside Gershgorin's interval. Each
//! count costs `O(j)`, so the estimate can be taken at every iteration of a run (the
//! forward-error stop of [`super::CgParams::forward_error`]) for any number of iterations.

/// Bisection steps: Gershgorin's interval halved 200 times is below the spacing of doubles
/// in it, so the extremes come out to rounding (the loop stops once the midpoint no longer
/// moves).
const BISECTION_STEPS: usize = 200;

/// The diagonal `d` and off-diagonal `e` of the Lanczos tridiagonal of a CG run.
fn tridiagonal(alphas: &[f64], betas: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let k = alphas.len();
    let d = (0..k)
        .map(|i| {
            1.0 / alphas[i]
                + if i > 0 {
                    betas[i - 1] / alphas[i - 1]
                } else {
                    0.0
                }
        })
        .collect();
    let e = (0..k.saturating_sub(1))
        .map(|i| betas[i].sqrt() / alphas[i])
        .collect();
    (d, e)
}

/// The number of eigenvalues of the symmetric tridiagonal `(d, e)` below `x` (Sturm count;
/// a zero pivot is moved to the smallest positive normal number, which counts it as not
/// negative, as LAPACK's `dstebz` does).
fn below(d: &[f64], e: &[f64], x: f64) -> usize {
    let mut count = 0;
    let mut q = 1.0;
    for i in 0..d.len() {
        let off = if i > 0 { e[i - 1] * e[i - 1] / q } else { 0.0 };
        q = d[i] - x - off;
        if q == 0.0 {
            q = f64::MIN_POSITIVE;
        }
        if q < 0.0 {
            count += 1;
        }
    }
    count
}

/// The eigenvalue of index `index` (0 the least) of the tridiagonal `(d, e)` in `[lo, hi]`,
/// by bisection on [`below`].
fn bisect(d: &[f64], e: &[f64], index: usize, mut lo: f64, mut hi: f64) -> f64 {
    for _ in 0..BISECTION_STEPS {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            break;
        }
        if below(d, e, mid) > index {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    0.5 * (lo + hi)
}

/// `(lambda_min, lambda_max)` of the Lanczos tridiagonal of a CG run (`None` with no
/// iteration or a tridiagonal that is not finite).
pub fn lanczos_extremes(alphas: &[f64], betas: &[f64]) -> Option<(f64, f64)> {
    let k = alphas.len();
    if k == 0 || betas.len() + 1 < k {
        return None;
    }
    let (d, e) = tridiagonal(alphas, betas);
    if d.iter().chain(&e).any(|v| !v.is_finite()) {
        return None;
    }
    // Gershgorin's interval holds every eigenvalue
    let radius = |i: usize| {
        (if i > 0 { e[i - 1].abs() } else { 0.0 }) + (if i + 1 < k { e[i].abs() } else { 0.0 })
    };
    let lo = (0..k)
        .map(|i| d[i] - radius(i))
        .fold(f64::INFINITY, f64::min);
    let hi = (0..k)
        .map(|i| d[i] + radius(i))
        .fold(f64::NEG_INFINITY, f64::max);
    let pad = 1e-12 * (hi - lo).abs().max(hi.abs()).max(f64::MIN_POSITIVE);
    let (lo, hi) = (lo - pad, hi + pad);
    Some((bisect(&d, &e, 0, lo, hi), bisect(&d, &e, k - 1, lo, hi)))
}

/// `lambda_max / lambda_min` of the Lanczos tridiagonal of a CG run (1 with fewer than two
/// iterations, infinite if `lambda_min <= 0`).
pub fn lanczos_condition(alphas: &[f64], betas: &[f64]) -> f64 {
    if alphas.len() < 2 {
        return 1.0;
    }
    match lanczos_extremes(alphas, betas) {
        Some((lo, hi)) if lo > 0.0 => hi / lo,
        _ => f64::INFINITY,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// The bisection's extremes against nalgebra's dense symmetric eigensolver on random
    /// tridiagonals of CG's form (positive `alpha`, `beta`), to 1e-10 of the largest.
    #[test]
    fn extremes_match_dense_eigenvalues() {
        let mut state = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        for k in [2usize, 3, 7, 40, 301] {
            let alphas: Vec<f64> = (0..k).map(|_| 0.05 + uniform()).collect();
            let betas: Vec<f64> = (0..k).map(|_| 1e-3 + uniform()).collect();
            let (d, e) = tridiagonal(&alphas, &betas);
            let mut t = DMatrix::<f64>::zeros(k, k);
            for i in 0..k {
                t[(i, i)] = d[i];
                if i + 1 < k {
                    t[(i, i + 1)] = e[i];
                    t[(i + 1, i)] = e[i];
                }
            }
            let eig = nalgebra::linalg::SymmetricEigen::new(t).eigenvalues;
            let lo = eig.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = eig.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let (blo, bhi) = lanczos_extremes(&alphas, &betas).unwrap();
            let scale = hi.abs().max(lo.abs());
            assert!((blo - lo).abs() <= 1e-10 * scale, "k {k}: {blo} vs {lo}");
            assert!((bhi - hi).abs() <= 1e-10 * scale, "k {k}: {bhi} vs {hi}");
        }
    }
}
