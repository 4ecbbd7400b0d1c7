//! The Cohen–Daubechies–Vial (CDV) construction of edge scaling functions and edge wavelets,
//! from first principles.
//!
//! Conventions (those of the CDV tables): the interior scaling function `phi` has support
//! `[-p+1, p]` and satisfies `phi(x) = sqrt2 sum_{i=-p+1}^{p} hc_i phi(2x - i)`,
//! `hc_i = h_{i+p-1}`. On the half line `[0, inf)` the interior translates `phi(x - m)`,
//! `m >= p`, are kept, and `p` edge functions replace the others.
//!
//! 1. *Polynomial edge functions.* With `y_{d,l} = int x^d phi(x - l) dx` (exact moments from the
//!    refinement equation), `x^d = sum_l y_{d,l} phi(x - l)` for `d < p`, and
//!    `E_d = sum_{l=-p+1}^{p-1} y_{d,l} phi(x - l) 1_{x >= 0}` is `x^d` minus the kept interior
//!    terms. Scaling `x -> 2x` gives the exact refinement
//!    `E_d(x) = 2^-d E_d(2x) + sum_{m=p}^{3p-2} c_{d,m} phi(2x - m)` and, because `E(2x)` is
//!    orthogonal to every kept fine translate, the Gram matrix solves
//!    `G = (D G D + C C^T) / 2`, i.e. `G_ab = (C C^T)_ab / (2 - 2^-(a+b))`.
//! 2. *Nested supports.* Combinations `B E` whose `k`-th row uses only truncated translates
//!    `l <= k` have support `[0, p + k]`; a Cholesky factorization `B G B^T = L L^T` (positive
//!    diagonal) orthonormalizes them along the nested supports: `phi_L = L^-1 B E`.
//!    Their refinement matrices are `H = Q D Q^-1 / sqrt2`, `h = Q C / sqrt2` with `Q = L^-1 B`,
//!    so that `phi_L(x) = sqrt2 H phi_L(2x) + sqrt2 h Phi(2x)`; the eigenvalues of `sqrt2 H`
//!    are `1, 1/2, ..., 2^-(p-1)`.
//! 3. *Polish.* The Gram matrix of the functions that `(H, h)` define is recomputed exactly from
//!    the Stein equation `G = H G H^T + h h^T` and a second lower-triangular orthonormalization
//!    removes the rounding of step 2 (span and nesting are unchanged).
//! 4. *Edge wavelets.* Edge wavelet `k` lives on the fine edge functions and the fine interior
//!    translates `m = p..p+2k` and is orthogonal to all coarse edge functions and to the coarse
//!    interior scaling functions and wavelets that overlap it: it spans the one new direction of
//!    that null space (nested, completed by orthogonal complement).
//!
//! The right edge is the left construction for the reversed filter, reflected.

use nalgebra::{DMatrix, DVector};

use super::filters::binomial;
use super::BasisError;

/// The interior filter pair and the exact facts about `phi` and `psi` derived from it.
#[derive(Clone, Debug)]
pub struct InteriorFilters {
    /// Vanishing moments `p`.
    pub p: usize,
    /// Low-pass `h_0..h_{2p-1}` (standard indexing, `phi` on `[0, 2p-1]`).
    pub h: Vec<f64>,
    /// High-pass `g_k = (-1)^k h_{2p-1-k}`.
    pub g: Vec<f64>,
    /// `phi_std(k)` for `k = 0..2p-2` (right limits): eigenvector of `T_0` with `sum = 1`.
    pub values_at_integers: Vec<f64>,
    /// `phi_std(k + 1)` left limits for `k = 0..2p-2`: fixed point of `T_1`, used at `x = 1`.
    pub left_limits_at_integers: Vec<f64>,
    /// Moments `M_r = int x^r phi_cdv(x) dx`, `r < p` (CDV support `[-p+1, p]`).
    pub moments: Vec<f64>,
    /// Moments `int x^r psi_cdv(x) dx`, `r < p` (all zero up to rounding).
    pub wavelet_moments: Vec<f64>,
}

