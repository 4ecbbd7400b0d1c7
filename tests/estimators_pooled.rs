//! The noise of a pixel's mean pooled over its 3 x 3 neighbourhood (`image::estimate::pooled`).
//!
//! - **Unbiased and steadier where the noise is even**: on per-pixel estimates drawn as
//!   `v chi²_k / k` (what a difference estimate of `k` blocks gives on Gaussian noise of
//!   variance `v`), the pooled estimates' mean stays within 5 % of `v` (the cap
//!   `min(vbar, 4 v_P)` binds only where the own draw is below a quarter of the
//!   neighbourhood's: at `k = 6` a few percent of the pixels, lowering the mean by about 1 %)
//!   and their spread (coefficient of variation) is at most 0.6 of the own estimates' (nine
//!   overlapping estimates: `1/3` for independent ones, more for the overlap and the cap).
//! - **Outliers keep their own**: a pixel with a sample above every sample of its eight
//!   neighbours (a firefly) keeps its `v_P`; so does one below them all.
//! - **Bounds** (proptest): every pooled value lies in `[min_{3x3} v, POOL_CAP v_P]`, and
//!   pixels not within their neighbours' range are unchanged bit for bit.

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::estimate::pooled::{pool_variance, within_neighbours, POOL_CAP};
use rkwave::image::estimate::PixelStatistics;
use rkwave::image::{ImagePlane, ImageSamples};

fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// `v chi²_k / k`.
fn chi2_estimate(rng: &mut Pcg64, v: f64, k: usize) -> f64 {
    v * (0..k).map(|_| normal(rng).powi(2)).sum::<f64>() / k as f64
}

fn mean_and_cv(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|y| (y - m).powi(2)).sum::<f64>() / n;
    (m, var.sqrt() / m)
}

#[test]
fn pooling_is_unbiased_and_steadier_where_the_noise_is_even() {
    let (w, h, v) = (64, 64, 2.5e-3);
    for (seed, k) in [(1u64, 6usize), (2, 12), (3, 30)] {
        let mut rng = Pcg64::seed_from_u64(seed);
        let own: Vec<f64> = (0..w * h).map(|_| chi2_estimate(&mut rng, v, k)).collect();
        let mut variance = vec![own.clone()];
        let report = pool_variance(&mut variance, &vec![true; w * h], w, h);
        let (m_own, cv_own) = mean_and_cv(&own);
        let (m_pool, cv_pool) = mean_and_cv(&variance[0]);
        println!(
            "k {k}: own mean {:.4} cv {cv_own:.3}; pooled mean {:.4} cv {cv_pool:.3}; capped {}",
            m_own / v,
            m_pool / v,
            report.capped_pixels
        );
        assert!((m_pool / v - 1.0).abs() <= 0.05, "k {k}: {}", m_pool / v);
        assert!(cv_pool <= 0.6 * cv_own, "k {k}: {cv_pool} vs {cv_own}");
        assert_eq!(report.pooled_pixels, w * h);
    }
}

/// Samples on a `w x h` plane, four a pixel at the strata centres, all of value `base`
/// except pixel `(fx, fy)`'s first sample, `spike`.
fn samples_with_one_spike(
    w: usize,
    h: usize,
    base: f64,
    fx: usize,
    fy: usize,
    spike: f64,
) -> ImageSamples {
    let plane = ImagePlane::new(w, h).unwrap();
    let (mut xs, mut ys, mut vs) = (vec![], vec![], vec![]);
    for y in 0..h {
        for x in 0..w {
            for (i, (dx, dy)) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
                .into_iter()
                .enumerate()
            {
                xs.push(x as f64 + dx);
                ys.push(y as f64 + dy);
                vs.push(if (x, y, i) == (fx, fy, 0) {
                    spike
                } else {
                    base + 0.01 * ((x + y + i) % 3) as f64
                });
            }
        }
    }
    ImageSamples::new(plane, xs, ys, vec![vs]).unwrap()
}

#[test]
fn a_sample_outside_the_neighbours_range_keeps_the_own_noise() {
    let (w, h) = (9, 7);
    for spike in [50.0, -50.0] {
        let samples = samples_with_one_spike(w, h, 0.3, 4, 3, spike);
        let stats = PixelStatistics::new(&samples);
        let within = within_neighbours(&stats);
        let firefly = 3 * w + 4;
        assert!(!within[firefly], "spike {spike}");
        // its neighbours hold it among their neighbours' samples: within
        assert!(within[2 * w + 4] && within[3 * w + 3]);
        let mut variance = vec![(0..w * h)
            .map(|p| if p == firefly { 600.0 } else { 1e-4 })
            .collect::<Vec<f64>>()];
        let report = pool_variance(&mut variance, &within, w, h);
        assert_eq!(variance[0][firefly], 600.0);
        // a quiet neighbour does not take the firefly's noise beyond the cap
        assert!(variance[0][2 * w + 4] <= POOL_CAP * 1e-4 * (1.0 + 1e-12));
        assert!(report.own_pixels >= 1 && report.capped_pixels >= 8);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    #[test]
    fn pooled_values_lie_between_the_neighbourhood_least_and_the_cap(
        seed in any::<u64>(),
        w in 1usize..12,
        h in 1usize..12,
        share in 0.0f64..1.0,
    ) {
        let mut rng = Pcg64::seed_from_u64(seed);
        let own: Vec<Vec<f64>> = (0..2)
            .map(|_| (0..w * h).map(|_| 10f64.powf(rng.random_range(-6.0..1.0))).collect())
            .collect();
        let within: Vec<bool> = (0..w * h).map(|_| rng.random::<f64>() < share).collect();
        let mut variance = own.clone();
        let report = pool_variance(&mut variance, &within, w, h);
        prop_assert_eq!(report.pooled_pixels + report.own_pixels, w * h);
        for (c, v) in variance.iter().enumerate() {
            for p in 0..w * h {
                if !within[p] {
                    prop_assert_eq!(v[p].to_bits(), own[c][p].to_bits());
                    continue;
                }
                let (x, y) = (p % w, p / w);
                let mut least = f64::INFINITY;
                for yy in y.saturating_sub(1)..(y + 2).min(h) {
                    for xx in x.saturating_sub(1)..(x + 2).min(w) {
                        least = least.min(own[c][yy * w + xx]);
                    }
                }
                prop_assert!(v[p] >= least * (1.0 - 1e-12), "{} < {}", v[p], least);
                prop_assert!(v[p] <= POOL_CAP * own[c][p] * (1.0 + 1e-12));
            }
        }
    }
}
