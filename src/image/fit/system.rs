//! Solving the 2D normal equations `(G + lambda D^{-2}) z = b`: sparse Cholesky or PCG.
//!
//! `D = diag(G)^{-1/2}` equilibrates: the matrix factored is `A = D G D + lambda I` (a
//! relative ridge `lambda`, stated in the report), `z = D y`, `A y = D b`. A function with no
//! sample in its support has `G_kk = 0`: `D_kk = 0` pins its coefficient to 0 (reported as
//! unsampled), the rest of the system is untouched.
//!
//! - Cholesky: faer's supernodal sparse `L L^T` with an AMD ordering; the symbolic
//!   factorization depends only on the stencil pattern (once per basis), the numeric one on
//!   the samples (once per image), and every channel is solved from the one factor. A failed
//!   factorization (a direction the samples do not determine) is retried with the ridge
//!   multiplied by 100 (reported).
//! - PCG on `A`: conjugate gradients with no preconditioner, Jacobi (`diag(A)^{-1}`, which on the
//!   equilibrated `A` is the identity up to the ridge, so it is run on `G` itself), or local
//!   inversion (`M = K~ K~^T` with `K~ ≈ K^+` from [`crate::solve::local_inversion`] on the 2D
//!   kernel matrix: `K^+ K^{+T} = (K^T K)^{-1}`), stopped at a relative residual.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, supernodal, LltRef, SymbolicCholesky, SymbolicCholeskyRaw,
    SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, Par, Side};
use rayon::prelude::*;
use serde::Serialize;
use sprs::CsMat;

use super::normal::{symmetric_matvec, StencilPattern};

/// Preconditioner of conjugate gradients.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Preconditioner {
    /// Plain CG on `G + lambda diag(G)`.
    None,
    /// `M = diag(G)^{-1}`: free, and removes the scale differences between functions.
    Jacobi,
    /// `M = K~ K~^T`, `K~` the local inversion of the 2D kernel matrix (rings 0, Cholesky
    /// blocks): a setup of one small factorization per sample pattern, an apply of two
    /// passes over `K~` (`m` columns of `(2p - 1)^2` entries); fewer iterations.
    Local,
}

/// Fill-reducing ordering of the sparse Cholesky.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum FillOrdering {
    /// Nested dissection of the grid of unknowns (separators one 1D half-bandwidth wide):
    /// `O(N log N)` fill and `O(N^{3/2})` flops on a 2D stencil, no graph search.
    #[default]
    NestedDissection,
    /// faer's approximate minimum degree (a general graph heuristic).
    Amd,
}

/// How the normal equations are solved.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum NormalSolver {
    /// Sparse Cholesky (exact; memory of the fill-in, ~`N log N`).
    Cholesky,
    /// Preconditioned conjugate gradients (memory of `G` only).
    Cg {
        /// The preconditioner.
        preconditioner: Preconditioner,
        /// Stop at `||b - A x|| <= tolerance ||b||`.
        tolerance: f64,
        /// Give up (and report it) after this many iterations.
        max_iterations: usize,
    },
    /// Local inversion instead of a global solve (DESIGN §4): `z_c = K~ f_c` with `K~ ≈ K^+`
    /// from [`crate::solve::apply_local`] on the 2D kernel matrix: local, approximate (its
    /// error against the global solve shrinks with `rings`), and `G` is still accumulated for
    /// [`super::ImageFit::solve_normal`].
    Local(crate::solve::LocalInversionParams),
}

/// What one CG solve did.
#[derive(Clone, Debug, Serialize)]
pub struct CgReport {
    /// The preconditioner.
    pub preconditioner: Preconditioner,
    /// Iterations per channel.
    pub iterations: Vec<usize>,
    /// Final relative residual per channel.
    pub residual: Vec<f64>,
    /// Whether every channel reached the tolerance.
    pub converged: bool,
    /// Seconds to build the preconditioner.
    pub setup_s: f64,
}

/// The assembled system and (for Cholesky) its factor.
pub struct NormalSystem {
    pattern: StencilPattern,
    /// `G` on the pattern (lower triangle).
    g: Vec<f64>,
    /// `D_kk = G_kk^{-1/2}` (0 where unsampled).
    d: Vec<f64>,
    /// Relative ridge actually used.
    ridge: f64,
    factor: Option<(SymbolicCholesky<usize>, Vec<f64>)>,
    /// Stored entries of the Cholesky factor.
    factor_nnz: usize,
}