impl InteriorFilters {
    /// Builds the interior facts from an orthonormal low-pass filter of length `2p`.
    pub fn new(h: &[f64]) -> Result<Self, BasisError> {
        let p = h.len() / 2;
        let g: Vec<f64> = (0..2 * p).map(|k| sign(k) * h[2 * p - 1 - k]).collect();
        let w = 2 * p - 1;
        let t = |d: usize| digit_matrix(h, d);
        let values_at_integers = fixed_point(&t(0), w, 1.0)?;
        let left_limits_at_integers = fixed_point(&t(1), w, 1.0)?;
        let hc = |i: i64| h[(i + p as i64 - 1) as usize];
        let gc = |i: i64| g[(i + p as i64 - 1) as usize];
        let range = || (-(p as i64) + 1)..=(p as i64);
        // a_q = sum_i hc_i i^q / sqrt2; M_r (1 - 2^-r) = 2^-r sum_{s<r} C(r,s) a_{r-s} M_s.
        let a: Vec<f64> = (0..p)
            .map(|q| {
                range()
                    .map(|i| hc(i) * (i as f64).powi(q as i32))
                    .sum::<f64>()
                    / SQRT2
            })
            .collect();
        let mut moments = vec![1.0; p];
        for r in 1..p {
            let s_sum: f64 = (0..r).map(|s| binomial(r, s) * a[r - s] * moments[s]).sum();
            let scale = 0.5f64.powi(r as i32);
            moments[r] = scale * s_sum / (1.0 - scale);
        }
        // int x^r psi(x) = 2^-r / sqrt2 sum_i gc_i sum_s C(r,s) i^(r-s) M_s.
        let wavelet_moments = (0..p)
            .map(|r| {
                let scale = 0.5f64.powi(r as i32) / SQRT2;
                scale
                    * range()
                        .map(|i| {
                            gc(i)
                                * (0..=r)
                                    .map(|s| {
                                        binomial(r, s)
                                            * (i as f64).powi((r - s) as i32)
                                            * moments[s]
                                    })
                                    .sum::<f64>()
                        })
                        .sum::<f64>()
            })
            .collect();
        Ok(Self {
            p,
            h: h.to_vec(),
            g,
            values_at_integers,
            left_limits_at_integers,
            moments,
            wavelet_moments,
        })
    }

    /// `hc_i = h_{i+p-1}` for `i` in `[-p+1, p]`, zero outside.
    pub fn hc(&self, i: i64) -> f64 {
        let k = i + self.p as i64 - 1;
        if (0..2 * self.p as i64).contains(&k) {
            self.h[k as usize]
        } else {
            0.0
        }
    }

    /// `gc_i = g_{i+p-1}` for `i` in `[-p+1, p]`, zero outside.
    pub fn gc(&self, i: i64) -> f64 {
        let k = i + self.p as i64 - 1;
        if (0..2 * self.p as i64).contains(&k) {
            self.g[k as usize]
        } else {
            0.0
        }
    }

    /// `phi_cdv(c)` at an integer `c` (right limit).
    pub fn phi_at_integer(&self, c: i64) -> f64 {
        let k = c + self.p as i64 - 1;
        if (0..(2 * self.p as i64 - 1)).contains(&k) {
            self.values_at_integers[k as usize]
        } else {
            0.0
        }
    }

    /// `y_{d,l} = int x^d phi_cdv(x - l) dx = sum_s C(d,s) l^(d-s) M_s`.
    pub fn translate_moment(&self, d: usize, l: i64) -> f64 {
        (0..=d)
            .map(|s| binomial(d, s) * (l as f64).powi((d - s) as i32) * self.moments[s])
            .sum()
    }
}

pub(crate) const SQRT2: f64 = std::f64::consts::SQRT_2;

fn sign(k: usize) -> f64 {
    if k % 2 == 0 {
        1.0
    } else {
        -1.0
    }
}

/// `(T_d)_{i,l} = sqrt2 h_{2i+d-l}`, `i, l < 2p-1`: `v((t+d)/2) = T_d v(t)` for
/// `v(t) = (phi(t), ..., phi(t+2p-2))`.
pub(crate) fn digit_matrix(filter: &[f64], d: usize) -> DMatrix<f64> {
    let w = filter.len() - 1;
    DMatrix::from_fn(w, w, |i, l| {
        let k = 2 * i as i64 + d as i64 - l as i64;
        if (0..filter.len() as i64).contains(&k) {
            SQRT2 * filter[k as usize]
        } else {
            0.0
        }
    })
}

