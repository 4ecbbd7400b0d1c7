//! The dense least-squares oracle every solver is checked against, as RustFFT checks every
//! algorithm against its naive DFT: the minimum-norm solution
//!
//! ```text
//! c* = K^+ f = V diag(1 / s_k) U^T f,        K = U diag(s) V^T   (m x P, m >= P)
//! ```
//!
//! of `min_c ||K c - f||_2`, from nalgebra's dense SVD of the kernel matrix the library itself
//! built (its rows: the thing under test is the solve, not the basis). nalgebra shares no code
//! with the library's solvers (faer's SVD, the banded QR, the sparse Cholesky, the conjugate
//! gradients). nalgebra's SVD is not always backward stable to `eps` (on one 512 x 73 kernel
//! matrix here `||K - U S V^T|| = 2e-11 ||K||`), so the first solution is refined twice
//! through the same SVD ([`DenseLs::solve`]); and the oracle checks itself on every solve:
//! `c*` satisfies the normal equations `K^T (f - K c*) = 0` to rounding.
//!
//! ## The tolerance rule, stated once
//!
//! With `eps` the unit roundoff of `f64`, `kappa = s_max / s_min` the condition number of `K`,
//! `r* = f - K c*` the least-squares residual and `C = 2 sqrt(m P)`, a solver's coefficients `c`
//! must satisfy `||c - c*|| / ||c*|| <=` the bound of its class ([`Accuracy`]):
//!
//! | class | solvers | bound |
//! | --- | --- | --- |
//! | backward stable | QR, SVD, local inversion by SVD/QR with rings reaching every function, corrected semi-normal equations | `C eps kappa (1 + kappa ||r*|| / (||K|| ||c*||))` |
//! | normal equations | Cholesky of `K^T K` | `C eps kappa^2 (1 + ||r*|| / (||K|| ||c*||))` |
//! | iterative | CG on `K^T K`, CGLS, Schwarz PCG | `C eps kappa^2 + ||K^T (f - K c)|| / (s_min^2 ||c*||)` |
//!
//! Why these: the first two are the first-order perturbation bounds of least squares (Wedin
//! 1973; Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Thm. 20.1 and
//! §20.4) for a method whose backward error is of order `eps`, and for the normal equations,
//! whose forming of `K^T K` squares `kappa` and whose right-hand side `K^T f` carries the
//! rounding of the residual's part of `f`. The constants of those theorems are `m P eps`
//! in the worst case, where every rounding error has the same sign; rounding errors of random
//! sign add like a random walk, the square root `sqrt(m P)`; and two computed solutions are
//! compared, the oracle's own obeying the same bound: `C = 2 sqrt(m P)` (from 8 to 1,300 on
//! the test problems, where the measured errors stay below half the bound). The third is exact
//! arithmetic plus the second: for any `c`, `c - c* = (K^T K)^{-1} K^T (f - K c)`, so
//! `||c - c*|| <= ||K^T (f - K c)|| / s_min^2`, what the iteration left, measured here rather
//! than taken from the solver's report.
//!
//! Test problems are well posed (full column rank, `kappa <= 1e5`, [`MAX_CONDITION`]): small
//! enough that the refinement converges (it contracts by the SVD's backward error times
//! `kappa^2`, at most `2e-11 * 1e10 = 0.2`).

use nalgebra::{DMatrix, DVector};
use sprs::CsMat;

/// How accurate a solver claims to be: selects the bound of the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Accuracy {
    /// Backward stable (QR, SVD): `C eps kappa (1 + kappa ||r*|| / (||K|| ||c*||))`.
    BackwardStable,
    /// The normal equations by Cholesky: `C eps kappa^2 (1 + ||r*|| / (||K|| ||c*||))`.
    NormalEquations,
    /// An iteration on the normal equations: `C eps kappa^2` plus what the iteration left,
    /// `||K^T (f - K c)|| / (s_min^2 ||c*||)`.
    Iterative,
}

/// The largest condition number the oracle accepts for a test problem (module docs).
pub const MAX_CONDITION: f64 = 1e5;

/// Most steps of the oracle's iterative refinement ([`DenseLs::solve`]): at `kappa = 1e5` and
/// an SVD backward error of `2e-11` a step contracts by about `kappa^2 2e-11 = 0.2`, so 40
/// steps reach rounding from any start with room to spare.
pub const REFINEMENT_STEPS: usize = 40;

