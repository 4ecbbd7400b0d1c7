//! The noise test with one probe channel (the renderer plan's `RENDERER_PROBES`) against four
//! (the in-process default), on a scene of known noise: a bilinear polynomial (every wavelet
//! coefficient of `p = 2` is zero, so the fit's detail and residuals are noise alone) plus
//! Gaussian noise of deviation `SIGMA`.

mod common;

use rkwave::image::adaptive::{refine_image, AdaptiveParams, ImageOracle, ImagePlan, NoisyOracle};
use rkwave::image::ImagePlane;

use rkwave::image::adaptive::significance::chi_square_quantile;
use rkwave::image::adaptive::{QuadTree, Significance};

use common::rendered::assert_noise_not_chased;
use common::scenes::polynomial;

/// Noise deviation: 5 % of a unit range.
const SIGMA: f64 = 0.05;

const ORACLE: NoisyOracle<'static> = NoisyOracle {
    inner: &polynomial,
    sigma: SIGMA,
    seed: 7,
};

/// The renderer's plan of a `side²` image at 4 spp with `probes` probe channels.
fn plan_params(side: usize, probes: usize) -> (ImagePlane, AdaptiveParams) {
    let plane = ImagePlane::new(side, side).unwrap();
    let mut params = AdaptiveParams::renderer_plan();
    params.stop.budget = 4 * plane.pixels();
    params.noise.probes = probes;
    (plane, params)
}

/// The noise level and the mean variance `v_P` over the parents of the base slots from the
/// base round's fit (PCG to the solver's own `1e-4`) with `probes` probe channels.
fn base_test(probes: usize) -> (f64, f64, usize) {
    let (significance, tree, _, m) = base_fit(probes);
    let s = significance;
    let parents: Vec<_> = tree.leaves().iter().filter_map(|c| c.parent()).collect();
    let v = parents.iter().map(|&p| s.variance(&tree, p)).sum::<f64>() / parents.len() as f64;
    (s.level.sigma, v, m)
}

/// The base round's test, tree and coefficients (one channel) with `probes` probe channels,
/// and the samples fitted.
fn base_fit(probes: usize) -> (Significance, QuadTree, Vec<f64>, usize) {
    let (plane, params) = plan_params(128, probes);
    let plan = ImagePlan::new(plane, &params).unwrap();
    let base = plan.base_positions();
    let values: Vec<f64> = base
        .xs
        .iter()
        .zip(&base.ys)
        .map(|(&x, &y)| {
            let mut v = [0.0];
            ORACLE.sample(x, y, &mut v);
            v[0]
        })
        .collect();
    let (fit, significance) = plan.fit(&base.xs, &base.ys, &[&values]).unwrap();
    let s = significance.expect("the renderer plan runs the noise test");
    assert_eq!(s.level.probes, probes, "the probes fitted are reported");
    let coefficients = fit.coefficients[0].clone();
    (s, plan.tree().clone(), coefficients, base.xs.len())
}

/// The renderer plan fits one probe channel by default.
#[test]
fn renderer_plan_fits_one_probe() {
    assert_eq!(AdaptiveParams::renderer_plan().noise.probes, 1);
    assert_eq!(AdaptiveParams::default().noise.probes, 4);
}

/// On the same base samples (at 128² and 4 spp the base covers every pixel with two:
/// `m = 32,768`), one probe and four estimate the same noise and the same coefficient
/// variance.
///
/// * `sigma = sqrt(median(r^2) / median(r_e^2))`: a median of `n` squared normal deviates has
///   a relative spread of `1 / (2 f(0.455) 0.455 sqrt(n)) = 2.33 / sqrt(n)` (`f` the `chi^2_1`
///   density at its median), so `sigma` with `k` probes spreads by `1.17 sqrt((1 + 1/k) / m)`:
///   0.9 % at `k = 1`. Both are held within 5 % of the true `SIGMA` (over 5 spreads), and
///   within 3 % of each other (they share the image channel's median: `1.17 sqrt(1.25 / m)`
///   = 0.7 % apart, 4 spreads).
/// * `v_P` is the larger of the cell's own mean of `3 k` squares and its neighbourhood's of up
///   to `27 k`, each unbiased for `G^{-1}_aa`; the larger of two is biased up, by
///   `E max(chi^2_{3k} / 3k, chi^2_{27k} / 27k)` = 1.33 at `k = 1` and 1.17 at `k = 4` for
///   independent squares, so the mean over the parents is expected at about 1.13 times four
///   probes' (less where neighbouring coefficients are correlated, which narrows the gap).
///   Held in `[0.95, 1.3]`: below 0.95 one probe would be biased low (more false alarms),
///   above 1.3 it would make the test markedly less sensitive than four.
#[test]
fn one_probe_estimates_the_four_probe_noise_level() {
    let (sigma1, v1, m) = base_test(1);
    let (sigma4, v4, m4) = base_test(4);
    assert_eq!(m, m4);
    assert_eq!(m, 32_768, "two base samples a pixel");
    for (k, s) in [(1, sigma1), (4, sigma4)] {
        assert!(
            (s / SIGMA - 1.0).abs() < 0.05,
            "sigma with {k} probes {s}, true {SIGMA}"
        );
    }
    assert!(
        (sigma1 / sigma4 - 1.0).abs() < 0.03,
        "sigma {sigma1} (1 probe) against {sigma4} (4 probes)"
    );
    let ratio = v1 / v4;
    assert!(
        (0.95..=1.3).contains(&ratio),
        "mean v_P {v1} (1 probe) against {v4} (4 probes): ratio {ratio}"
    );
}