/// Eigenvector of `t` for eigenvalue 1 normalized to `sum = total`.
fn fixed_point(t: &DMatrix<f64>, w: usize, total: f64) -> Result<Vec<f64>, BasisError> {
    if w == 1 {
        return Ok(vec![total]);
    }
    // Replace the last equation of (T - I) v = 0 by sum v = total.
    let mut a = t - DMatrix::identity(w, w);
    let mut b = DVector::zeros(w);
    for l in 0..w {
        a[(w - 1, l)] = 1.0;
    }
    b[w - 1] = total;
    let v = a.lu().solve(&b).ok_or(BasisError::Construction {
        step: "values at the integers",
        detail: "the refinement matrix has no unique fixed point".into(),
    })?;
    Ok(v.iter().copied().collect())
}

/// Refinement matrices and exact facts of one edge (left edge of the given interior filter).
#[derive(Clone, Debug)]
pub struct EdgeFilters {
    /// Number of edge functions `p`.
    pub count: usize,
    /// `H[k, l]`: edge scaling `k` on fine edge scaling `l`.
    pub h_edge: DMatrix<f64>,
    /// `h[k, m - p]`: edge scaling `k` on fine interior translate `m = p..3p-2`.
    pub h_interior: DMatrix<f64>,
    /// `G[k, l]`: edge wavelet `k` on fine edge scaling `l`.
    pub g_edge: DMatrix<f64>,
    /// `g[k, m - p]`: edge wavelet `k` on fine interior translate `m`.
    pub g_interior: DMatrix<f64>,
    /// `phi_L_k(c)` for `c = 0..2p-2`, as `[c][k]`.
    pub values_at_integers: Vec<Vec<f64>>,
    /// `int x^d phi_L_k(x) dx`, `[k][d]`, `d < p`.
    pub scaling_moments: Vec<Vec<f64>>,
    /// `int x^d psi_L_k(x) dx`, `[k][d]`, `d < p` (zero up to rounding).
    pub wavelet_moments: Vec<Vec<f64>>,
    /// Max deviation from the identity of the exact Gram matrix of the edge scaling functions
    /// (Stein equation), and of their inner products with the kept interior translates.
    pub gram_error: f64,
}

