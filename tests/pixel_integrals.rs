//! Exact integrals of single-scale CDV functions (`rkwave::basis::integral`) against the exact
//! moments of `basis::facts`, additivity, reproduction of polynomials (an identity that involves
//! every function, edges included), and an independent fine quadrature of the pointwise
//! evaluator; p = 1..10.

use rand::{Rng, SeedableRng};
use rkwave::basis::facts::monomial_coefficients;
use rkwave::basis::integral::ScalingIntegrals;
use rkwave::basis::{minimum_level, BasisValue, CdvBasis, FilterFamily};
use rkwave::sampling::Domain;

fn basis(p: usize, level: u32, domain: Domain) -> CdvBasis {
    CdvBasis::new(p, FilterFamily::cdv_default(p), level, level, domain).unwrap()
}

fn levels(p: usize) -> [u32; 2] {
    let j = minimum_level(p).max(1);
    [j, j + 3]
}

fn dense(v: &[BasisValue], size: usize) -> Vec<f64> {
    let mut out = vec![0.0; size];
    for x in v {
        out[x.index] = x.value;
    }
    out
}

/// Rounding of the digit walk: the maps are contractions, so each step adds a few ulps of the
/// state (entries up to `(2p)^d`); 64 ulps covers every p and level here.
const EXACT: f64 = 64.0 * f64::EPSILON;

#[test]
fn totals_are_the_exact_moments_of_facts() {
    for p in 1..=10 {
        for j in levels(p) {
            let b = basis(p, j, Domain::UNIT);
            let ints = ScalingIntegrals::new(&b, 0).unwrap();
            let moments = monomial_coefficients(&b, 0);
            let whole = dense(&ints.integrals(0.0, 1.0).unwrap(), ints.size());
            let totals = ints.totals();
            for k in 0..ints.size() {
                assert!(
                    (whole[k] - moments[k]).abs() < EXACT,
                    "p={p} J={j} k={k}: {} vs {}",
                    whole[k],
                    moments[k]
                );
                assert!((totals[k] - moments[k]).abs() < EXACT);
            }
        }
    }
}

#[test]
fn integrals_are_additive() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(81);
    for p in 1..=10 {
        for j in levels(p) {
            let b = basis(p, j, Domain::UNIT);
            let ints = ScalingIntegrals::new(&b, 0).unwrap();
            for _ in 0..50 {
                let mut x = [
                    rng.random::<f64>(),
                    rng.random::<f64>(),
                    rng.random::<f64>(),
                ];
                if rng.random::<f64>() < 0.2 {
                    x[0] = 0.0;
                }
                if rng.random::<f64>() < 0.2 {
                    x[2] = 1.0;
                }
                x.sort_by(f64::total_cmp);
                let n = ints.size();
                let ab = dense(&ints.integrals(x[0], x[1]).unwrap(), n);
                let bc = dense(&ints.integrals(x[1], x[2]).unwrap(), n);
                let ac = dense(&ints.integrals(x[0], x[2]).unwrap(), n);
                for k in 0..n {
                    assert!((ab[k] + bc[k] - ac[k]).abs() < EXACT, "p={p} J={j} k={k}");
                }
            }
        }
    }
}

/// `sum_k <t^d, phi_k> phi_k = t^d` for `d < p`, so
/// `sum_k <t^d, phi_k> int_a^b phi_k = (b^{d+1} - a^{d+1}) / (d + 1)` for every interval.
#[test]
fn polynomials_are_integrated_exactly() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(82);
    for p in 1..=10 {
        for j in levels(p) {
            let b = basis(p, j, Domain::UNIT);
            let ints = ScalingIntegrals::new(&b, 0).unwrap();
            let coefficients: Vec<Vec<f64>> =
                (0..p).map(|d| monomial_coefficients(&b, d)).collect();
            for trial in 0..60 {
                let (a, c) = match trial {
                    0 => (0.0, 1.0),
                    1 => (0.0, 0.01),
                    2 => (0.99, 1.0),
                    _ => {
                        let mut x = [rng.random::<f64>(), rng.random::<f64>()];
                        x.sort_by(f64::total_cmp);
                        (x[0], x[1])
                    }
                };
                let v = ints.integrals(a, c).unwrap();
                for (d, coef) in coefficients.iter().enumerate() {
                    let got: f64 = v.iter().map(|x| coef[x.index] * x.value).sum();
                    let want = (c.powi(d as i32 + 1) - a.powi(d as i32 + 1)) / (d as f64 + 1.0);
                    // The coefficients come from the moment recursion of facts.rs (relative
                    // rounding ~1e-13 for large p); sum |coef| |int| is O(1).
                    assert!(
                        (got - want).abs() < 1e-11,
                        "p={p} J={j} d={d} [{a}, {c}]: {got} vs {want}"
                    );
                }
            }
        }
    }
}

