//! Exact integrals of the single-scale functions `phi_{J,k}` of `V_J` over arbitrary intervals,
//! and their polynomial moments, by the digit recursion of [`super::eval`] run on antiderivatives.
//!
//! Interior function (standard indexing, support `[0, 2p-1]`,
//! `phi(s) = sum_k c_k phi(2s - k)`, `c_k = sqrt2 h_k`): its moment antiderivatives
//! `M_d(y) = int_0^y s^d phi(s) ds` satisfy
//!
//! `M_d(y) = 2^{-d-1} sum_k c_k sum_{e <= d} C(d, e) k^{d-e} M_e(2y - k)`,
//!
//! with `M_e = 0` left of the support and `M_e = mu_e = int s^e phi` right of it (`M_0` is the
//! antiderivative `Phi`, `mu_0 = 1`). For `t` in `[0, 1)` the state
//! `X(t) = (M_d(t + i))_{d <= D, i < 2p-1}` therefore obeys the affine digit relation
//! `X((t + b)/2) = A_b X(t) + r_b` (`b` a binary digit; `A_b` is `T_b` of evaluation scaled by
//! `2^{-d-1}` and coupled across `d` by the binomial shifts; `r_b` collects the terms past the
//! support). `X(0)` is the fixed point `(I - A_0) X(0) = r_0` (`A_0` has spectral radius `1/2`),
//! and for `t = 0.b_1 b_2 ... b_K` (every `f64` has finitely many binary digits)
//! `X(frac(2^j t)) = A_{b_{j+1}} (... (A_{b_K} X(0) + r_{b_K}) ...) + r_{b_{j+1}}`: exact to
//! rounding, and the maps are contractions, so rounding does not grow along the walk.
//!
//! Left edge functions (`phi_L(u) = sqrt2 H phi_L(2u) + sqrt2 h Phi(2u)`, support in
//! `[0, 2p-1]`): `Y_d(u) = int_0^u s^d phi_L(s) ds` obeys
//! `Y_d(u) = 2^{-d-1} (sqrt2 H Y_d(2u) + sqrt2 h Z_d(2u))`,
//! `Z_d(y)_q = int_0^y z^d phi(z - q - 1) dz = sum_e C(d, e) (q+1)^{d-e} M_e(y - q - 1)`
//! (the fine interior translates `m = p + q`). It starts where the point leaves the support
//! (`Y_d = nu_d = int s^d phi_L`, from `(I - 2^{-d-1} sqrt2 H) nu_d = 2^{-d-1} sqrt2 h Z_d(inf)`)
//! or becomes an integer (`Y_d(c)`, `c < 2p - 1`, solved top-down from the same relation),
//! exactly as evaluation starts its edge recursion. The right edge is the left construction of
//! the reversed filter in the reflected coordinate `1 - t` (exact in `f64` for `t >= 1/2`; at
//! `t < 1/2` the right edge functions are already complete, since `2^J >= 4p - 2`).
//!
//! For `phi_{J,k}(t) = 2^{J/2} phi(sigma_k(t))` with its own variable
//! `sigma_k(t) = 2^J t - k + p - 1` (interior), `2^J t` (left edge) or `2^J (1 - t)` (right
//! edge), `F_{k,d}(t) = int_0^t sigma_k^d phi_{J,k}` is `2^{-J/2}` times the state above, and
//! `int_a^b sigma_k^d phi_{J,k} = F_{k,d}(b) - F_{k,d}(a)`. On a domain `[A, A + L]` the basis
//! is `L^{-1/2} phi_{J,k}((x - A)/L)`, so domain integrals carry the Jacobian `L^{1/2}`.
//! Degree `D = 0` gives the plain integrals `int_a^b phi_{J,k}` (the box pixel filter); higher
//! degrees give exact integrals against polynomial pieces (film filters).
//!
//! Accuracy: every quantity is a finite composition of the refinement relation, so the result
//! is exact up to rounding. Absolute rounding is `O(eps (2p)^d)` in the `sigma` variable; a
//! moment in a variable `u = (x - a)/(b - a)` over a short interval amplifies it by
//! `(2^J (b - a) / L)^{-d}` (the cancellation of two antiderivatives).
//!
//! Length: about 700 lines on purpose. Interior moments, edge moments and the public
//! interval integrals are one construction sharing the digit walk (`Dyadic`) and its
//! scratch state; split across files they would have to expose those internals to each other.