impl EdgeFilters {
    /// CDV left-edge construction for the interior filter `int`.
    pub fn left(int: &InteriorFilters) -> Result<Self, BasisError> {
        let p = int.p;
        let w = 2 * p - 1;
        // Nested edge functions in the coordinates of the truncated translates
        // T_l = phi(x - l) 1_{x >= 0}, l = -p+1..p-1 (column l + p - 1):
        // F_k = sum_{l <= k} q_k(l) T_l, q_k(l) = prod_{i=k+1}^{p-1} (l - i) / scale.
        let mut qt = DMatrix::<f64>::zeros(p, w);
        for k in 0..p {
            for l in (-(p as i64) + 1)..=(k as i64) {
                let v: f64 = ((k + 1)..p).map(|i| (l - i as i64) as f64).product();
                qt[(k, (l + p as i64 - 1) as usize)] = v;
            }
            // Positive coefficient on T_k: the sign convention of the published tables.
            let scale = qt.row(k).amax() * qt[(k, k + p - 1)].signum();
            qt.row_mut(k).scale_mut(1.0 / scale);
        }
        // Refinement of the translates: T_l = sqrt2 sum_i hc_i T'_{2l+i} (fine edge coordinates
        // for 2l+i <= p-1, fine interior translates phi(2x - q), q = p..3p-2, beyond).
        let mut re = DMatrix::<f64>::zeros(w, w);
        let mut ri = DMatrix::<f64>::zeros(w, w);
        for l in (-(p as i64) + 1)..(p as i64) {
            for i in (-(p as i64) + 1)..=(p as i64) {
                let q = 2 * l + i;
                let row = (l + p as i64 - 1) as usize;
                if q < -(p as i64) + 1 {
                    continue; // entirely on the negative axis: vanishes on [0, inf)
                } else if q < p as i64 {
                    re[(row, (q + p as i64 - 1) as usize)] += int.hc(i);
                } else {
                    ri[(row, (q - p as i64) as usize)] += int.hc(i);
                }
            }
        }
        // The edge part stays in the nested space (dilation maps polynomials to polynomials):
        // Q R_e = M Q, solved by least squares, its residual measured.
        let lhs = &qt * &re;
        let mt = qt
            .transpose()
            .svd(true, true)
            .solve(&lhs.transpose(), 1e-300)
            .map_err(|_| singular("edge dilation"))?;
        let m = mt.transpose();
        let consistency = (&m * &qt - &lhs).amax();
        if consistency > 1e-8 {
            return Err(BasisError::Construction {
                step: "edge dilation",
                detail: format!("polynomial edge space not invariant ({consistency:e})"),
            });
        }
        let mut h_edge = m;
        let mut h_interior = &qt * &ri;
        // Orthonormalize along the nested supports: Gram from the Stein equation
        // G = H G H^T + h h^T, Cholesky with positive diagonal; repeated until the Gram matrix
        // is the identity to rounding (the first pass may be ill-conditioned for large p).
        for _ in 0..4 {
            let g = stein(&h_edge, &(&h_interior * h_interior.transpose()));
            let l = cholesky_lower(&g, "edge Gram matrix")?;
            // Triangular solves keep the nested zero pattern exactly.
            h_edge = l
                .solve_lower_triangular(&(&h_edge * &l))
                .ok_or_else(|| singular("edge Gram factor"))?;
            h_interior = l
                .solve_lower_triangular(&h_interior)
                .ok_or_else(|| singular("edge Gram factor"))?;
        }
        // The nested supports: h[k, m] = 0 for m > p + 2k, exactly (structural).
        debug_assert!((0..p).all(|k| ((2 * k + 1)..w).all(|j| h_interior[(k, j)] == 0.0)));
        let (g_edge, g_interior) = edge_wavelets(int, &h_edge, &h_interior)?;
        let gram_error = edge_gram_error(int, &h_edge, &h_interior);
        let values_at_integers = edge_values_at_integers(int, &h_edge, &h_interior)?;
        let scaling_moments = edge_moments(int, &h_edge, &h_interior, None);
        let wavelet_moments = edge_moments(int, &h_edge, &h_interior, Some((&g_edge, &g_interior)));
        Ok(Self {
            count: p,
            h_edge,
            h_interior,
            g_edge,
            g_interior,
            values_at_integers,
            scaling_moments,
            wavelet_moments,
            gram_error,
        })
    }
}

fn singular(what: &'static str) -> BasisError {
    BasisError::Construction {
        step: what,
        detail: "matrix is singular".into(),
    }
}

fn cholesky_lower(a: &DMatrix<f64>, what: &'static str) -> Result<DMatrix<f64>, BasisError> {
    let sym = (a + a.transpose()) * 0.5;
    sym.cholesky()
        .map(|c| c.l())
        .ok_or(BasisError::Construction {
            step: what,
            detail: "not positive definite".into(),
        })
}

/// Solves `G = A G A^T + C` by doubling (`rho(A) < 1`).
fn stein(a: &DMatrix<f64>, c: &DMatrix<f64>) -> DMatrix<f64> {
    let mut g = c.clone();
    let mut ak = a.clone();
    for _ in 0..12 {
        g = &g + &ak * &g * ak.transpose();
        ak = &ak * &ak;
    }
    g
}

