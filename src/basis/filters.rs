//! Orthonormal Daubechies low-pass filters with `p = 1..=10` vanishing moments, computed from
//! first principles by spectral factorization (`f64`, faer's complex type `c64` — num-complex's
//! `Complex<f64>` — and faer's LU for the Newton steps).
//!
//! # Construction
//!
//! With `y = sin^2(xi/2)`, the squared modulus of the trigonometric polynomial
//! `m0(xi) = 2^{-1/2} sum_k h_k e^{-i k xi}` of a Daubechies filter is
//! `|m0(xi)|^2 = (1 - y)^p P(y)`, where `P(y) = sum_{k=0}^{p-1} C(p-1+k, k) y^k`.
//!
//! 1. The `p - 1` roots `y_i` of `P` are found by the Aberth–Ehrlich iteration in the complex
//!    plane and polished by Newton steps on `P`.
//! 2. Since `y = (2 - z - 1/z)/4` for `z = e^{i xi}`, each `y_i` gives the reciprocal pair of
//!    zeros of `z^2 - (2 - 4 y_i) z + 1`; `a_i` denotes the member with `|a_i| < 1`.
//! 3. A filter is `H(z) = sum_k h_k z^k = c (1 + z)^p prod_i (z - r_i)` with one `r_i` from
//!    every pair (`r_i = a_i` or `1/a_i`; the two members of a complex-conjugate pair of `y`
//!    roots are chosen together so that `h` is real), normalised so that `sum_k h_k = sqrt 2`.
//!    All `2^{#groups}` choices are orthonormal filters with `p` vanishing moments; reversing
//!    `h` corresponds to swapping every `r_i` for its reciprocal.
//! 4. The result is polished by Newton's method on the defining equations
//!    `sum_k h_k h_{k+2m} = delta_{m,0}` (`m = 0..p-1`) and
//!    `sum_k (-1)^k (2k - 2p + 1)^d h_k = 0` (`d = 0..p-1`; the same conditions as the raw
//!    moments `sum_k (-1)^k k^d h_k = 0`, taken about the centre of the support for scaling),
//!    with residuals in compensated arithmetic, so that the coefficients are accurate to a few
//!    units in the last place. Together these imply `sum_k h_k = sqrt 2` (the sign is that of
//!    the starting point); see `defining_system` for why that equation itself is not used.
//!
//! The family decides the choice in step 3 ([`FilterFamily`]); the orientation of the returned
//! vector follows PyWavelets' `rec_lo` (see [`daubechies_lowpass`]).

use std::f64::consts::{FRAC_PI_2, SQRT_2, TAU};
use std::sync::OnceLock;

use faer::c64;

/// Which Daubechies family.
///
/// Both families have the same `|m0(xi)|^2 = (1 - y)^p P(y)` (hence the same length `2p`, the same
/// `p` vanishing moments and the same orthonormality); they differ only in which zero of each
/// reciprocal pair `{a_i, 1/a_i}` is given to `H(z)`, i.e. in the phase of `m0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FilterFamily {
    /// Extremal phase ("dbP"): every zero of `sum_k h_k z^{-k}` other than the `p`-fold zero at
    /// `z = -1` lies inside the unit disc (minimum phase; `s_i = +1` for all `i` in the notation
    /// below, up to reversal), so the filter's energy is concentrated at its start:
    /// `sum_{k<n} h_k^2` is maximal for every `n` among all filters with the same `|m0|`.
    Extremal,
    /// Least asymmetric ("symP", symlets): the choice of zeros whose phase is closest to linear
    /// in the mean-square sense (Daubechies, *Ten Lectures* §8.1). Exact criterion: let
    /// `theta(xi)` be the continuous phase of `sum_k h_k e^{-i k xi}` on `[0, pi)`
    /// (`theta(0) = 0`) and `tau = p/2 + #{zeros of sum_k h_k z^k inside the unit disc}` the
    /// filter's mean group delay over a period (the `p`-fold zero at `z = -1` counting 1/2
    /// each); minimise
    /// `J = int_0^pi (theta(xi) + tau xi)^2 dxi = (pi/2) sum_{n>=1} (sum_i s_i a_i^n)^2 / n^2`
    /// over all `2^{#groups}` choices, where `i` runs over all inner zeros `a_i`, `s_i = +1` if
    /// `a_i` is a zero of the filter and `-1` if `1/a_i` is (the series follows from
    /// `theta(xi) + tau xi = -sum_i s_i sum_n Re(a_i^n) sin(n xi) / n`). This is the criterion of
    /// MATLAB's `symaux` (from which PyWavelets' `symP` tables come), which evaluates the same
    /// integral on a 200-point grid of `[0, 2 pi]`. `J` is invariant under reversal, so it fixes
    /// the filter up to orientation. For `p = 1` this is Haar; for `p = 2, 3` the only two
    /// choices are mirror images and the filter equals db2/db3.
    LeastAsymmetric,
}