use nalgebra::{DMatrix, DVector};

use super::filters::binomial;
use super::{BasisError, BasisValue, CdvBasis, FilterBank};
use crate::domain::Domain;

/// Largest polynomial degree supported for moments (film filters need at most cubics).
pub const MAX_MOMENT_DEGREE: usize = 7;

/// A position `t = m 2^-k` in `[0, 1]` (`m` odd or `m = 0`); `t = 1` is `m = 1, k = 0`.
#[derive(Clone, Copy, Debug)]
struct Dyadic {
    m: u64,
    k: u32,
}

impl Dyadic {
    fn new(t: f64) -> Self {
        if t >= 1.0 {
            return Self { m: 1, k: 0 };
        }
        if t <= 0.0 {
            return Self { m: 0, k: 0 };
        }
        let (m, k) = super::digits::odd_mantissa(t);
        Self { m, k }
    }

    /// `floor(2^j t)` (`2^j` at `t = 1`).
    fn cell(&self, j: u32) -> u64 {
        super::digits::dyadic_cell(self.m, self.k, j)
    }

    /// Binary digit `b_i` of `t = 0.b_1 b_2 ...`.
    fn digit(&self, i: u32) -> usize {
        super::digits::dyadic_digit(self.m, self.k, i)
    }
}

/// The affine digit maps of one interior filter for moments up to degree `D`.
#[derive(Clone, Debug)]
struct InteriorMoments {
    /// `2p - 1`.
    w: usize,
    /// `D + 1`.
    nd: usize,
    /// `A_b`, row-major `(nd w) x (nd w)`, state index `d * w + i`.
    a: [Vec<f64>; 2],
    /// `r_b`.
    r: [Vec<f64>; 2],
    /// `X(0)`: `M_d(i)` at the integers.
    x0: Vec<f64>,
    /// `mu_d = int s^d phi`.
    mu: Vec<f64>,
}

impl InteriorMoments {
    fn new(h: &[f64], degree: usize) -> Result<Self, BasisError> {
        let w = h.len() - 1;
        let nd = degree + 1;
        let n = nd * w;
        let c: Vec<f64> = h.iter().map(|x| x * std::f64::consts::SQRT_2).collect();
        // mu_r (1 - 2^-r) = 2^{-r-1} sum_k c_k sum_{e<r} C(r,e) k^{r-e} mu_e.
        let mut mu = vec![1.0; nd];
        for r in 1..nd {
            let s: f64 = (0..r)
                .map(|e| {
                    binomial(r, e)
                        * mu[e]
                        * c.iter()
                            .enumerate()
                            .map(|(k, ck)| ck * (k as f64).powi((r - e) as i32))
                            .sum::<f64>()
                })
                .sum();
            let scale = 0.5f64.powi(r as i32);
            mu[r] = 0.5 * scale * s / (1.0 - scale);
        }
        let mut a = [vec![0.0; n * n], vec![0.0; n * n]];
        let mut r = [vec![0.0; n], vec![0.0; n]];
        for b in 0..2 {
            for d in 0..nd {
                let sd = 0.5f64.powi(d as i32 + 1);
                for i in 0..w {
                    let row = d * w + i;
                    for (k, ck) in c.iter().enumerate() {
                        let l = 2 * i as i64 + b as i64 - k as i64;
                        if l < 0 {
                            continue;
                        }
                        for e in 0..=d {
                            let coef = sd * ck * binomial(d, e) * (k as f64).powi((d - e) as i32);
                            if l >= w as i64 {
                                r[b][row] += coef * mu[e];
                            } else {
                                a[b][row * n + e * w + l as usize] += coef;
                            }
                        }
                    }
                }
            }
        }
        let am = DMatrix::from_row_slice(n, n, &a[0]);
        let lhs = DMatrix::identity(n, n) - am;
        let x0 =
            lhs.lu()
                .solve(&DVector::from_column_slice(&r[0]))
                .ok_or(BasisError::Construction {
                    step: "antiderivatives at the integers",
                    detail: "I - A_0 is singular".into(),
                })?;
        Ok(Self {
            w,
            nd,
            a,
            r,
            x0: x0.iter().copied().collect(),
            mu,
        })
    }