/// Inner products `X[k, m] = <phi_L_k, phi(. - m)>`, `m = p..3p-3`, from
/// `X_{k,m} = sum_i hc_i (sum_l H_kl X_{l,2m+i} + h_{k,2m+i})`, solved as a linear system;
/// returns max |G - I| over the edge Gram matrix and |X|.
fn edge_gram_error(int: &InteriorFilters, h_edge: &DMatrix<f64>, h_int: &DMatrix<f64>) -> f64 {
    let p = int.p;
    let g = stein(h_edge, &(h_int * h_int.transpose()));
    let mut err = (g - DMatrix::identity(p, p)).amax();
    let nm = 2 * p - 2;
    if nm == 0 {
        return err;
    }
    let n = p * nm;
    let idx = |k: usize, m: usize| k * nm + (m - p);
    let mut a = DMatrix::<f64>::identity(n, n);
    let mut b = DVector::<f64>::zeros(n);
    for k in 0..p {
        for m in p..(3 * p - 2) {
            let row = idx(k, m);
            for i in (-(p as i64) + 1)..=(p as i64) {
                let q = 2 * m as i64 + i;
                let hci = int.hc(i);
                if q >= p as i64 && q <= 3 * p as i64 - 2 {
                    b[row] += hci * h_int[(k, q as usize - p)];
                }
                if q >= p as i64 && q < 3 * p as i64 - 2 {
                    for l in 0..p {
                        a[(row, idx(l, q as usize))] -= hci * h_edge[(k, l)];
                    }
                }
            }
        }
    }
    if let Some(x) = a.lu().solve(&b) {
        err = err.max(x.amax());
    } else {
        err = f64::INFINITY;
    }
    err
}

/// Edge wavelets by nested orthogonal complement (module docs, step 4).
fn edge_wavelets(
    int: &InteriorFilters,
    h_edge: &DMatrix<f64>,
    h_int: &DMatrix<f64>,
) -> Result<(DMatrix<f64>, DMatrix<f64>), BasisError> {
    let p = int.p;
    let w = 2 * p - 1;
    let width = p + w; // fine columns: edge 0..p-1, interior p..3p-2
    let mut found: Vec<DVector<f64>> = Vec::new();
    for k in 0..p {
        let cols = p + 2 * k + 1;
        // Constraint rows restricted to the window.
        let mut rows: Vec<Vec<f64>> = Vec::new();
        for r in 0..p {
            let mut row = vec![0.0; cols];
            for l in 0..p {
                row[l] = h_edge[(r, l)];
            }
            for j in 0..(cols - p) {
                row[p + j] = h_int[(r, j)];
            }
            rows.push(row);
        }
        for mp in p..(p + k) {
            for wavelet in [false, true] {
                let mut row = vec![0.0; cols];
                for (j, item) in row.iter_mut().enumerate().skip(p) {
                    let i = j as i64 - 2 * mp as i64;
                    *item = if wavelet { int.gc(i) } else { int.hc(i) };
                }
                rows.push(row);
            }
        }
        // Full SVD (faer): the right singular vectors of the smallest singular values span the
        // null space.
        let m = faer::Mat::<f64>::from_fn(rows.len(), cols, |i, j| rows[i][j]);
        let svd = m.svd().map_err(|_| singular("edge wavelet null space"))?;
        let sv: Vec<f64> = (0..cols)
            .map(|i| {
                if i < rows.len().min(cols) {
                    svd.S().column_vector()[i]
                } else {
                    0.0
                }
            })
            .collect();
        let vmat = svd.V();
        let mut order: Vec<usize> = (0..cols).collect();
        order.sort_by(|&a, &b| sv[a].total_cmp(&sv[b]));
        let nullity = k + 1;
        let small = sv[order[nullity - 1]];
        let next = order.get(nullity).map_or(f64::INFINITY, |&i| sv[i]);
        if small > 1e-9 || next < 1e-7 {
            return Err(BasisError::Construction {
                step: "edge wavelets",
                detail: format!(
                    "null space of wavelet {k} has unexpected dimension (s = {small:e}, next {next:e})"
                ),
            });
        }
        // Project the null space off the previous wavelets; the largest remaining direction.
        let z = DMatrix::from_fn(cols, nullity, |i, j| vmat[(i, order[j])]);
        let mut zp = z.clone();
        for prev in &found {
            let pv = DVector::from_fn(cols, |i, _| if i < prev.len() { prev[i] } else { 0.0 });
            let coef = pv.transpose() * &zp;
            zp -= &pv * coef;
        }
        // What is left is one direction (plus rounding): its largest column.
        let best = (0..nullity)
            .max_by(|&a, &b| zp.column(a).norm().total_cmp(&zp.column(b).norm()))
            .unwrap_or(0);
        let mut v: DVector<f64> = zp.column(best).into_owned();
        // Re-orthogonalize against the previous ones and normalize.
        for prev in &found {
            let d: f64 = (0..prev.len()).map(|i| prev[i] * v[i]).sum();
            for i in 0..prev.len() {
                v[i] -= d * prev[i];
            }
        }
        let norm = v.norm();
        v /= norm;
        if v[cols - 1] < 0.0 {
            v = -v;
        }
        found.push(v);
    }
    let mut g_edge = DMatrix::zeros(p, p);
    let mut g_int = DMatrix::zeros(p, w);
    for (k, v) in found.iter().enumerate() {
        for l in 0..p {
            g_edge[(k, l)] = v[l];
        }
        for j in p..v.len() {
            g_int[(k, j - p)] = v[j];
        }
    }
    debug_assert_eq!(width, p + w);
    Ok((g_edge, g_int))
}

