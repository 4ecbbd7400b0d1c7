//! Orthonormal Daubechies low-pass filters with `p = 1..=10` vanishing moments, computed from
//! first principles by spectral factorization (std only, `f64` plus a small complex type).
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
use std::ops::{Add, Div, Mul, Sub};
use std::sync::OnceLock;

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
            let zeros: Vec<Complex> = groups.iter().flatten().copied().collect();
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
fn root_groups(p: usize) -> Vec<Vec<Complex>> {
    let ys = polynomial_roots(&y_polynomial(p));
    let tol = 1e-8;
    let mut reps: Vec<Complex> = ys.iter().copied().filter(|y| y.im > -tol).collect();
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
                let a = inner_zero(Complex::real(y.re));
                vec![Complex::real(a.re)]
            } else {
                let a = inner_zero(y);
                vec![a, a.conj()]
            }
        })
        .collect()
}

/// The zero with `|z| < 1` of `z^2 - (2 - 4y) z + 1` (the other one is its reciprocal).
fn inner_zero(y: Complex) -> Complex {
    let b = Complex::real(2.0) - y.scale(4.0);
    let d = (b * b - Complex::real(4.0)).sqrt();
    // Larger root without cancellation, then the smaller one as its reciprocal.
    let big = if (b + d).abs() >= (b - d).abs() {
        (b + d).scale(0.5)
    } else {
        (b - d).scale(0.5)
    };
    big.recip()
}

/// Zeros for the sign pattern: `a` where `s = +1`, `1/a` where `s = -1`.
fn chosen_zeros(groups: &[Vec<Complex>], signs: &[f64]) -> Vec<Complex> {
    groups
        .iter()
        .zip(signs)
        .flat_map(|(g, &s)| g.iter().map(move |&a| if s > 0.0 { a } else { a.recip() }))
        .collect()
}

/// Signs `s_g` minimising `J(s) = (pi/2) sum_n (sum_g s_g sum_{a in g} a^n)^2 / n^2` over all
/// `2^{#groups}` patterns (first minimum kept; a pattern and its negation tie exactly).
fn least_asymmetric_signs(groups: &[Vec<Complex>]) -> Vec<f64> {
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
fn phase_nonlinearity(groups: &[Vec<Complex>], signs: &[f64]) -> f64 {
    let terms: Vec<(f64, Complex)> = groups
        .iter()
        .zip(signs)
        .flat_map(|(g, &s)| g.iter().map(move |&a| (s, a)))
        .collect();
    let rho = terms.iter().map(|(_, a)| a.abs()).fold(0.0, f64::max);
    let mut powers: Vec<Complex> = terms.iter().map(|&(_, a)| a).collect();
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
            *pw = *pw * a;
        }
        rho_n *= rho;
        n += 1;
    }
    FRAC_PI_2 * sum
}

/// Real coefficients (ascending powers) of `(1 + z)^p prod (z - r)`, scaled to sum `sqrt 2`.
fn expand(zeros: &[Complex], p: usize) -> Vec<f64> {
    let mut poly = vec![Complex::real(1.0)];
    let minus_one = Complex::real(-1.0);
    for r in std::iter::repeat_n(&minus_one, p).chain(zeros) {
        let mut next = vec![Complex::real(0.0); poly.len() + 1];
        for (i, &c) in poly.iter().enumerate() {
            next[i + 1] = next[i + 1] + c;
            next[i] = next[i] - *r * c;
        }
        poly = next;
    }
    let h: Vec<f64> = poly.iter().map(|c| c.re).collect();
    let s: f64 = h.iter().sum();
    h.iter().map(|x| x * SQRT_2 / s).collect()
}

/// All complex roots of the real polynomial `sum_k c_k y^k` (Aberth–Ehrlich, then Newton).
fn polynomial_roots(c: &[f64]) -> Vec<Complex> {
    let n = c.len().saturating_sub(1);
    if n == 0 {
        return Vec::new();
    }
    let radius = (c[0].abs() / c[n].abs()).powf(1.0 / n as f64);
    let mut z: Vec<Complex> = (0..n)
        .map(|k| {
            let t = TAU * k as f64 / n as f64 + 0.4;
            Complex::new(radius * t.cos(), radius * t.sin())
        })
        .collect();
    for _ in 0..500 {
        let mut max_step: f64 = 0.0;
        for k in 0..n {
            let zk = z[k];
            let (v, dv) = horner(c, zk);
            if v.abs() == 0.0 {
                continue;
            }
            let ratio = v / dv;
            let repulsion = z
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != k)
                .fold(Complex::real(0.0), |acc, (_, &zj)| acc + (zk - zj).recip());
            let step = ratio / (Complex::real(1.0) - ratio * repulsion);
            z[k] = zk - step;
            max_step = max_step.max(step.abs() / (1.0 + zk.abs()));
        }
        if max_step < 1e-15 {
            break;
        }
    }
    for zk in &mut z {
        for _ in 0..3 {
            let (v, dv) = horner(c, *zk);
            if dv.abs() > 0.0 {
                *zk = *zk - v / dv;
            }
        }
    }
    z
}