    /// `M_e(y)` at `y = frac + i` for a state `x` at that fractional part.
    #[inline]
    fn value(&self, x: &[f64], e: usize, i: i64) -> f64 {
        if i < 0 {
            0.0
        } else if i >= self.w as i64 {
            self.mu[e]
        } else {
            x[e * self.w + i as usize]
        }
    }

    /// States `X(frac(2^j t))` for `j = lo..=hi` into `out` (`(hi - lo + 1) * nd * w`).
    fn walk(&self, pos: &Dyadic, lo: u32, hi: u32, out: &mut Vec<f64>, tmp: &mut Vec<f64>) {
        let n = self.nd * self.w;
        let levels = (hi - lo + 1) as usize;
        out.clear();
        out.resize(levels * n, 0.0);
        tmp.clear();
        tmp.extend_from_slice(&self.x0);
        let mut next = vec![0.0; n];
        // Digits hi+1..=K, the last first.
        let mut i = pos.k;
        while i > hi {
            self.step(pos.digit(i), tmp, &mut next);
            std::mem::swap(tmp, &mut next);
            i -= 1;
        }
        let top = (levels - 1) * n;
        out[top..top + n].copy_from_slice(tmp);
        for j in (lo..hi).rev() {
            let l = (j - lo) as usize;
            let (below, above) = out.split_at_mut((l + 1) * n);
            self.step(pos.digit(j + 1), &above[..n], &mut below[l * n..]);
        }
    }

    #[inline]
    fn step(&self, b: usize, x: &[f64], y: &mut [f64]) {
        let n = self.nd * self.w;
        let a = &self.a[b];
        for (row, yr) in y.iter_mut().enumerate().take(n) {
            let ar = &a[row * n..(row + 1) * n];
            *yr = self.r[b][row] + ar.iter().zip(x).map(|(p, q)| p * q).sum::<f64>();
        }
    }
}

/// The moment recursion of one edge (left edge of a filter).
#[derive(Clone, Debug)]
struct EdgeMoments {
    /// `p`.
    count: usize,
    /// `sqrt2 H`, `p x p` row-major.
    h_edge: Vec<f64>,
    /// `sqrt2 h`, `p x (2p-1)` row-major.
    h_interior: Vec<f64>,
    /// `nu_d`, `[d * p + k]`.
    totals: Vec<f64>,
    /// `Y_d(c)` at the integers `c < 2p - 1`, `[c][d * p + k]`.
    at_integers: Vec<Vec<f64>>,
}