/// The dense SVD of a small kernel matrix and the least-squares solutions it gives.
pub struct DenseLs {
    k: DMatrix<f64>,
    u: DMatrix<f64>,
    s: DVector<f64>,
    v: DMatrix<f64>,
    s_max: f64,
    s_min: f64,
}

/// `K` as a dense matrix (CSR or CSC; repeated entries summed).
pub fn dense(k: &CsMat<f64>) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(k.rows(), k.cols());
    for (&v, (i, j)) in k.iter() {
        out[(i, j)] += v;
    }
    out
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

impl DenseLs {
    /// The SVD of `K` (`m x P`, `m >= P`, full column rank with `kappa <= MAX_CONDITION`).
    #[track_caller]
    pub fn new(k: &CsMat<f64>) -> Self {
        let k = dense(k);
        assert!(
            k.nrows() >= k.ncols() && k.ncols() > 0,
            "a least-squares test problem: {} x {}",
            k.nrows(),
            k.ncols()
        );
        let svd = k.clone().svd(true, true);
        let s = svd.singular_values.clone();
        let s_max = s.iter().copied().fold(0.0, f64::max);
        let s_min = s.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(
            s_min > 0.0 && s_max / s_min <= MAX_CONDITION,
            "the test problem is not well posed: cond(K) = {:e}",
            s_max / s_min
        );
        Self {
            u: svd.u.expect("U"),
            v: svd.v_t.expect("V^T").transpose(),
            k,
            s,
            s_max,
            s_min,
        }
    }

    /// `kappa = s_max / s_min`.
    pub fn condition(&self) -> f64 {
        self.s_max / self.s_min
    }

    /// `||K||_2 = s_max`.
    pub fn norm(&self) -> f64 {
        self.s_max
    }

    /// `C = 2 sqrt(m P)` of the tolerance rule.
    pub fn constant(&self) -> f64 {
        2.0 * ((self.k.nrows() * self.k.ncols()) as f64).sqrt()
    }

    /// `K c`.
    pub fn apply(&self, c: &[f64]) -> Vec<f64> {
        (&self.k * DVector::from_column_slice(c))
            .iter()
            .copied()
            .collect()
    }

    /// `K^T (f - K c)`: the gradient of `||K c - f||^2 / 2`, zero at the least-squares
    /// solution.
    pub fn normal_residual(&self, f: &[f64], c: &[f64]) -> Vec<f64> {
        let r = DVector::from_column_slice(f) - &self.k * DVector::from_column_slice(c);
        (self.k.transpose() * r).iter().copied().collect()
    }

    /// `c* = V diag(1 / s) U^T f`, refined and checked against the normal equations:
    /// `||K^T (f - K c*)|| <= C eps ||K|| (||K|| ||c*|| + ||f||)`, the rounding of the product.
    ///
    /// The first solution is refined by the same pseudo-inverse,
    /// `c <- c + V diag(1 / s^2) V^T K^T (f - K c)` (the normal equations solved through the
    /// SVD: iterative refinement), which contracts the error by about
    /// `kappa^2 ||K - U S V^T|| / ||K||` a step. With nalgebra's SVD at a backward error near
    /// `1e-11` and `kappa` up to [`MAX_CONDITION`] a step can contract by only `0.2`, so the
    /// refinement runs to its fixed point (a step below `4 eps ||c||`), at most
    /// [`REFINEMENT_STEPS`] steps: a fixed number of two steps left errors of `4e-13` on
    /// well-conditioned random problems where the solvers under test agreed with each other
    /// to `1e-15`.
    #[track_caller]
    pub fn solve(&self, f: &[f64]) -> Vec<f64> {
        assert_eq!(f.len(), self.k.nrows(), "one value per row of K");
        let utf = self.u.transpose() * DVector::from_column_slice(f);
        let mut c = &self.v * utf.component_div(&self.s);
        let s2 = self.s.component_mul(&self.s);
        let allowed = |c: &[f64]| {
            self.constant() * f64::EPSILON * self.s_max * (self.s_max * norm(c) + norm(f))
        };
        for _ in 0..REFINEMENT_STEPS {
            let g = DVector::from_vec(self.normal_residual(f, c.as_slice()));
            let step = &self.v * (self.v.transpose() * g).component_div(&s2);
            c += &step;
            if step.norm() <= 4.0 * f64::EPSILON * c.norm() {
                break;
            }
        }
        let c: Vec<f64> = c.iter().copied().collect();
        let gradient = norm(&self.normal_residual(f, &c));
        let allowed = allowed(&c);
        assert!(
            gradient <= allowed,
            "the oracle itself: ||K^T r*|| = {gradient:e} > {allowed:e} (cond(K) = {:e}, {} x {})",
            self.condition(),
            self.k.nrows(),
            self.k.ncols()
        );
        c
    }