/// `phi_L(c)` at the integers `c = 0..2p-2`: `phi_L(0)` is the eigenvector of `sqrt2 H` for
/// eigenvalue 1 with `mu_0 . phi_L(0) = 1` (the constant reproduced at `x = 0`); larger `c`
/// follow top-down from `phi_L(c) = sqrt2 H phi_L(2c) + sqrt2 h Phi(2c)`.
fn edge_values_at_integers(
    int: &InteriorFilters,
    h_edge: &DMatrix<f64>,
    h_int: &DMatrix<f64>,
) -> Result<Vec<Vec<f64>>, BasisError> {
    let p = int.p;
    let w = 2 * p - 1;
    let mu = edge_moments(int, h_edge, h_int, None);
    let mut a = h_edge * SQRT2 - DMatrix::identity(p, p);
    let mut b = DVector::zeros(p);
    for k in 0..p {
        a[(p - 1, k)] = mu[k][0];
    }
    b[p - 1] = 1.0;
    // The eigenvalue-1 eigenvector: replace the last equation by the normalization.
    let v0 = a
        .lu()
        .solve(&b)
        .ok_or_else(|| singular("edge values at 0"))?;
    let mut vals = vec![vec![0.0; p]; w];
    vals[0] = v0.iter().copied().collect();
    for c in (1..w).rev() {
        for k in 0..p {
            let mut s = 0.0;
            if 2 * c < w {
                for l in 0..p {
                    s += h_edge[(k, l)] * vals[2 * c][l];
                }
            }
            for j in 0..w {
                let m = (j + p) as i64;
                s += h_int[(k, j)] * int.phi_at_integer(2 * c as i64 - m);
            }
            vals[c][k] = SQRT2 * s;
        }
    }
    Ok(vals)
}

/// Moments `int x^d f_k(x) dx` of the edge scaling functions (`wavelet = None`) or edge
/// wavelets: `(I - 2^-(d+1/2) H) mu_d = 2^-(d+1/2) h y_d`, then
/// `nu_d = 2^-(d+1/2) (G mu_d + g y_d)`.
fn edge_moments(
    int: &InteriorFilters,
    h_edge: &DMatrix<f64>,
    h_int: &DMatrix<f64>,
    wavelet: Option<(&DMatrix<f64>, &DMatrix<f64>)>,
) -> Vec<Vec<f64>> {
    let p = int.p;
    let w = 2 * p - 1;
    let mut out = vec![vec![0.0; p]; p];
    for d in 0..p {
        let s = 0.5f64.powi(d as i32) / SQRT2;
        let y = DVector::from_fn(w, |j, _| int.translate_moment(d, (j + p) as i64));
        let a = DMatrix::identity(p, p) - h_edge * s;
        let rhs = h_int * &y * s;
        let mu = a.lu().solve(&rhs).unwrap_or_else(|| DVector::zeros(p));
        let res = match wavelet {
            None => mu,
            Some((ge, gi)) => (ge * &mu + gi * &y) * s,
        };
        for (k, row) in out.iter_mut().enumerate() {
            row[d] = res[k];
        }
    }
    out
}