impl EdgeMoments {
    fn new(e: &super::cdv::EdgeFilters, int: &InteriorMoments) -> Result<Self, BasisError> {
        let p = e.count;
        let w = int.w;
        let nd = int.nd;
        let flat = |m: &DMatrix<f64>| -> Vec<f64> {
            let mut out = Vec::with_capacity(m.nrows() * m.ncols());
            for i in 0..m.nrows() {
                for j in 0..m.ncols() {
                    out.push(std::f64::consts::SQRT_2 * m[(i, j)]);
                }
            }
            out
        };
        let h_edge = flat(&e.h_edge);
        let h_interior = flat(&e.h_interior);
        // Z_d(inf)_q = sum_e C(d,e) (q+1)^{d-e} mu_e.
        let mut totals = vec![0.0; nd * p];
        for d in 0..nd {
            let s = 0.5f64.powi(d as i32 + 1);
            let z: Vec<f64> = (0..w)
                .map(|q| {
                    (0..=d)
                        .map(|e| binomial(d, e) * ((q + 1) as f64).powi((d - e) as i32) * int.mu[e])
                        .sum()
                })
                .collect();
            let hm = DMatrix::from_row_slice(p, p, &h_edge);
            let lhs = DMatrix::identity(p, p) - hm * s;
            let rhs = DVector::from_fn(p, |k, _| {
                s * (0..w).map(|q| h_interior[k * w + q] * z[q]).sum::<f64>()
            });
            let nu = lhs.lu().solve(&rhs).ok_or(BasisError::Construction {
                step: "edge moments",
                detail: "I - 2^{-d-1} sqrt2 H is singular".into(),
            })?;
            totals[d * p..(d + 1) * p].copy_from_slice(nu.as_slice());
        }
        let mut me = Self {
            count: p,
            h_edge,
            h_interior,
            totals,
            at_integers: vec![vec![0.0; nd * p]; w],
        };
        // Y(c), c = w-1 down to 1, from Y(2c) and the interior antiderivatives at integers.
        let mut z = vec![0.0; nd * w];
        for c in (1..w).rev() {
            for d in 0..nd {
                for q in 0..w {
                    let i = 2 * c as i64 - 1 - q as i64;
                    z[d * w + q] = (0..=d)
                        .map(|e| {
                            binomial(d, e)
                                * ((q + 1) as f64).powi((d - e) as i32)
                                * int.value(&int.x0, e, i)
                        })
                        .sum();
                }
            }
            let finer = if 2 * c >= w {
                me.totals.clone()
            } else {
                me.at_integers[2 * c].clone()
            };
            let mut out = vec![0.0; nd * p];
            me.combine(&finer, &z, w, &mut out);
            me.at_integers[c] = out;
        }
        Ok(me)
    }

    /// `Y_d = 2^{-d-1} (sqrt2 H Y_d(finer) + sqrt2 h Z_d)`.
    fn combine(&self, finer: &[f64], z: &[f64], w: usize, out: &mut [f64]) {
        let p = self.count;
        let nd = out.len() / p;
        for d in 0..nd {
            let s = 0.5f64.powi(d as i32 + 1);
            let yf = &finer[d * p..(d + 1) * p];
            let zd = &z[d * w..(d + 1) * w];
            for k in 0..p {
                let he = &self.h_edge[k * p..(k + 1) * p];
                let hi = &self.h_interior[k * w..(k + 1) * w];
                out[d * p + k] = s
                    * (he.iter().zip(yf).map(|(a, b)| a * b).sum::<f64>()
                        + hi.iter().zip(zd).map(|(a, b)| a * b).sum::<f64>());
            }
        }
    }

    /// `Y_d(2^J t)` for all `d`, `k` (as `[d * p + k]`) from the walk states of levels
    /// `J+1..=start` of the matching interior filter.
    fn at(
        &self,
        int: &InteriorMoments,
        pos: &Dyadic,
        level: u32,
        scratch: &mut Scratch,
    ) -> Vec<f64> {
        let p = self.count;
        let w = int.w;
        let nd = int.nd;
        let n = nd * w;
        let mut start = level;
        while pos.cell(start) < w as u64 && start < pos.k {
            start += 1;
        }
        let direct = |j: u32| -> Vec<f64> {
            let c = pos.cell(j);
            if c >= w as u64 {
                self.totals.clone()
            } else {
                self.at_integers[c as usize].clone()
            }
        };
        let mut y = direct(start);
        if start == level {
            return y;
        }
        int.walk(pos, level + 1, start, &mut scratch.states, &mut scratch.tmp);
        let mut z = vec![0.0; n];
        let mut next = vec![0.0; nd * p];
        for j in (level..start).rev() {
            let l = (j + 1 - (level + 1)) as usize;
            let x = &scratch.states[l * n..(l + 1) * n];
            let c = pos.cell(j + 1) as i64;
            for d in 0..nd {
                for q in 0..w {
                    z[d * w + q] = (0..=d)
                        .map(|e| {
                            binomial(d, e)
                                * ((q + 1) as f64).powi((d - e) as i32)
                                * int.value(x, e, c - 1 - q as i64)
                        })
                        .sum();
                }
            }
            self.combine(&y, &z, w, &mut next);
            std::mem::swap(&mut y, &mut next);
        }
        y
    }
}