/// Value and derivative of `sum_k c_k y^k` at `y`.
fn horner(c: &[f64], y: Complex) -> (Complex, Complex) {
    let mut v = Complex::real(0.0);
    let mut dv = Complex::real(0.0);
    for &ck in c.iter().rev() {
        dv = dv * y + v;
        v = v * y + Complex::real(ck);
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
        let Some(delta) = solve_linear(jac, f) else {
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

/// Solves `a x = b` by Gaussian elimination with partial pivoting (`None` if singular).
fn solve_linear(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col] == 0.0 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        let pivot_row = a[col].clone();
        for row in col + 1..n {
            let factor = a[row][col] / pivot_row[col];
            if factor != 0.0 {
                for (x, &pv) in a[row][col..].iter_mut().zip(&pivot_row[col..]) {
                    *x -= factor * pv;
                }
                b[row] -= factor * b[col];
            }
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let tail: f64 = (row + 1..n).map(|j| a[row][j] * x[j]).sum();
        x[row] = (b[row] - tail) / a[row][row];
    }
    Some(x)
}

// ---------------------------------------------------------------------------------------------
// Minimal complex arithmetic.
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug, PartialEq)]
struct Complex {
    re: f64,
    im: f64,
}

impl Complex {
    fn new(re: f64, im: f64) -> Self {
        Self { re, im }
    }

    fn real(re: f64) -> Self {
        Self { re, im: 0.0 }
    }

    fn conj(self) -> Self {
        Self::new(self.re, -self.im)
    }

    fn abs(self) -> f64 {
        self.re.hypot(self.im)
    }

    fn scale(self, s: f64) -> Self {
        Self::new(self.re * s, self.im * s)
    }

    fn recip(self) -> Self {
        Self::real(1.0) / self
    }

    /// Principal square root.
    fn sqrt(self) -> Self {
        let r = self.abs();
        let re = ((r + self.re) / 2.0).max(0.0).sqrt();
        let im = ((r - self.re) / 2.0).max(0.0).sqrt();
        Self::new(re, if self.im < 0.0 { -im } else { im })
    }
}

impl Add for Complex {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self::new(self.re + o.re, self.im + o.im)
    }
}

impl Sub for Complex {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self::new(self.re - o.re, self.im - o.im)
    }
}

impl Mul for Complex {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        Self::new(
            self.re * o.re - self.im * o.im,
            self.re * o.im + self.im * o.re,
        )
    }
}