    /// `||f - K c*|| / (||K|| ||c*||)`: how large the least-squares residual is against the
    /// fitted part; the rounding of `K^T r` in any solver (and in the oracle's refinement)
    /// grows with it.
    fn residual_ratio(&self, f: &[f64], c_star: &[f64]) -> f64 {
        let r: Vec<f64> = f
            .iter()
            .zip(self.apply(c_star))
            .map(|(a, b)| a - b)
            .collect();
        norm(&r) / (self.s_max * norm(c_star))
    }

    /// The bound of the tolerance rule on `||c - c*|| / ||c*||` for coefficients `c` of
    /// data `f` (`c*` the oracle's solution).
    pub fn bound(&self, accuracy: Accuracy, f: &[f64], c_star: &[f64], c: &[f64]) -> f64 {
        let eps = f64::EPSILON;
        let kappa = self.condition();
        let cnorm = norm(c_star);
        let rounding = self.constant() * eps;
        match accuracy {
            Accuracy::BackwardStable => {
                rounding * kappa * (1.0 + kappa * self.residual_ratio(f, c_star))
            }
            Accuracy::NormalEquations => {
                rounding * kappa * kappa * (1.0 + self.residual_ratio(f, c_star))
            }
            Accuracy::Iterative => {
                let left = norm(&self.normal_residual(f, c)) / (self.s_min * self.s_min * cnorm);
                rounding * kappa * kappa + left
            }
        }
    }

    /// Asserts `||c - c*|| / ||c*|| <= bound` for one channel; returns the error and the
    /// bound.
    #[track_caller]
    pub fn check(&self, what: &str, accuracy: Accuracy, f: &[f64], c: &[f64]) -> (f64, f64) {
        assert_eq!(
            c.len(),
            self.k.ncols(),
            "{what}: one coefficient per column of K"
        );
        assert!(
            c.iter().all(|v| v.is_finite()),
            "{what}: non-finite coefficients"
        );
        let c_star = self.solve(f);
        let diff: Vec<f64> = c.iter().zip(&c_star).map(|(a, b)| a - b).collect();
        let error = norm(&diff) / norm(&c_star);
        let bound = self.bound(accuracy, f, &c_star, c);
        assert!(
            error <= bound,
            "{what}: ||c - c*|| / ||c*|| = {error:.3e} > {bound:.3e} ({accuracy:?}, \
             cond(K) = {:.3e}, {} x {})",
            self.condition(),
            self.k.nrows(),
            self.k.ncols()
        );
        (error, bound)
    }
}

/// Checks a solver's coefficients (one vector per channel, in the column order of `k`)
/// against the dense SVD solution of `min ||K c - f||` for every channel of `values`, within
/// the bound of `accuracy` (module docs); prints the worst ratio error / bound. Builds the SVD
/// once: pass every channel in one call.
#[track_caller]
pub fn check_ls_solver(
    what: &str,
    k: &CsMat<f64>,
    values: &[&[f64]],
    coefficients: &[Vec<f64>],
    accuracy: Accuracy,
) {
    check_with(&DenseLs::new(k), what, values, coefficients, accuracy);
}

/// [`check_ls_solver`] with an SVD already computed (several solvers on one problem).
#[track_caller]
pub fn check_with(
    oracle: &DenseLs,
    what: &str,
    values: &[&[f64]],
    coefficients: &[Vec<f64>],
    accuracy: Accuracy,
) {
    assert_eq!(
        values.len(),
        coefficients.len(),
        "{what}: one solution per channel"
    );
    let mut worst = (0.0, 1.0);
    for (ch, (f, c)) in values.iter().zip(coefficients).enumerate() {
        let (error, bound) = oracle.check(&format!("{what}, channel {ch}"), accuracy, f, c);
        if error / bound > worst.0 / worst.1 {
            worst = (error, bound);
        }
    }
    println!(
        "{what}: cond(K) = {:.2e}, error {:.2e} <= {:.2e} ({accuracy:?})",
        oracle.condition(),
        worst.0,
        worst.1
    );
}