#[derive(Default)]
struct Scratch {
    states: Vec<f64>,
    tmp: Vec<f64>,
}

/// The moment antiderivatives `F_{k,d}(t)` of every function of `V_J` at one position: functions
/// below `first` are complete (`F = ` their totals), functions at or above `first + len` have not
/// started (`F = 0`).
#[derive(Clone, Debug)]
pub struct Antiderivative {
    /// First function index whose antiderivative is partial at the position.
    pub first: usize,
    /// Number of partial functions (at most `2p`).
    pub len: usize,
    /// `F_{k,d}` for `k = first..first+len`, as `[(k - first) * (D + 1) + d]`, in each function's
    /// own variable `sigma_k`, on the unit interval (without the domain Jacobian).
    pub values: Vec<f64>,
}

/// Exact integrals `int_a^b u^d phi_{J,k}(x) dx` of the scaling functions of one level of a
/// CDV basis over intervals of its domain (module docs give the recursion).
#[derive(Clone, Debug)]
pub struct ScalingIntegrals {
    level: u32,
    size: usize,
    p: usize,
    edges: usize,
    domain: Domain,
    degree: usize,
    forward: InteriorMoments,
    reversed: InteriorMoments,
    left: Option<EdgeMoments>,
    right: Option<EdgeMoments>,
    /// `F_{k,d}(1)`: the complete moments in the own variable, `[k * (D + 1) + d]`.
    totals: Vec<f64>,
}

impl ScalingIntegrals {
    /// Integrals of the scaling functions of level `basis.coarse()` (the single-scale space of a
    /// `Psi(J, J)` basis, as reconstructions are evaluated) on the basis' domain, moments up to
    /// degree `degree` (`0` for plain integrals).
    pub fn new(basis: &CdvBasis, degree: usize) -> Result<Self, BasisError> {
        Self::with_bank(basis.bank(), basis.coarse(), basis.domain(), degree)
    }

    /// As [`ScalingIntegrals::new`] from a filter bank, a level and a domain.
    pub fn with_bank(
        bank: &FilterBank,
        level: u32,
        domain: Domain,
        degree: usize,
    ) -> Result<Self, BasisError> {
        let p = bank.p();
        let minimum = super::minimum_level(p);
        if level < minimum {
            return Err(BasisError::CoarseLevelTooSmall {
                p,
                coarse: level,
                minimum,
            });
        }
        if level > super::MAX_LEVEL {
            return Err(BasisError::FineLevelTooDeep {
                fine: level,
                max: super::MAX_LEVEL,
            });
        }
        if degree > MAX_MOMENT_DEGREE {
            return Err(BasisError::Construction {
                step: "moment degree",
                detail: format!(
                    "degree {degree} is above the supported {MAX_MOMENT_DEGREE}: use a lower degree"
                ),
            });
        }
        let forward = InteriorMoments::new(&bank.interior.h, degree)?;
        let reversed = InteriorMoments::new(&bank.reversed.h, degree)?;
        let left = bank
            .left
            .as_ref()
            .map(|e| EdgeMoments::new(e, &forward))
            .transpose()?;
        let right = bank
            .right
            .as_ref()
            .map(|e| EdgeMoments::new(e, &reversed))
            .transpose()?;
        let size = 1usize << level;
        let edges = bank.edge_count();
        let nd = degree + 1;
        let mut totals = vec![0.0; size * nd];
        let scale = 0.5f64.powf(level as f64 / 2.0);
        for k in 0..size {
            for d in 0..nd {
                let v = if k < edges {
                    left.as_ref().map_or(0.0, |l| l.totals[d * p + k])
                } else if k >= size - edges {
                    right
                        .as_ref()
                        .map_or(0.0, |r| r.totals[d * p + (size - 1 - k)])
                } else {
                    forward.mu[d]
                };
                totals[k * nd + d] = scale * v;
            }
        }
        Ok(Self {
            level,
            size,
            p,
            edges,
            domain,
            degree,
            forward,
            reversed,
            left,
            right,
            totals,
        })
    }