/// What the Cholesky factorization found.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FactorReport {
    /// The fill-reducing ordering used.
    pub ordering: FillOrdering,
    /// Stored entries of `L` (fill-in included).
    pub factor_nnz: usize,
    /// Pivots `L_jj^2` of the equilibrated matrix below [`PIVOT_TOLERANCE`] (directions the
    /// samples do not determine, beyond the unsampled functions): each was replaced by 1,
    /// which fixes that direction's component at about 0 (reported, never NaN).
    pub replaced_pivots: usize,
    /// Smallest pivot `L_jj^2` kept (about `1 / cond`; small values flag undersampled areas).
    pub min_pivot: f64,
    /// Times the factorization met a negative pivot and was redone with the ridge times 100
    /// (the final ridge is in the solve report).
    pub ridge_retries: usize,
}

/// Largest relative ridge tried before the factorization is declared failed.
pub const MAX_RIDGE: f64 = 1e-2;

/// Pivots of the equilibrated factor below this are replaced (as in 1D, see
/// [`crate::reconstruct::PIVOT_TOLERANCE`]).
pub const PIVOT_TOLERANCE: f64 = crate::reconstruct::PIVOT_TOLERANCE;

impl std::fmt::Debug for NormalSystem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("NormalSystem")
            .field("unknowns", &self.pattern.len())
            .field("nnz", &self.pattern.nnz())
            .field("ridge", &self.ridge)
            .field("factored", &self.factor.is_some())
            .finish()
    }
}

