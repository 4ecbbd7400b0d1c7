//! The noise of a pixel's mean on uneven per-pixel counts ([`PixelNoise::equalise_counts`]).
//!
//! **Pure noise, uneven counts.** A 64 x 64 plane, each pixel holding 2, 3, 4, 6 or 8 samples
//! (drawn at random, 2 the most common) at uniform positions, values i.i.d. `N(0, 1)`: every
//! single difference estimate is unbiased for `s² = 1`, and the least of three is exact at 2
//! samples and low from 3 up. Asserted, per count class (at least 300 pixels each, so the mean
//! of `n_P v_P` has a relative standard error of at most `sqrt(2 / 300) = 8 %` at one block, far
//! less with more):
//! - before the equalisation, some class's mean `n_P v_P` is below 0.8 (the bias the
//!   equalisation removes exists at these positions);
//! - after it, every class's mean `n_P v_P` is within 15 % of the reference class's (2
//!   samples, `c_2 = 1`), i.e. of the true `s² = 1` (the class means are independent draws;
//!   15 % is about two standard errors of the smallest class at one block);
//! - the reference class's estimates did not move (bit for bit) and its factor is 1.
//!
//! **Uniform counts.** Every pixel with the same count: one class, factor 1, `v_P` bit for bit.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::estimate::PixelNoise;
use rkwave::image::splat::PixelBins;
use rkwave::image::{ImagePlane, ImageSamples};

const SIDE: usize = 64;

fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let t: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * t).cos()
}

/// Pure noise with the count of pixel `p` from `count(p, rng)`.
fn noise_samples(seed: u64, mut count: impl FnMut(&mut Pcg64) -> usize) -> ImageSamples {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut xs, mut ys, mut vs) = (vec![], vec![], vec![]);
    for py in 0..SIDE {
        for px in 0..SIDE {
            let n = count(&mut rng);
            for _ in 0..n {
                xs.push(px as f64 + rng.random::<f64>());
                ys.push(py as f64 + rng.random::<f64>());
                vs.push(normal(&mut rng));
            }
        }
    }
    ImageSamples::new(ImagePlane::new(SIDE, SIDE).unwrap(), xs, ys, vec![vs]).unwrap()
}

/// The mean of `n_P v_P` per count (ascending), over the pixels of each count.
fn class_means(noise: &PixelNoise) -> Vec<(usize, f64, usize)> {
    let mut sums = std::collections::BTreeMap::new();
    for (p, &n) in noise.count.iter().enumerate() {
        if n >= 2 {
            let e = sums.entry(n).or_insert((0.0, 0usize));
            e.0 += noise.mean_variance[0][p] * n as f64;
            e.1 += 1;
        }
    }
    sums.into_iter()
        .map(|(n, (s, k))| (n, s / k as f64, k))
        .collect()
}

#[test]
fn uneven_counts_on_pure_noise_are_brought_to_one_bias() {
    for seed in [1u64, 2, 3] {
        let s = noise_samples(seed, |rng| {
            let u: f64 = rng.random();
            // 2 samples for 40 % of the pixels, 15 % each for 3, 4, 6, 8
            match u {
                u if u < 0.40 => 2,
                u if u < 0.55 => 3,
                u if u < 0.70 => 4,
                u if u < 0.85 => 6,
                _ => 8,
            }
        });
        let bins = PixelBins::new(&s);
        let mut noise = PixelNoise::new(&s, &bins).unwrap();
        let before = class_means(&noise);
        let reference_before = noise.mean_variance.clone();
        let calibration = noise.equalise_counts(&s, &bins);
        let after = class_means(&noise);
        assert_eq!(calibration.reference_count, 2, "seed {seed}");
        assert!(before.iter().all(|&(_, _, k)| k >= 300), "{before:?}");
        assert!(
            before.iter().any(|&(_, m, _)| m < 0.8),
            "seed {seed}: no count class biased low before: {before:?}"
        );
        let reference = after[0].1;
        for &(n, m, _) in &after {
            assert!(
                (m / reference - 1.0).abs() <= 0.15,
                "seed {seed}: count {n} at {m:.3} against the reference's {reference:.3} \
                 (before {before:?})"
            );
        }
        for (p, &n) in noise.count.iter().enumerate() {
            if n == 2 {
                assert_eq!(
                    noise.mean_variance[0][p].to_bits(),
                    reference_before[0][p].to_bits()
                );
            }
        }
        let class2 = calibration.classes.iter().find(|c| c.count == 2).unwrap();
        assert_eq!(class2.factor, 1.0);
        assert!((class2.ratio - 1.0).abs() <= 1e-12, "{class2:?}");
        assert_eq!(
            calibration.moved_pixels(),
            noise.count.iter().filter(|&&n| n > 2).count()
        );
    }
}

#[test]
fn one_count_moves_nothing() {
    for n in [2usize, 4, 8] {
        let s = noise_samples(7 + n as u64, |_| n);
        let bins = PixelBins::new(&s);
        let mut noise = PixelNoise::new(&s, &bins).unwrap();
        let before = noise.mean_variance.clone();
        let calibration = noise.equalise_counts(&s, &bins);
        assert_eq!(calibration.reference_count, n);
        assert_eq!(calibration.classes.len(), 1);
        assert_eq!(calibration.classes[0].factor, 1.0);
        assert_eq!(calibration.moved_pixels(), 0);
        let bits = |v: &Vec<Vec<f64>>| -> Vec<u64> { v[0].iter().map(|x| x.to_bits()).collect() };
        assert_eq!(bits(&noise.mean_variance), bits(&before));
    }
}