    /// The level `J`.
    pub fn level(&self) -> u32 {
        self.level
    }
    /// `2^J`, the number of functions.
    pub fn size(&self) -> usize {
        self.size
    }
    /// Highest moment degree `D`.
    pub fn degree(&self) -> usize {
        self.degree
    }
    /// The domain `[A, A + L]`.
    pub fn domain(&self) -> Domain {
        self.domain
    }

    /// `F_{k,d}(t)` at a unit position `t` in `[0, 1]` (clamped), module docs.
    pub fn antiderivative_unit(&self, t: f64) -> Antiderivative {
        let mut scratch = Scratch::default();
        self.antiderivative_with(t, &mut scratch)
    }

    fn antiderivative_with(&self, t: f64, scratch: &mut Scratch) -> Antiderivative {
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        let pos = Dyadic::new(t);
        let j = self.level;
        let p = self.p as i64;
        let nd = self.degree + 1;
        let c = pos.cell(j) as i64;
        let first = (c - p + 1).clamp(0, self.size as i64) as usize;
        let end = (c + p).clamp(0, self.size as i64) as usize;
        let len = end - first;
        let mut values = vec![0.0; len * nd];
        let scale = 0.5f64.powf(j as f64 / 2.0);
        let fw = &self.forward;
        let n = fw.nd * fw.w;
        // Interior states at level J.
        fw.walk(&pos, j, j, &mut scratch.states, &mut scratch.tmp);
        let x = scratch.states[..n].to_vec();
        let left_vals = if first < self.edges {
            self.left.as_ref().map(|l| l.at(fw, &pos, j, scratch))
        } else {
            None
        };
        let right_vals = if end > self.size - self.edges {
            // For t <= 1/2 the reflected point is past the right edge supports, so the
            // rounding of 1 - t cannot matter there.
            self.right
                .as_ref()
                .map(|r| r.at(&self.reversed, &Dyadic::new(1.0 - t), j, scratch))
        } else {
            None
        };
        for k in first..end {
            let out = &mut values[(k - first) * nd..(k - first + 1) * nd];
            if k < self.edges {
                let lv = left_vals.as_ref().expect("left edge values computed");
                for (d, o) in out.iter_mut().enumerate() {
                    *o = scale * lv[d * self.p + k];
                }
            } else if k >= self.size - self.edges {
                let r = self.size - 1 - k;
                let rv = right_vals.as_ref().expect("right edge values computed");
                for (d, o) in out.iter_mut().enumerate() {
                    *o = self.totals[k * nd + d] - scale * rv[d * self.p + r];
                }
            } else {
                let i = c + p - 1 - k as i64;
                for (d, o) in out.iter_mut().enumerate() {
                    *o = scale * fw.value(&x, d, i);
                }
            }
        }
        Antiderivative { first, len, values }
    }

    /// `F_{k,d}` of an antiderivative window for any `k` (totals below, zero above).
    fn window_value(&self, f: &Antiderivative, k: usize, d: usize) -> f64 {
        let nd = self.degree + 1;
        if k < f.first {
            self.totals[k * nd + d]
        } else if k < f.first + f.len {
            f.values[(k - f.first) * nd + d]
        } else {
            0.0
        }
    }