impl FilterFamily {
    /// CDV's choice: extremal phase for p <= 3, least asymmetric for p >= 4.
    ///
    /// (For `p <= 3` the two families coincide up to orientation anyway.)
    pub fn cdv_default(p: usize) -> Self {
        if p <= 3 {
            Self::Extremal
        } else {
            Self::LeastAsymmetric
        }
    }

    /// "db" or "sym".
    ///
    /// The PyWavelets/MATLAB name prefix: `dbP` is the extremal-phase filter with `P` vanishing
    /// moments (length `2P`), `symP` the least-asymmetric one.
    pub fn short_name(self) -> &'static str {
        match self {
            Self::Extremal => "db",
            Self::LeastAsymmetric => "sym",
        }
    }
}

/// Largest supported p.
///
/// `p` is the number of vanishing moments of the wavelet, `sum_k (-1)^k k^d h_k = 0` for
/// `d = 0..p-1`; the filters have length `2p <= 20`.
pub const MAX_VANISHING_MOMENTS: usize = 10;

/// Low-pass filter h_0..h_{2p-1}, sum sqrt(2), orthonormal to its even shifts. Panics if p == 0 or p > MAX (callers validate first).
///
/// The filter satisfies `sum_k h_k = sqrt 2`, `sum_k h_k h_{k+2m} = delta_{m,0}` for all `m`,
/// and the two-scale relation `phi(x) = sqrt 2 sum_k h_k phi(2x - k)` defines a scaling function
/// supported on `[0, 2p-1]` whose wavelet has `p` vanishing moments; equivalently
/// `m0(xi) = 2^{-1/2} sum_k h_k e^{-i k xi}` has a zero of order `p` at `xi = pi` and
/// `|m0(xi)|^2 = cos^{2p}(xi/2) P(sin^2(xi/2))`, `P(y) = sum_{k<p} C(p-1+k, k) y^k`.
///
/// Orientation is PyWavelets' `rec_lo` (e.g. db3 = 0.3327, 0.8069, 0.4599, -0.1350, -0.0854,
/// 0.0352):
/// * [`FilterFamily::Extremal`]: `sum_k h_k z^{-k}` has all zeros in the closed unit disc
///   (minimum phase, energy at the start).
/// * [`FilterFamily::LeastAsymmetric`]: the criterion `J` is reversal invariant, so the
///   orientation is a convention. PyWavelets copies MATLAB's `symaux`, which fixes it with a
///   per-order compatibility rule; expressed intrinsically, the centre of mass of the scaling
///   function, `int x phi(x) dx = sum_k k h_k / sqrt 2`, lies left of the midpoint
///   `(2p-1)/2` of the support for `p = 2, 3, 7` (as for every dbP) and right of it for
///   `p = 4, 5, 6, 8, 9, 10`. This implementation applies exactly that rule.
///
/// Results are computed once per `(p, family)` and cached.
pub fn daubechies_lowpass(p: usize, family: FilterFamily) -> Vec<f64> {
    assert!(
        (1..=MAX_VANISHING_MOMENTS).contains(&p),
        "daubechies_lowpass: p = {p} vanishing moments is not supported (choose 1..={MAX_VANISHING_MOMENTS})"
    );
    static CACHE: [OnceLock<Vec<f64>>; 2 * MAX_VANISHING_MOMENTS] =
        [const { OnceLock::new() }; 2 * MAX_VANISHING_MOMENTS];
    let slot = 2 * (p - 1)
        + match family {
            FilterFamily::Extremal => 0,
            FilterFamily::LeastAsymmetric => 1,
        };
    CACHE[slot]
        .get_or_init(|| compute_lowpass(p, family))
        .clone()
}