fn equilibration(pattern: &StencilPattern, g: &[f64]) -> Vec<f64> {
    (0..pattern.len())
        .map(|j| {
            let v = g[pattern.col_ptr[j]];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect()
}

impl NormalSystem {
    /// Wraps `G` without factoring (for CG).
    pub fn new(pattern: StencilPattern, g: Vec<f64>, ridge: f64) -> Self {
        let d = equilibration(&pattern, &g);
        Self {
            pattern,
            g,
            d,
            ridge,
            factor: None,
            factor_nnz: 0,
        }
    }

    /// Factors `A = D G D + lambda I`: symbolic (AMD ordering, supernodal when worth it),
    /// then numeric with pivots below [`PIVOT_TOLERANCE`] replaced by 1.
    pub fn factor(&mut self, ordering: FillOrdering) -> Result<FactorReport, String> {
        let n = self.pattern.len();
        let fwd = match ordering {
            FillOrdering::NestedDissection => self.pattern.nested_dissection(),
            FillOrdering::Amd => Vec::new(),
        };
        let mut inv = vec![0usize; fwd.len()];
        for (new, &old) in fwd.iter().enumerate() {
            inv[old] = new;
        }
        let ord = match ordering {
            FillOrdering::NestedDissection => {
                SymmetricOrdering::Custom(faer::perm::PermRef::new_checked(&fwd, &inv, n))
            }
            FillOrdering::Amd => SymmetricOrdering::Amd,
        };
        let symbolic = SymbolicSparseColMatRef::new_checked(
            n,
            n,
            &self.pattern.col_ptr,
            None,
            &self.pattern.row_idx,
        );
        let sym = factorize_symbolic_cholesky(symbolic, Side::Lower, ord, Default::default())
            .map_err(|e| format!("symbolic Cholesky of the 2D normal matrix: {e:?}"))?;
        let par = Par::rayon(0);
        let mut values = vec![0.0; sym.len_val()];
        let mut mem =
            MemBuffer::new(sym.factorize_numeric_llt_scratch::<f64>(par, Default::default()));
        let mut ridge_retries = 0;
        loop {
            let a = self.equilibrated(self.ridge);
            let mat = SparseColMatRef::new(symbolic, &a);
            let result = sym.factorize_numeric_llt(
                &mut values,
                mat,
                Side::Lower,
                LltRegularization {
                    dynamic_regularization_delta: 1.0,
                    dynamic_regularization_epsilon: PIVOT_TOLERANCE,
                },
                par,
                MemStack::new(&mut mem),
                Default::default(),
            );
            match result {
                Ok(_) => break,
                // a negative pivot (rounding on a direction the samples do not determine):
                // a larger ridge, reported
                Err(e) if self.ridge < MAX_RIDGE => {
                    self.ridge = (self.ridge * 100.0).max(1e-12);
                    ridge_retries += 1;
                    let _ = e;
                }
                Err(e) => {
                    return Err(format!(
                        "numeric Cholesky of the 2D normal matrix failed with ridge {:e}: {e:?}",
                        self.ridge
                    ))
                }
            }
        }
        let pivots = diagonal(&sym, &values);
        // replaced pivots are exactly 1 (delta); so are unsampled functions' (pinned) ones
        let pinned = self.d.iter().filter(|&&d| d == 0.0).count();
        let ones = pivots.iter().filter(|&&l| l == 1.0).count();
        let min_pivot = pivots
            .iter()
            .filter(|&&l| l != 1.0)
            .map(|l| l * l)
            .fold(f64::INFINITY, f64::min);
        self.factor_nnz = values.len();
        self.factor = Some((sym, values));
        Ok(FactorReport {
            ordering,
            factor_nnz: self.factor_nnz,
            replaced_pivots: ones.saturating_sub(pinned),
            min_pivot,
            ridge_retries,
        })
    }

    /// `A = D G D + lambda I` on the pattern (unsampled diagonals set to 1).
    fn equilibrated(&self, ridge: f64) -> Vec<f64> {
        let p = &self.pattern;
        let mut a = vec![0.0; self.g.len()];
        a.par_chunks_mut(1 << 14)
            .enumerate()
            .for_each(|(chunk, out)| {
                let start = chunk << 14;
                // column of the first entry: binary search in col_ptr
                let mut j = p.col_ptr.partition_point(|&c| c <= start) - 1;
                for (t, v) in out.iter_mut().enumerate() {
                    let s = start + t;
                    while p.col_ptr[j + 1] <= s {
                        j += 1;
                    }
                    let i = p.row_idx[s];
                    *v = self.d[i] * self.g[s] * self.d[j];
                    if i == j {
                        *v = if self.d[j] == 0.0 { 1.0 } else { *v + ridge };
                    }
                }
            });
        a
    }

    /// The pattern of `G`.
    pub fn pattern(&self) -> &StencilPattern {
        &self.pattern
    }
    /// Relative ridge in use.
    pub fn ridge(&self) -> f64 {
        self.ridge
    }
    /// Entries of the Cholesky factor (0 before [`Self::factor`]).
    pub fn factor_nnz(&self) -> usize {
        self.factor_nnz
    }
    /// Whether a Cholesky factor is held.
    pub fn is_factored(&self) -> bool {
        self.factor.is_some()
    }

    /// Solves `(G + lambda D^{-2}) z = b` for several right-hand sides with the factor.
    ///
    /// # Panics
    /// If the system is not factored (an internal contract).
    pub fn solve_factored(&self, rhs: &[&[f64]]) -> Vec<Vec<f64>> {
        let (sym, values) = self.factor.as_ref().expect("solve_factored needs a factor");
        let n = self.pattern.len();
        let mut b = Mat::<f64>::from_fn(n, rhs.len(), |i, c| self.d[i] * rhs[c][i]);
        let par = if rhs.len() > 1 {
            Par::rayon(0)
        } else {
            Par::Seq
        };
        let mut mem = MemBuffer::new(sym.solve_in_place_scratch::<f64>(rhs.len(), par));
        LltRef::new(sym, values).solve_in_place_with_conj(
            Conj::No,
            b.as_mut(),
            par,
            MemStack::new(&mut mem),
        );
        (0..rhs.len())
            .map(|c| (0..n).map(|i| self.d[i] * b[(i, c)]).collect())
            .collect()
    }

    /// `y_c = (G + lambda D^{-2}) x_c` for every vector (zero rows and columns where
    /// unsampled).
    pub fn apply(&self, x: &[&[f64]], y: &mut [Vec<f64>]) {
        symmetric_matvec(&self.pattern, &self.g, x, y);
        let r = self.ridge;
        if r > 0.0 {
            for (xc, yc) in x.iter().zip(y.iter_mut()) {
                for ((yi, xi), di) in yc.iter_mut().zip(xc.iter()).zip(&self.d) {
                    if *di > 0.0 {
                        *yi += r * xi / (di * di)
                    }
                }
            }
        }
    }

    /// PCG for `(G + lambda D^{-2}) z_c = b_c`, all right-hand sides together (one pass over
    /// `G` per iteration serves every channel still iterating); `local` is `K~` (CSC,
    /// `P x m`) and its CSR form for [`Preconditioner::Local`]. Returns per channel the
    /// solution, the iterations and the final relative residual `||b - A z|| / ||b||`.
    /// Vector operations are sequential (`O(N)` each, cheap beside the product): fewer
    /// synchronisations, which matter on a shared machine.
    pub fn solve_cg(
        &self,
        rhs: &[&[f64]],
        preconditioner: Preconditioner,
        local: Option<&(CsMat<f64>, CsMat<f64>)>,
        tolerance: f64,
        max_iterations: usize,
    ) -> Vec<(Vec<f64>, usize, f64)> {
        let n = self.pattern.len();
        let k = rhs.len();
        let precondition = |r: &[f64], z: &mut [f64]| match (preconditioner, local) {
            (Preconditioner::Jacobi, _) => {
                for ((zi, ri), di) in z.iter_mut().zip(r).zip(&self.d) {
                    *zi = di * di * ri / (1.0 + self.ridge);
                }
            }
            (Preconditioner::Local, Some((csc, csr))) => local_apply(csc, csr, r, z),
            _ => z.copy_from_slice(r),
        };
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| x * y).sum() };
        // unsampled components of b are outside the range of G: dropped
        let r0: Vec<Vec<f64>> = rhs
            .iter()
            .map(|b| {
                b.iter()
                    .zip(&self.d)
                    .map(|(v, d)| if *d > 0.0 { *v } else { 0.0 })
                    .collect()
            })
            .collect();
        let norm_b: Vec<f64> = r0.iter().map(|b| dot(b, b).sqrt()).collect();
        let mut x = vec![vec![0.0; n]; k];
        let mut r = r0;
        let mut z = vec![vec![0.0; n]; k];
        for c in 0..k {
            precondition(&r[c], &mut z[c]);
        }
        let mut p = z.clone();
        let mut rz: Vec<f64> = (0..k).map(|c| dot(&r[c], &z[c])).collect();
        let mut q = vec![vec![0.0; n]; k];
        let mut res: Vec<f64> = norm_b
            .iter()
            .map(|&b| if b > 0.0 { 1.0 } else { 0.0 })
            .collect();
        let mut iterations = vec![0usize; k];
        let mut active: Vec<usize> = (0..k).filter(|&c| norm_b[c] > 0.0).collect();
        for it in 0..max_iterations {
            if active.is_empty() {
                break;
            }
            {
                let ps: Vec<&[f64]> = active.iter().map(|&c| p[c].as_slice()).collect();
                let mut qs: Vec<Vec<f64>> =
                    active.iter().map(|&c| std::mem::take(&mut q[c])).collect();
                self.apply(&ps, &mut qs);
                for (&c, qc) in active.iter().zip(qs) {
                    q[c] = qc;
                }
            }
            let mut still = Vec::with_capacity(active.len());
            for &c in &active {
                iterations[c] = it + 1;
                let pq = dot(&p[c], &q[c]);
                if pq <= 0.0 || !pq.is_finite() {
                    continue; // breakdown: keep the iterate, report its residual
                }
                let alpha = rz[c] / pq;
                for i in 0..n {
                    x[c][i] += alpha * p[c][i];
                    r[c][i] -= alpha * q[c][i];
                }
                res[c] = dot(&r[c], &r[c]).sqrt() / norm_b[c];
                if res[c] <= tolerance {
                    continue;
                }
                precondition(&r[c], &mut z[c]);
                let rz_new = dot(&r[c], &z[c]);
                let beta = rz_new / rz[c];
                rz[c] = rz_new;
                for i in 0..n {
                    p[c][i] = z[c][i] + beta * p[c][i];
                }
                still.push(c);
            }
            active = still;
        }
        x.into_iter()
            .zip(iterations)
            .zip(res)
            .map(|((x, it), r)| (x, it, r))
            .collect()
    }
}