    /// Antiderivatives at domain positions (checked), in order.
    pub fn antiderivatives(&self, xs: &[f64]) -> Result<Vec<Antiderivative>, BasisError> {
        let mut scratch = Scratch::default();
        xs.iter()
            .map(|&x| {
                if !self.domain.contains(x) {
                    return Err(BasisError::PositionOutside {
                        x,
                        a: self.domain.a(),
                        b: self.domain.b(),
                    });
                }
                Ok(self.antiderivative_with(self.domain.to_unit(x), &mut scratch))
            })
            .collect()
    }

    /// `int_a^b phi_{J,k}(x) dx` on the domain (Jacobian included) for every `k` whose support
    /// meets `(a, b)`, ascending, from the antiderivatives at `a` and `b` (`a <= b`).
    pub fn integrals_between(&self, fa: &Antiderivative, fb: &Antiderivative) -> Vec<BasisValue> {
        let jac = self.domain.length().sqrt();
        (fa.first..(fb.first + fb.len).max(fa.first))
            .map(|k| BasisValue {
                index: k,
                value: jac * (self.window_value(fb, k, 0) - self.window_value(fa, k, 0)),
            })
            .collect()
    }

    /// `int_a^b phi_{J,k}(x) dx` for every `k` whose support meets `(a, b)`; `a > b` gives the
    /// negated integrals of `[b, a]`.
    pub fn integrals(&self, a: f64, b: f64) -> Result<Vec<BasisValue>, BasisError> {
        let (lo, hi, sign) = if a <= b { (a, b, 1.0) } else { (b, a, -1.0) };
        let f = self.antiderivatives(&[lo, hi])?;
        let mut out = self.integrals_between(&f[0], &f[1]);
        out.iter_mut().for_each(|v| v.value *= sign);
        Ok(out)
    }

    /// `int phi_{J,k}` over the whole domain (Jacobian included), all `k`.
    pub fn totals(&self) -> Vec<f64> {
        let jac = self.domain.length().sqrt();
        let nd = self.degree + 1;
        (0..self.size).map(|k| jac * self.totals[k * nd]).collect()
    }

    /// Moments `int_a^b u^d phi_{J,k}(x) dx`, `u = (x - a) / (b - a)`, `d <= D`, on the domain
    /// (Jacobian included), for every `k` whose support meets `(a, b)`: `(k, [moments])`, from the
    /// antiderivatives at `a < b`.
    pub fn moments_between(
        &self,
        a: f64,
        b: f64,
        fa: &Antiderivative,
        fb: &Antiderivative,
    ) -> Vec<(usize, Vec<f64>)> {
        let nd = self.degree + 1;
        let len_d = self.domain.length();
        let jac = len_d.sqrt();
        let scale = (1u64 << self.level) as f64;
        let h = b - a;
        // x = A + L t; interior/left: t = (sigma + off) / 2^J; right: t = 1 - sigma / 2^J.
        let alpha = len_d / (scale * h);
        let mut sigma = vec![0.0; nd];
        (fa.first..(fb.first + fb.len).max(fa.first))
            .map(|k| {
                for (d, s) in sigma.iter_mut().enumerate() {
                    *s = self.window_value(fb, k, d) - self.window_value(fa, k, d);
                }
                let (al, beta) = if k < self.edges {
                    (alpha, (self.domain.a() - a) / h)
                } else if k >= self.size - self.edges {
                    (-alpha, (self.domain.a() + len_d - a) / h)
                } else {
                    let off = k as f64 - self.p as f64 + 1.0;
                    (alpha, (self.domain.a() + len_d * off / scale - a) / h)
                };
                let m: Vec<f64> = (0..nd)
                    .map(|d| {
                        jac * (0..=d)
                            .map(|e| {
                                binomial(d, e)
                                    * al.powi(e as i32)
                                    * beta.powi((d - e) as i32)
                                    * sigma[e]
                            })
                            .sum::<f64>()
                    })
                    .collect();
                (k, m)
            })
            .collect()
    }
}