/// High-pass (wavelet) filter g_k = (-1)^k h_{2p-1-k}.
///
/// For an orthonormal low-pass `h` of length `L = 2p`, `g` is orthonormal to its even shifts and
/// orthogonal to every even shift of `h` (`sum_k h_k g_{k+2m} = 0`), and
/// `psi(x) = sqrt 2 sum_k g_k phi(2x - k)`. The `p`-fold zero of `m0` at `pi` becomes
/// `sum_k g_k k^d = 0` for `d = 0..p-1` (vanishing moments).
pub fn quadrature_mirror(h: &[f64]) -> Vec<f64> {
    let n = h.len();
    (0..n)
        .map(|k| {
            let v = h[n - 1 - k];
            if k % 2 == 0 {
                v
            } else {
                -v
            }
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Construction.
// ---------------------------------------------------------------------------------------------

/// Orders `p` for which PyWavelets' `symP` puts the centre of mass of `phi` left of the midpoint.
fn sym_centre_left(p: usize) -> bool {
    matches!(p, 2 | 3 | 7)
}

fn compute_lowpass(p: usize, family: FilterFamily) -> Vec<f64> {
    let groups = root_groups(p);
    let mut h = match family {
        FilterFamily::Extremal => {
            let zeros: Vec<c64> = groups.iter().flatten().copied().collect();
            // Zeros inside the disc for sum h_k z^k; reversed, sum h_k z^{-k} has them inside.
            let mut h = expand(&zeros, p);
            h.reverse();
            h
        }
        FilterFamily::LeastAsymmetric => {
            let signs = least_asymmetric_signs(&groups);
            let zeros = chosen_zeros(&groups, &signs);
            let mut h = expand(&zeros, p);
            let mid = (h.len() as f64 - 1.0) / 2.0;
            let centre = centre_of_mass(&h);
            if centre != mid && (centre < mid) != sym_centre_left(p) {
                h.reverse();
            }
            h
        }
    };
    polish(&mut h);
    h
}

/// `sum_k k h_k / sum_k h_k`, the centre of mass of `phi` (and its group delay at `xi = 0`).
fn centre_of_mass(h: &[f64]) -> f64 {
    let s: f64 = h.iter().sum();
    h.iter().enumerate().map(|(k, x)| k as f64 * x).sum::<f64>() / s
}

/// Coefficients (ascending) of `P(y) = sum_{k<p} C(p-1+k, k) y^k`.
fn y_polynomial(p: usize) -> Vec<f64> {
    (0..p).map(|k| binomial(p - 1 + k, k)).collect()
}

/// Binomial coefficient `C(n, k)` as `f64` (exact for the small arguments used in rkwave, e.g.
/// `C(18, 9) = 48620`).
pub(crate) fn binomial(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// Inner zeros grouped as the filter must choose them: a real `y` root gives one real `a`,
/// a conjugate pair `y, conj(y)` gives `[a, conj(a)]`. Groups are sorted by `Re y`.
fn root_groups(p: usize) -> Vec<Vec<c64>> {
    let ys = polynomial_roots(&y_polynomial(p));
    let tol = 1e-8;
    let mut reps: Vec<c64> = ys.iter().copied().filter(|y| y.im > -tol).collect();
    reps.sort_by(|a, b| a.re.total_cmp(&b.re));
    let n_real = reps.iter().filter(|y| y.im.abs() <= tol).count();
    assert_eq!(
        n_real + 2 * (reps.len() - n_real),
        p - 1,
        "root classification of P(y) failed for p = {p}"
    );
    reps.iter()
        .map(|&y| {
            if y.im.abs() <= tol {
                let a = inner_zero(c64::new(y.re, 0.0));
                vec![c64::new(a.re, 0.0)]
            } else {
                let a = inner_zero(y);
                vec![a, a.conj()]
            }
        })
        .collect()
}

/// The zero with `|z| < 1` of `z^2 - (2 - 4y) z + 1` (the other one is its reciprocal).
fn inner_zero(y: c64) -> c64 {
    let b = c64::new(2.0, 0.0) - y.scale(4.0);
    let d = (b * b - c64::new(4.0, 0.0)).sqrt();
    // Larger root without cancellation, then the smaller one as its reciprocal.
    let big = if (b + d).norm() >= (b - d).norm() {
        (b + d).scale(0.5)
    } else {
        (b - d).scale(0.5)
    };
    big.inv()
}

/// Zeros for the sign pattern: `a` where `s = +1`, `1/a` where `s = -1`.
fn chosen_zeros(groups: &[Vec<c64>], signs: &[f64]) -> Vec<c64> {
    groups
        .iter()
        .zip(signs)
        .flat_map(|(g, &s)| g.iter().map(move |&a| if s > 0.0 { a } else { a.inv() }))
        .collect()
}

/// Signs `s_g` minimising `J(s) = (pi/2) sum_n (sum_g s_g sum_{a in g} a^n)^2 / n^2` over all
/// `2^{#groups}` patterns (first minimum kept; a pattern and its negation tie exactly).
fn least_asymmetric_signs(groups: &[Vec<c64>]) -> Vec<f64> {
    let n = groups.len();
    let mut best: Option<(f64, Vec<f64>)> = None;
    for mask in 0..(1usize << n) {
        let signs = signs_of_mask(mask, n);
        let j = phase_nonlinearity(groups, &signs);
        let better = match &best {
            None => true,
            Some((bj, _)) => j < *bj,
        };
        if better {
            best = Some((j, signs));
        }
    }
    best.map(|(_, s)| s).unwrap_or_default()
}

fn signs_of_mask(mask: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|g| if (mask >> g) & 1 == 1 { -1.0 } else { 1.0 })
        .collect()
}

/// `J = int_0^pi (theta(xi) + tau xi)^2 dxi` for the sign pattern, via its Fourier series.
///
/// On `[0, pi)`, `theta(xi) + tau xi = -sum_i s_i sum_{n>=1} Re(a_i^n) sin(n xi) / n` (the
/// `(1+z)^p` factor has exactly linear phase and each pair of zeros contributes
/// `s_i Arg(1 - a_i e^{i xi})` summed over a conjugate-closed set), so by orthogonality of the
/// sines `J = (pi/2) sum_n t_n^2 / n^2` with `t_n = sum_i s_i Re(a_i^n)`.
fn phase_nonlinearity(groups: &[Vec<c64>], signs: &[f64]) -> f64 {
    let terms: Vec<(f64, c64)> = groups
        .iter()
        .zip(signs)
        .flat_map(|(g, &s)| g.iter().map(move |&a| (s, a)))
        .collect();
    let rho = terms.iter().map(|(_, a)| a.norm()).fold(0.0, f64::max);
    let mut powers: Vec<c64> = terms.iter().map(|&(_, a)| a).collect();
    let mut rho_n = rho;
    let mut sum = 0.0;
    let mut n = 1usize;
    while rho_n > 1e-20 && n <= 10_000 {
        let t: f64 = terms
            .iter()
            .zip(&powers)
            .map(|(&(s, _), pw)| s * pw.re)
            .sum();
        sum += t * t / (n * n) as f64;
        for (pw, &(_, a)) in powers.iter_mut().zip(&terms) {
            *pw *= a;
        }
        rho_n *= rho;
        n += 1;
    }
    FRAC_PI_2 * sum
}

/// Real coefficients (ascending powers) of `(1 + z)^p prod (z - r)`, scaled to sum `sqrt 2`.
fn expand(zeros: &[c64], p: usize) -> Vec<f64> {
    let mut poly = vec![c64::new(1.0, 0.0)];
    let minus_one = c64::new(-1.0, 0.0);
    for r in std::iter::repeat_n(&minus_one, p).chain(zeros) {
        let mut next = vec![c64::new(0.0, 0.0); poly.len() + 1];
        for (i, &c) in poly.iter().enumerate() {
            next[i + 1] += c;
            next[i] -= *r * c;
        }
        poly = next;
    }
    let h: Vec<f64> = poly.iter().map(|c| c.re).collect();
    let s: f64 = h.iter().sum();
    h.iter().map(|x| x * SQRT_2 / s).collect()
}

/// All complex roots of the real polynomial `sum_k c_k y^k` (Aberth–Ehrlich, then Newton).
fn polynomial_roots(c: &[f64]) -> Vec<c64> {
    let n = c.len().saturating_sub(1);
    if n == 0 {
        return Vec::new();
    }
    let radius = (c[0].abs() / c[n].abs()).powf(1.0 / n as f64);
    let mut z: Vec<c64> = (0..n)
        .map(|k| {
            let t = TAU * k as f64 / n as f64 + 0.4;
            c64::new(radius * t.cos(), radius * t.sin())
        })
        .collect();
    for _ in 0..500 {
        let mut max_step: f64 = 0.0;
        for k in 0..n {
            let zk = z[k];
            let (v, dv) = horner(c, zk);
            if v.norm() == 0.0 {
                continue;
            }
            let ratio = v / dv;
            let repulsion = z
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .fold(c64::new(0.0, 0.0), |acc, (_, &zj)| acc + (zk - zj).inv());
            let step = ratio / (c64::new(1.0, 0.0) - ratio * repulsion);
            z[k] = zk - step;
            max_step = max_step.max(step.norm() / (1.0 + zk.norm()));
        }
        if max_step < 1e-15 {
            break;
        }
    }
    for zk in &mut z {
        for _ in 0..3 {
            let (v, dv) = horner(c, *zk);
            if dv.norm() > 0.0 {
                *zk -= v / dv;
            }
        }
    }
    z
}

/// Value and derivative of `sum_k c_k y^k` at `y`.
fn horner(c: &[f64], y: c64) -> (c64, c64) {
    let mut v = c64::new(0.0, 0.0);
    let mut dv = c64::new(0.0, 0.0);
    for &ck in c.iter().rev() {
        dv = dv * y + v;
        v = v * y + ck;
    }
    (v, dv)
}

// ---------------------------------------------------------------------------------------------
// Newton polish on the defining equations.
// ---------------------------------------------------------------------------------------------

/// Residuals `F(h)` (length `2p`) and Jacobian of the defining equations used for polishing:
/// `sum_k h_k h_{k+2m} - delta_{m,0}` for `m = 0..p-1` and `sum_k (-1)^k (2k - 2p + 1)^d h_k`
/// for `d = 0..p-1` (moments about the centre of the support, integer coefficients, hence exact;
/// row `d` is divided by `(2p-1)^d` for scaling). Given orthonormality, `sum_k h_k = sqrt 2` is
/// equivalent to `(sum_k (-1)^k h_k)^2 = 0`, a double root that would make the Jacobian singular,
/// so the linear `d = 0` moment is used instead; the sign `sum_k h_k = +sqrt 2` is inherited from
/// the starting point. Residuals are evaluated with compensated (error-free) dot products, so
/// Newton converges to the solution rounded to `f64` rather than to a solution of the rounded
/// equations.
fn defining_system(h: &[f64]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let l = h.len();
    let p = l / 2;
    let mut f = Vec::with_capacity(l);
    let mut jac = Vec::with_capacity(l);
    for m in 0..p {
        let s = 2 * m;
        let delta = if m == 0 { 1.0 } else { 0.0 };
        f.push(dot2(-delta, (0..l - s).map(|k| (h[k], h[k + s]))));
        jac.push(
            (0..l)
                .map(|j| {
                    let right = if j + s < l { h[j + s] } else { 0.0 };
                    let left = if j >= s { h[j - s] } else { 0.0 };
                    right + left
                })
                .collect(),
        );
    }
    let width = (l - 1) as f64;
    for d in 0..p {
        // (2k - l + 1)^d <= 19^9 < 2^53: exact.
        let row: Vec<f64> = (0..l)
            .map(|k| {
                let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
                sign * (2.0 * k as f64 - width).powi(d as i32)
            })
            .collect();
        let scale = width.powi(d as i32).recip();
        f.push(dot2(0.0, row.iter().copied().zip(h.iter().copied())) * scale);
        jac.push(row.iter().map(|r| r * scale).collect());
    }
    (f, jac)
}

/// `init + sum x_i y_i` in twice the working precision (Ogita–Rump–Oishi `Dot2`), rounded.
fn dot2(init: f64, pairs: impl Iterator<Item = (f64, f64)>) -> f64 {
    let mut sum = init;
    let mut err = 0.0;
    for (x, y) in pairs {
        let prod = x * y;
        let prod_err = x.mul_add(y, -prod);
        let t = sum + prod;
        let v = t - sum;
        let sum_err = (sum - (t - v)) + (prod - v);
        sum = t;
        err += prod_err + sum_err;
    }
    sum + err
}

/// Newton's method on the defining equations, started from the spectral factorization.
/// Skipped for Haar, where the system is singular at its (exact) solution.
fn polish(h: &mut [f64]) {
    if h.len() < 4 {
        return;
    }
    for _ in 0..8 {
        let (f, jac) = defining_system(h);
        let Some(delta) = solve_linear(&jac, &f) else {
            return;
        };
        let step = delta.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        for (x, d) in h.iter_mut().zip(&delta) {
            *x -= d;
        }
        if step < 1e-17 {
            break;
        }
    }
}

/// Solves `a x = b` (`a` given by rows) by faer's LU with partial pivoting; `None` if `a` is
/// singular (a zero pivot of `U`) or the solution is not finite.
fn solve_linear(a: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    use faer::linalg::solvers::Solve;
    let n = b.len();
    let lu = faer::Mat::<f64>::from_fn(n, n, |i, j| a[i][j]).partial_piv_lu();
    if (0..n).any(|i| lu.U()[(i, i)] == 0.0) {
        return None;
    }
    let x = lu.solve(faer::Mat::<f64>::from_fn(n, 1, |i, _| b[i]));
    let x: Vec<f64> = (0..n).map(|i| x[(i, 0)]).collect();
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests;