/// The renderer's plan with its one probe on the noisy polynomial: noise alone deepens at
/// most one round (false-alarm rate 1 % a round, about 10 rounds; the draw is fixed, so the
/// test is deterministic), the tree stays within one step of the base, and the budget is
/// spent by densifying instead. A noise test whose single probe understated `v_P` would
/// chase the noise down to the depth limit (as the test switched off does: asserted in
/// `tests/image_adaptive_noise.rs`).
#[test]
fn one_probe_does_not_chase_the_noise() {
    let (plane, params) = plan_params(48, 1);
    let run = refine_image(&ORACLE, plane, &params).unwrap();
    assert_noise_not_chased(&run);
    assert!(run
        .report
        .rounds
        .iter()
        .all(|r| r.noise.as_ref().is_some_and(|n| n.probes == 1)));
    assert!(
        run.report.notes.iter().any(|n| n.contains("1 probe")),
        "{:?}",
        run.report.notes
    );
}

/// The test's false-alarm rate on noise alone, through the plan's own fit: on the noisy
/// polynomial every detail coefficient is noise, so at the level `p` per function
/// ([`Significance::threshold_at`]: `ch F(ch, d)`'s quantile, `d` the probe terms of `v_C`)
/// the functions of the base tree (`N = 16,320`, cells of every step) exceeding it are
/// counted, with one probe and with four, at `p = 1e-2` and `1e-3` (seeded: deterministic).
///
/// The `F(ch, d)` model takes the `d` squares pooled in `v_C` as independent and of the
/// function's own variance; in the fit neighbouring coefficients are correlated and their
/// variances differ (the sample density varies), which lowers the effective `d`, while the
/// `max` with the cell's own estimate raises `v_C`. Measured (this draw): one probe, `p =
/// 1e-2`: 230 alarms for a nominal 163 (1.4 `p`; the chi-square quantile 337, 2.1 `p`);
/// `p = 1e-3`: 67 for 16 (4.1 `p`; chi-square 110, 6.7 `p`); four probes 211 and 47 (chi-square
/// 232 and 55). So the nominal rate is **not** reached in the plan's fit, and this test is a
/// guard against a worse test, not a proof of the rate: the count at most `Binomial(N, 5 p)`'s
/// mean plus 5 standard deviations, and with one probe below the chi-square quantile's
/// count (the F quantile is larger for any `d`, so it only fails if the counts were wrong).
/// The statistic itself, on independent draws, has the nominal rate
/// (`tests/significance_quantile.rs`).
#[test]
fn noise_alone_false_alarms_within_the_binomial_bound() {
    let mut failures = Vec::new();
    for probes in [1, 4] {
        let (s, tree, c, _) = base_fit(probes);
        for p in [1e-2, 1e-3] {
            let (mut n, mut alarms, mut alarms_chi) = (0usize, 0usize, 0usize);
            for f in tree.functions() {
                let Some(cell) = tree.cell_of_function(f) else {
                    continue;
                };
                n += 1;
                alarms += usize::from(c[f].abs() > s.threshold_at(&tree, cell, p));
                let chi =
                    s.level.sigma * (s.variance(&tree, cell) * chi_square_quantile(1, p)).sqrt();
                alarms_chi += usize::from(c[f].abs() > chi);
            }
            let mean = n as f64 * 5.0 * p;
            let bound = mean + 5.0 * (mean * (1.0 - 5.0 * p)).sqrt();
            println!(
                "{probes} probe(s), p {p}: {alarms} of {n} functions (nominal mean {:.1}, \
                 bound {bound:.1}); chi-square quantile {alarms_chi}",
                n as f64 * p
            );
            if alarms as f64 > bound || (probes == 1 && alarms >= alarms_chi) {
                failures.push(format!(
                    "{probes} probe(s), p {p}: {alarms} of {n} (bound {bound:.1}, chi-square \
                     quantile {alarms_chi})"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}