/// Composite Gauss–Legendre (5 points) on `n` equal cells of the pointwise evaluator.
fn quadrature(b: &CdvBasis, a: f64, c: f64, n: usize) -> Vec<f64> {
    let nodes = [
        (0.0, 128.0 / 225.0),
        (-0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (0.538_469_310_105_683_1, 0.478_628_670_499_366_5),
        (-0.906_179_845_938_664, 0.236_926_885_056_189_1),
        (0.906_179_845_938_664, 0.236_926_885_056_189_1),
    ];
    let size = 1usize << b.coarse();
    let mut out = vec![0.0; size];
    let mut ev = b.evaluator();
    let mut vals = Vec::new();
    let h = (c - a) / n as f64;
    for i in 0..n {
        let mid = a + (i as f64 + 0.5) * h;
        for &(x, wgt) in &nodes {
            ev.eval_scaling_unit_into(mid + 0.5 * h * x, &mut vals);
            for v in &vals {
                out[v.index] += 0.5 * h * wgt * v.value;
            }
        }
    }
    out
}

/// An independent check for smooth-enough p: the quadrature error of a function in `C^alpha`
/// on cells of width `h` (unit coordinates, `2^J h` in the function's own variable) is
/// `O((2^J h)^alpha)` times `2^{-J/2} |phi|_{C^alpha}`: p = 4 (Hölder 1.6) at `2^J h = 2^-11`,
/// p = 6 (2.2) at `2^-9`, p = 10 (~3) at `2^-8`: the tolerances are these a-priori bounds
/// `(2^J h)^alpha` (rounded up); the errors measured are ~1e-13 (5-point Gauss does better than
/// the bound where the function is locally smoother).
#[test]
fn integrals_match_fine_quadrature() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(83);
    for (p, cells, tol) in [(4, 11, 1e-5), (6, 9, 1e-6), (10, 8, 1e-7)] {
        let j = minimum_level(p) + 1;
        let b = basis(p, j, Domain::UNIT);
        let ints = ScalingIntegrals::new(&b, 0).unwrap();
        for trial in 0..3 {
            let (a, c) = match trial {
                0 => (0.0, 0.37),
                1 => (0.61, 1.0),
                _ => {
                    let mut x = [rng.random::<f64>(), rng.random::<f64>()];
                    x.sort_by(f64::total_cmp);
                    (x[0], x[1])
                }
            };
            let n = (((c - a) * (1u64 << (cells + j)) as f64) as usize).max(1);
            let q = quadrature(&b, a, c, n);
            let v = dense(&ints.integrals(a, c).unwrap(), ints.size());
            let worst = (0..ints.size())
                .map(|k| (q[k] - v[k]).abs())
                .fold(0.0, f64::max);
            eprintln!("p={p} [{a}, {c}]: max |quadrature - exact| = {worst:e}");
            for k in 0..ints.size() {
                assert!(
                    (q[k] - v[k]).abs() < tol,
                    "p={p} k={k} [{a}, {c}]: quadrature {} exact {}",
                    q[k],
                    v[k]
                );
            }
        }
    }
}

/// On a domain `[A, A + L]` the integrals carry the Jacobian: `int_0^W phi_k` equals
/// `sqrt(W) int_0^1 phi_k^unit`, and pixel rows sum to the whole.
#[test]
fn domain_integrals_carry_the_jacobian() {
    let w = 37.0;
    let b = basis(3, 5, Domain::new(0.0, w).unwrap());
    let unit = basis(3, 5, Domain::UNIT);
    let ints = ScalingIntegrals::new(&b, 0).unwrap();
    let uints = ScalingIntegrals::new(&unit, 0).unwrap();
    let whole = ints.totals();
    let uwhole = uints.totals();
    let mut sum = vec![0.0; ints.size()];
    for i in 0..37 {
        for v in ints.integrals(i as f64, i as f64 + 1.0).unwrap() {
            sum[v.index] += v.value;
        }
    }
    for k in 0..ints.size() {
        assert!((whole[k] - w.sqrt() * uwhole[k]).abs() < 1e-14 * w);
        assert!((sum[k] - whole[k]).abs() < 1e-13 * w);
    }
}

/// Moments against polynomial pieces: `sum_k <t^e, phi_k> int_a^b u^d phi_k = int_a^b u^d t^e`,
/// `u = (t - a)/(b - a)`, exactly, for `e < p`, `d <= 3` (the film-filter degree).
#[test]
fn moments_reproduce_polynomial_products() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(84);
    for p in [1, 2, 3, 5, 8] {
        let j = minimum_level(p).max(1) + 2;
        let b = basis(p, j, Domain::UNIT);
        let ints = ScalingIntegrals::new(&b, 3).unwrap();
        let coefficients: Vec<Vec<f64>> = (0..p).map(|d| monomial_coefficients(&b, d)).collect();
        for trial in 0..40 {
            let (a, c) = if trial == 0 {
                (0.0, 1.0)
            } else {
                let a = rng.random::<f64>() * 0.9;
                (a, a + rng.random::<f64>() * (1.0 - a))
            };
            let f = ints.antiderivatives(&[a, c]).unwrap();
            let m = ints.moments_between(a, c, &f[0], &f[1]);
            for (e, coef) in coefficients.iter().enumerate() {
                for d in 0..=3 {
                    let got: f64 = m.iter().map(|(k, mk)| coef[*k] * mk[d]).sum();
                    // int_0^1 u^d (a + h u)^e h du = h sum_r C(e,r) a^{e-r} h^r / (d + r + 1)
                    let h = c - a;
                    let want: f64 = h
                        * (0..=e)
                            .map(|r| {
                                binom(e, r) * a.powi((e - r) as i32) * h.powi(r as i32)
                                    / (d + r + 1) as f64
                            })
                            .sum::<f64>();
                    // Cancellation of two antiderivatives in the local variable u amplifies
                    // rounding by (2^J h)^-d (module docs); h >= 1e-3 here.
                    let tol = 1e-12 * (1.0 + (1.0 / ((1u64 << j) as f64 * h)).powi(d as i32));
                    assert!(
                        (got - want).abs() < tol,
                        "p={p} e={e} d={d} [{a}, {c}]: {got} vs {want}"
                    );
                }
            }
        }
    }
}

fn binom(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}
