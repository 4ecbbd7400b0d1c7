//! The noise test's quantile: `F(ch, d)`'s upper quantile against closed forms and the
//! chi-square limit, and its false-alarm rate on random noise-only statistics against the
//! binomial bound (module docs of `rkwave::image::adaptive::significance`).

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use rkwave::image::adaptive::significance::{
    chi_square_quantile, f_upper_quantile, f_upper_tail, incomplete_beta,
};

/// A standard normal deviate (Box–Muller).
fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random::<f64>();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// `F(2, d)` has the closed tail `P(F > x) = (1 + 2 x / d)^(-d / 2)`, so its quantile is
/// `x = (d / 2) (p^(-2 / d) - 1)`; the bisection reaches it to `1e-9` relative (the bisection
/// is exact to the last bits of `y`, the incomplete beta to about `1e-14`), down to the
/// Bonferroni levels the plan uses (`1e-12`).
#[test]
fn f_quantile_with_two_numerator_degrees_matches_the_closed_form() {
    for d in [1.0f64, 3.0, 6.0, 27.0, 108.0] {
        for p in [0.5f64, 1e-2, 1e-5, 1e-8, 1e-12] {
            let exact = d / 2.0 * (p.powf(-2.0 / d) - 1.0);
            let q = f_upper_quantile(2.0, d, p);
            assert!(
                ((q - exact) / exact).abs() < 1e-9,
                "F(2, {d}) at {p}: {q} against {exact}"
            );
            let tail = f_upper_tail(2.0, d, exact);
            assert!(((tail - p) / p).abs() < 1e-9, "tail {tail} against {p}");
        }
    }
}

/// `F(1, 1)` is the square of a standard Cauchy variable: `P(F > x) = 1 - (2 / pi) atan(sqrt
/// x)`, so `x = cot(pi p / 2)^2`.
#[test]
fn f_quantile_with_one_and_one_degrees_is_the_squared_cauchy() {
    for p in [0.5, 0.1, 1e-3, 1e-6, 1e-10] {
        let exact = (1.0 / (std::f64::consts::FRAC_PI_2 * p).tan()).powi(2);
        let q = f_upper_quantile(1.0, 1.0, p);
        assert!(
            ((q - exact) / exact).abs() < 1e-9,
            "{p}: {q} against {exact}"
        );
    }
}

/// `I_x(a, b) + I_{1-x}(b, a) = 1` and `I_x(1, b) = 1 - (1 - x)^b` (closed form), to `1e-13`.
#[test]
fn incomplete_beta_keeps_its_symmetry_and_closed_forms() {
    for (a, b) in [
        (0.5, 0.5),
        (1.5, 13.5),
        (13.5, 1.5),
        (54.0, 1.5),
        (2.0, 7.0),
    ] {
        for x in [1e-6, 0.01, 0.3, 0.5, 0.77, 0.999] {
            let s = incomplete_beta(a, b, x) + incomplete_beta(b, a, 1.0 - x);
            assert!((s - 1.0).abs() < 1e-13, "({a}, {b}) at {x}: {s}");
        }
    }
    for b in [0.5, 1.5, 4.0] {
        for x in [1e-3f64, 0.2, 0.9] {
            let exact = 1.0 - (1.0 - x).powf(b);
            let got = incomplete_beta(1.0, b, x);
            assert!(
                (got - exact).abs() < 1e-13 * exact.max(1e-3),
                "{got} against {exact}"
            );
        }
    }
}

/// `ch F(ch, d) -> chi^2_ch` as `d -> infinity`: at `d = 10^7`, for `ch = 2` the exact
/// `chi^2_2` quantile `-2 ln p` to `1e-5` (the finite `d` shifts it by `O(q / d)`); for
/// `ch = 3` at `p = 1e-2` the Wilson–Hilferty approximation ([`chi_square_quantile`]) within
/// 1 % (0.2 % off the exact 11.34 there; in the far tails it is above the exact quantile:
/// 38.5 against 35.4 for `chi^2_3` at `1e-7`, 16.2 against 15.1 for `chi^2_1` at `1e-4`, so it
/// is no reference there). At `d = 3` (one probe, one cell) the F quantile is more than
/// twice the chi-square one for `ch = 1` and `3`.
#[test]
fn many_probe_terms_give_the_chi_square_quantile() {
    for p in [1e-2f64, 1e-4, 1e-7] {
        let f = 2.0 * f_upper_quantile(2.0, 1e7, p);
        let exact = -2.0 * p.ln();
        assert!(
            ((f - exact) / exact).abs() < 1e-5,
            "ch 2, p {p}: {f} against {exact}"
        );
    }
    for ch in [1usize, 3] {
        for (i, p) in [1e-2, 1e-4, 1e-7].into_iter().enumerate() {
            let f = ch as f64 * f_upper_quantile(ch as f64, 1e7, p);
            let chi = chi_square_quantile(ch, p);
            if ch == 3 && i == 0 {
                assert!(
                    ((f - chi) / chi).abs() < 0.01,
                    "ch {ch}, p {p}: {f} against {chi}"
                );
            }
            let few = ch as f64 * f_upper_quantile(ch as f64, 3.0, p);
            assert!(few > 2.0 * chi, "d = 3: {few} against {chi}");
        }
    }
}

/// The statistic of the test on random noise-only inputs: `|c|^2` over `ch` channels of
/// `N(0, g)` against `v`, the mean of `d` squared probe coefficients `N(0, g)` (`g` drawn per
/// trial: the test does not depend on it). With the F quantile the false alarms at the level
/// `p` are `Binomial(N, p)`: within 5 standard deviations of `N p` (a seeded draw; a correct
/// quantile fails with probability below `1e-5`). The chi-square quantile, which ignores the
/// spread of `v`, lands far outside the bound with few probe terms.
#[test]
fn false_alarm_rate_is_the_stated_one_for_any_probe_count() {
    let mut rng = Pcg64::seed_from_u64(40);
    let trials = 200_000usize;
    let p = 1e-3;
    let expected = trials as f64 * p;
    let bound = 5.0 * (expected * (1.0 - p)).sqrt();
    for (ch, d) in [
        (1usize, 3usize),
        (3, 3),
        (3, 12),
        (3, 27),
        (1, 27),
        (3, 108),
    ] {
        let q_f = ch as f64 * f_upper_quantile(ch as f64, d as f64, p);
        let q_chi = chi_square_quantile(ch, p);
        let (mut alarms_f, mut alarms_chi) = (0usize, 0usize);
        for _ in 0..trials {
            let g: f64 = 0.1 + 10.0 * rng.random::<f64>();
            let c2: f64 = (0..ch).map(|_| g * normal(&mut rng).powi(2)).sum();
            let v: f64 = (0..d).map(|_| g * normal(&mut rng).powi(2)).sum::<f64>() / d as f64;
            alarms_f += usize::from(c2 > v * q_f);
            alarms_chi += usize::from(c2 > v * q_chi);
        }
        assert!(
            (alarms_f as f64 - expected).abs() <= bound,
            "ch {ch}, d {d}: {alarms_f} false alarms with the F quantile, {expected} +- {bound}"
        );
        if d <= 27 {
            assert!(
                alarms_chi as f64 > expected + bound,
                "ch {ch}, d {d}: the chi-square quantile gave {alarms_chi} (expected more \
                 than {expected} +- {bound})"
            );
        }
    }
}