/// The diagonal `L_jj` of the factor (in the permuted order).
fn diagonal(sym: &SymbolicCholesky<usize>, values: &[f64]) -> Vec<f64> {
    match sym.raw() {
        SymbolicCholeskyRaw::Supernodal(s) => {
            let l = supernodal::SupernodalLltRef::new(s, values);
            (0..s.n_supernodes())
                .flat_map(|k| {
                    let v = l.supernode(k).val();
                    (0..v.ncols()).map(move |j| v[(j, j)]).collect::<Vec<_>>()
                })
                .collect()
        }
        SymbolicCholeskyRaw::Simplicial(s) => {
            let (cp, ri) = (s.col_ptr(), s.row_idx());
            (0..s.ncols())
                .map(|j| {
                    (cp[j]..cp[j + 1])
                        .find(|&t| ri[t] == j)
                        .map_or(0.0, |t| values[t])
                })
                .collect()
        }
    }
}

/// `z = K~ (K~^T r)`: `u = K~^T r` (one dot product per sample, from the CSC columns), then
/// `z = K~ u` (gathered from the CSR rows).
fn local_apply(csc: &CsMat<f64>, csr: &CsMat<f64>, r: &[f64], z: &mut [f64]) {
    let m = csc.cols();
    let (ip, ix, dv) = (csc.indptr(), csc.indices(), csc.data());
    let ip = ip.raw_storage();
    let u: Vec<f64> = (0..m)
        .into_par_iter()
        .map(|i| (ip[i]..ip[i + 1]).map(|t| dv[t] * r[ix[t]]).sum())
        .collect();
    let (rp, rx, rv) = (csr.indptr(), csr.indices(), csr.data());
    let rp = rp.raw_storage();
    z.par_iter_mut().enumerate().for_each(|(a, za)| {
        *za = (rp[a]..rp[a + 1]).map(|t| rv[t] * u[rx[t]]).sum();
    });
}