impl Div for Complex {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        // Smith's algorithm: no overflow/underflow from squaring |o|.
        if o.re.abs() >= o.im.abs() {
            let r = o.im / o.re;
            let d = o.re + o.im * r;
            Self::new((self.re + self.im * r) / d, (self.im - self.re * r) / d)
        } else {
            let r = o.re / o.im;
            let d = o.re * r + o.im;
            Self::new((self.re * r + self.im) / d, (self.im * r - self.re) / d)
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Tests.
// ---------------------------------------------------------------------------------------------

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    const FAMILIES: [FilterFamily; 2] = [FilterFamily::Extremal, FilterFamily::LeastAsymmetric];

    fn all_filters() -> Vec<(usize, FilterFamily, Vec<f64>)> {
        let mut out = Vec::new();
        for p in 1..=MAX_VANISHING_MOMENTS {
            for family in FAMILIES {
                out.push((p, family, daubechies_lowpass(p, family)));
            }
        }
        out
    }

    /// `max_m |sum_k h_k h_{k+2m} - delta_m|` over all `m >= 0`.
    fn orthonormality_error(h: &[f64]) -> f64 {
        (0..h.len().div_ceil(2))
            .map(|m| {
                let s = 2 * m;
                let dot: f64 = (0..h.len() - s).map(|k| h[k] * h[k + s]).sum();
                (dot - if m == 0 { 1.0 } else { 0.0 }).abs()
            })
            .fold(0.0, f64::max)
    }

    /// `max_{d<p} |sum_k g_k k^d| / (2p)^d` for `g = quadrature_mirror(h)`.
    fn scaled_moment_error(h: &[f64]) -> f64 {
        let g = quadrature_mirror(h);
        let p = h.len() / 2;
        (0..p)
            .map(|d| {
                let m: f64 = g
                    .iter()
                    .enumerate()
                    .map(|(k, gk)| gk * (k as f64).powi(d as i32))
                    .sum();
                m.abs() / ((2 * p) as f64).powi(d as i32)
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn length_and_sum() {
        for (p, family, h) in all_filters() {
            assert_eq!(h.len(), 2 * p);
            let s: f64 = h.iter().sum();
            assert!((s - SQRT_2).abs() <= 1e-14, "{family:?} p={p}: sum {s}");
        }
    }

    #[test]
    fn orthonormal_to_even_shifts() {
        let mut worst = [0.0f64; 2];
        for (p, family, h) in all_filters() {
            let e = orthonormality_error(&h);
            worst[(family == FilterFamily::LeastAsymmetric) as usize] =
                worst[(family == FilterFamily::LeastAsymmetric) as usize].max(e);
            assert!(e <= 1e-14, "{family:?} p={p}: orthonormality error {e:e}");
        }
        eprintln!(
            "max orthonormality error: db {:e}, sym {:e}",
            worst[0], worst[1]
        );
    }

    #[test]
    fn wavelet_has_p_vanishing_moments() {
        // |sum_k g_k k^d| is a sum of 2p terms of size up to |g_k| (2p-1)^d, so both the
        // rounding of the sum and a ~1e-16 error in the filter are amplified by up to (2p)^d:
        // the tolerance 1e-14 (2p)^d is a relative accuracy of 1e-14 in that natural scale.
        let mut worst = [0.0f64; 2];
        for (p, family, h) in all_filters() {
            let e = scaled_moment_error(&h);
            let i = (family == FilterFamily::LeastAsymmetric) as usize;
            worst[i] = worst[i].max(e);
            assert!(e <= 1e-14, "{family:?} p={p}: scaled moment error {e:e}");
            // The p-th moment must not vanish (exactly p vanishing moments).
            let g = quadrature_mirror(&h);
            let mp: f64 = g
                .iter()
                .enumerate()
                .map(|(k, gk)| gk * (k as f64).powi(p as i32))
                .sum();
            assert!(mp.abs() > 1e-6, "{family:?} p={p}: moment p vanishes");
        }
        eprintln!(
            "max scaled moment error: db {:e}, sym {:e}",
            worst[0], worst[1]
        );
    }

    #[test]
    fn highpass_is_orthogonal_to_lowpass_shifts() {
        for (p, family, h) in all_filters() {
            let g = quadrature_mirror(&h);
            let l = h.len() as isize;
            for m in -(l / 2)..=(l / 2) {
                let s: f64 = (0..l)
                    .filter(|k| (0..l).contains(&(k + 2 * m)))
                    .map(|k| h[k as usize] * g[(k + 2 * m) as usize])
                    .sum();
                assert!(s.abs() <= 1e-15, "{family:?} p={p} m={m}: {s:e}");
            }
            assert!((orthonormality_error(&g)) <= 1e-14);
        }
    }

    #[test]
    fn quadrature_mirror_definition() {
        let h = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(quadrature_mirror(&h), vec![4.0, -3.0, 2.0, -1.0]);
    }

    #[test]
    fn haar() {
        for family in FAMILIES {
            let h = daubechies_lowpass(1, family);
            assert_eq!(h.len(), 2);
            for x in h {
                assert!((x - std::f64::consts::FRAC_1_SQRT_2).abs() <= 1e-16);
            }
        }
    }

    #[test]
    fn exact_db2() {
        let s3 = 3f64.sqrt();
        let den = 4.0 * SQRT_2;
        let exact = [
            (1.0 + s3) / den,
            (3.0 + s3) / den,
            (3.0 - s3) / den,
            (1.0 - s3) / den,
        ];
        let h = daubechies_lowpass(2, FilterFamily::Extremal);
        for (a, b) in h.iter().zip(exact) {
            assert!((a - b).abs() <= 1e-15, "db2: {a} vs {b}");
        }
    }

    #[test]
    fn exact_db3() {
        let r10 = 10f64.sqrt();
        let s = (5.0 + 2.0 * r10).sqrt();
        let exact = [
            1.0 + r10 + s,
            5.0 + r10 + 3.0 * s,
            10.0 - 2.0 * r10 + 2.0 * s,
            10.0 - 2.0 * r10 - 2.0 * s,
            5.0 + r10 - 3.0 * s,
            1.0 + r10 - s,
        ]
        .map(|v| v * SQRT_2 / 32.0);
        let h = daubechies_lowpass(3, FilterFamily::Extremal);
        for (a, b) in h.iter().zip(exact) {
            assert!((a - b).abs() <= 1e-15, "db3: {a} vs {b}");
        }
    }

    #[test]
    fn sym2_sym3_equal_db2_db3() {
        for p in 1..=3 {
            let db = daubechies_lowpass(p, FilterFamily::Extremal);
            let sym = daubechies_lowpass(p, FilterFamily::LeastAsymmetric);
            for (a, b) in db.iter().zip(&sym) {
                assert!((a - b).abs() <= 1e-15, "p={p}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn extremal_phase_is_minimum_phase() {
        // Minimum phase <=> maximal partial energies sum_{k<n} h_k^2 among all choices of zeros.
        for p in 2..=MAX_VANISHING_MOMENTS {
            let db = daubechies_lowpass(p, FilterFamily::Extremal);
            let groups = root_groups(p);
            for mask in 0..(1usize << groups.len()) {
                let zeros = chosen_zeros(&groups, &signs_of_mask(mask, groups.len()));
                let ascending = expand(&zeros, p);
                let descending: Vec<f64> = ascending.iter().rev().copied().collect();
                for other in [ascending, descending] {
                    let (mut e_db, mut e_other) = (0.0, 0.0);
                    for (a, b) in db.iter().zip(&other) {
                        e_db += a * a;
                        e_other += b * b;
                        assert!(e_db >= e_other - 1e-12, "p={p} mask={mask}");
                    }
                }
            }
        }
    }

    #[test]
    fn least_asymmetric_choice_is_well_separated() {
        // The selected pattern beats every other non-mirror pattern by at least 5% in J, so the
        // selection is not decided by rounding.
        for p in 4..=MAX_VANISHING_MOMENTS {
            let groups = root_groups(p);
            let n = groups.len();
            let best = least_asymmetric_signs(&groups);
            let j_best = phase_nonlinearity(&groups, &best);
            for mask in 0..(1usize << n) {
                let s = signs_of_mask(mask, n);
                let mirror = s.iter().zip(&best).all(|(a, b)| a == b)
                    || s.iter().zip(&best).all(|(a, b)| *a == -b);
                if !mirror {
                    let j = phase_nonlinearity(&groups, &s);
                    assert!(j > 1.05 * j_best, "p={p}: J {j} vs best {j_best}");
                }
            }
        }
    }

    #[test]
    fn phase_nonlinearity_matches_quadrature() {
        // J from the Fourier series equals a direct quadrature of (theta + tau xi)^2 on [0, pi],
        // with theta the continuous phase of sum_k h_k e^{-ik xi} (ascending orientation).
        for p in [4, 7, 10] {
            let groups = root_groups(p);
            let n = groups.len();
            for mask in [0, 1, (1 << n) - 2] {
                let signs = signs_of_mask(mask, n);
                let zeros = chosen_zeros(&groups, &signs);
                let inside = zeros.iter().filter(|z| z.abs() < 1.0).count();
                let tau = p as f64 / 2.0 + inside as f64;
                // H(z) = c (1 + z)^p prod (z - r) with c real and H(1) > 0, so on [0, pi) the
                // phase of sum_k h_k z^k at z = e^{-i xi} is -p xi / 2 plus the phase of
                // sign(prod (1 - r)) prod (e^{-i xi} - r), computed here directly.
                let at_one = zeros
                    .iter()
                    .fold(Complex::real(1.0), |acc, &r| acc * (Complex::real(1.0) - r));
                let sign = at_one.re.signum();
                let steps = 4000;
                let mut prev = 0.0;
                let mut integral = 0.0;
                for i in 0..steps {
                    // Midpoint rule; phase unwrapped along the path (|H| > 0 on [0, pi)).
                    let xi = std::f64::consts::PI * (i as f64 + 0.5) / steps as f64;
                    let unit = Complex::new(xi.cos(), -xi.sin());
                    let w = zeros
                        .iter()
                        .fold(Complex::real(sign), |acc, &r| acc * (unit - r));
                    let mut theta = w.im.atan2(w.re) - p as f64 * xi / 2.0;
                    while theta - prev > std::f64::consts::PI {
                        theta -= TAU;
                    }
                    while theta - prev < -std::f64::consts::PI {
                        theta += TAU;
                    }
                    prev = theta;
                    let dev = theta + tau * xi;
                    integral += dev * dev * std::f64::consts::PI / steps as f64;
                }
                let j = phase_nonlinearity(&groups, &signs);
                assert!(
                    (integral - j).abs() <= 1e-9 * j,
                    "p={p} mask={mask}: quadrature {integral} vs series {j}"
                );
            }
        }
    }

    /// Parses `family,p,k,h_k` rows (comment lines start with `#`).
    fn published() -> BTreeMap<(String, usize), Vec<f64>> {
        let text = include_str!("../../data/pywavelets-filters.csv");
        let mut map: BTreeMap<(String, usize), Vec<f64>> = BTreeMap::new();
        for line in text.lines() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let f: Vec<&str> = line.split(',').map(str::trim).collect();
            assert_eq!(f.len(), 4, "bad row {line:?}");
            let p: usize = f[1].parse().expect("p");
            let k: usize = f[2].parse().expect("k");
            let v: f64 = f[3].parse().expect("h_k");
            let entry = map.entry((f[0].to_string(), p)).or_default();
            assert_eq!(entry.len(), k, "rows of {}{} out of order", f[0], p);
            entry.push(v);
        }
        map
    }

    #[test]
    fn agrees_with_pywavelets() {
        let table = published();
        let mut expected: Vec<(FilterFamily, usize)> = Vec::new();
        expected.extend((1..=10).map(|p| (FilterFamily::Extremal, p)));
        expected.extend((2..=10).map(|p| (FilterFamily::LeastAsymmetric, p)));
        let mut worst = [0.0f64; 2];
        for (family, p) in expected {
            let key = (family.short_name().to_string(), p);
            let reference = table
                .get(&key)
                .unwrap_or_else(|| panic!("{}{} missing from the CSV", key.0, p));
            let h = daubechies_lowpass(p, family);
            assert_eq!(reference.len(), h.len(), "{}{p}", key.0);
            let diff = h
                .iter()
                .zip(reference)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            // PyWavelets' sym2..sym8 (from MATLAB) are themselves accurate only to a few 1e-12:
            // they violate orthonormality / the moment conditions by up to 4.8e-12 (sym3),
            // while the filters here satisfy them to ~1e-16. Where the published values are
            // measurably off (residual > 1e-13) the comparison can only be that good.
            let published_residual =
                orthonormality_error(reference).max(scaled_moment_error(reference));
            let tol = if published_residual > 1e-13 {
                5e-12
            } else {
                1e-12
            };
            eprintln!(
                "{}{p}: max |h - pywt| = {diff:.2e} (published residual {published_residual:.1e})",
                key.0
            );
            let i = (family == FilterFamily::LeastAsymmetric) as usize;
            worst[i] = worst[i].max(diff);
            assert!(
                diff <= tol,
                "{}{p}: max abs difference {diff:e} > {tol:e}",
                key.0
            );
        }
        eprintln!("max |h - pywt|: db {:e}, sym {:e}", worst[0], worst[1]);
    }

    #[test]
    fn cdv_default_and_names() {
        for p in 1..=3 {
            assert_eq!(FilterFamily::cdv_default(p), FilterFamily::Extremal);
        }
        for p in 4..=MAX_VANISHING_MOMENTS {
            assert_eq!(FilterFamily::cdv_default(p), FilterFamily::LeastAsymmetric);
        }
        assert_eq!(FilterFamily::Extremal.short_name(), "db");
        assert_eq!(FilterFamily::LeastAsymmetric.short_name(), "sym");
    }

    #[test]
    fn roots_of_p_are_accurate() {
        for p in 2..=MAX_VANISHING_MOMENTS {
            let c = y_polynomial(p);
            let roots = polynomial_roots(&c);
            assert_eq!(roots.len(), p - 1);
            for y in roots {
                let (v, _) = horner(&c, y);
                let scale: f64 = c
                    .iter()
                    .enumerate()
                    .map(|(k, ck)| ck * y.abs().powi(k as i32))
                    .sum();
                assert!(v.abs() <= 1e-13 * scale, "p={p}: |P(y)| = {:e}", v.abs());
            }
        }
    }

    #[test]
    #[should_panic]
    fn rejects_zero() {
        let _ = daubechies_lowpass(0, FilterFamily::Extremal);
    }

    #[test]
    #[should_panic]
    fn rejects_too_many_moments() {
        let _ = daubechies_lowpass(MAX_VANISHING_MOMENTS + 1, FilterFamily::LeastAsymmetric);
    }
}
