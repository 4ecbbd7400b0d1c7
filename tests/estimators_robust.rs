//! The robust candidate for heavy-tailed samples ([`robust_estimate`]): its bias within the
//! bound its module states, on synthetic samples from a lognormal bulk with a Pareto tail of
//! known mean (fireflies), stationary and with the tail on one half of the plane only.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rkwave::image::estimate::robust::{robust_estimate, KAPPA, ROBUST_HALF};
use rkwave::image::splat::PixelBins;
use rkwave::image::{ImagePlane, ImageSamples};

const SIDE: usize = 40;
const SPP: usize = 4;
/// Firefly probability, Pareto scale and shape (finite variance: shape > 2).
const P_TAIL: f64 = 0.03;
const X_M: f64 = 5.0;
const ALPHA: f64 = 2.5;

/// A standard normal deviate (Box–Muller).
fn normal(rng: &mut Pcg64) -> f64 {
    let u: f64 = rng.random::<f64>().max(1e-300);
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
}

/// The bulk: lognormal, median 0.3, `sigma = 0.5`, mean `0.3 e^{0.125}`.
fn bulk_mean() -> f64 {
    0.3 * (0.125f64).exp()
}

/// The Pareto tail's mean `alpha x_m / (alpha - 1)`.
fn tail_mean() -> f64 {
    ALPHA * X_M / (ALPHA - 1.0)
}

/// Samples: in pixels with `tail(px)` the mixture `(1 - p) bulk + p Pareto`, elsewhere the
/// bulk alone; the pixel integrals are the mixture's mean.
fn samples(seed: u64, tail: fn(usize) -> bool) -> (ImageSamples, Vec<f64>) {
    let mut rng = Pcg64::seed_from_u64(seed);
    let (mut xs, mut ys, mut vs) = (vec![], vec![], vec![]);
    let mut mu = vec![0.0; SIDE * SIDE];
    for py in 0..SIDE {
        for px in 0..SIDE {
            let heavy = tail(px);
            mu[py * SIDE + px] = if heavy {
                (1.0 - P_TAIL) * bulk_mean() + P_TAIL * tail_mean()
            } else {
                bulk_mean()
            };
            for _ in 0..SPP {
                xs.push(px as f64 + rng.random::<f64>());
                ys.push(py as f64 + rng.random::<f64>());
                let v = if heavy && rng.random::<f64>() < P_TAIL {
                    X_M * (1.0 - rng.random::<f64>()).powf(-1.0 / ALPHA)
                } else {
                    0.3 * (0.5 * normal(&mut rng)).exp()
                };
                vs.push(v);
            }
        }
    }
    let plane = ImagePlane::new(SIDE, SIDE).unwrap();
    (ImageSamples::new(plane, xs, ys, vec![vs]).unwrap(), mu)
}

/// Mean and standard error over replications of each pixel's robust estimate minus its
/// integral.
fn bias(tail: fn(usize) -> bool, reps: u64) -> (Vec<f64>, Vec<f64>) {
    let n = SIDE * SIDE;
    let (mut sum, mut sum2) = (vec![0.0; n], vec![0.0; n]);
    for r in 0..reps {
        let (s, mu) = samples(500 + r, tail);
        let (image, _, report) = robust_estimate(&s, &PixelBins::new(&s), KAPPA, ROBUST_HALF);
        assert!(report.cut_samples > 0, "the tail is cut somewhere");
        for p in 0..n {
            let d = image.channels[0][p] - mu[p];
            sum[p] += d;
            sum2[p] += d * d;
        }
    }
    let k = reps as f64;
    let mean: Vec<f64> = sum.iter().map(|s| s / k).collect();
    let se = sum2
        .iter()
        .zip(&mean)
        .map(|(s2, m)| ((s2 / k - m * m) / (k - 1.0)).max(0.0).sqrt())
        .collect();
    (mean, se)
}

/// Pixels whose gate window (and the threshold's 3 x 3 neighbourhood) lies inside the plane,
/// and, for the half-plane case, on one side of the tail's edge at column `SIDE / 2`.
fn interior(px: usize, py: usize, away_from_edge: bool) -> bool {
    let h = ROBUST_HALF + 1;
    let inside = px >= h && py >= h && px + h < SIDE && py + h < SIDE;
    let side = !away_from_edge || px + h < SIDE / 2 || px >= SIDE / 2 + h;
    inside && side
}

/// Stationary tail: the robust estimate is unbiased (module docs: `E b_P = e_P`). Averaged
/// over the interior pixels and 40 replications, its error against the known mean is within
/// 4 standard errors (the standard error from the replications' spread of that average; a
/// false alarm below 1e-4 for an unbiased estimate), while the cut mean alone (the estimate
/// minus the energy put back) is biased by the tail's share: shown to be far outside.
#[test]
fn the_robust_estimate_is_unbiased_where_the_tail_is_stationary() {
    let reps = 40u64;
    let mut averages = vec![];
    for r in 0..reps {
        let (s, mu) = samples(900 + r, |_| true);
        let (image, _, _) = robust_estimate(&s, &PixelBins::new(&s), KAPPA, ROBUST_HALF);
        let pixels: Vec<usize> = (0..SIDE * SIDE)
            .filter(|&p| interior(p % SIDE, p / SIDE, false))
            .collect();
        let err = pixels
            .iter()
            .map(|&p| image.channels[0][p] - mu[p])
            .sum::<f64>()
            / pixels.len() as f64;
        averages.push(err);
    }
    let k = reps as f64;
    let mean = averages.iter().sum::<f64>() / k;
    let sd = (averages.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt();
    let se = sd / k.sqrt();
    let mu = (1.0 - P_TAIL) * bulk_mean() + P_TAIL * tail_mean();
    eprintln!("stationary: bias {mean:.4e} (standard error {se:.2e}) of mu {mu:.3}");
    assert!(
        mean.abs() <= 4.0 * se,
        "bias {mean:.4e}, standard error {se:.2e}"
    );
}

/// Tail on the left half only: where the window lies on one side of the edge, unbiased as
/// above (each pixel within 4 standard errors of its replications; over the ~500 pixels a
/// few such excursions are expected, so at most 2 % may exceed it); next to the edge the
/// bias lies within the bound the module states, `|E r_P - mu_P| <= max_{Q in W(P)} e_Q`,
/// with `e_Q <= p E[Pareto] = 0.25` (the excess over the threshold is at most the firefly's
/// value), plus 4 standard errors.
#[test]
fn the_robust_estimates_bias_stays_within_its_bound_beside_a_tail_edge() {
    let (mean, se) = bias(|px| px < SIDE / 2, 60);
    let bound = P_TAIL * tail_mean();
    let (mut far, mut far_out, mut worst_near) = (0usize, 0usize, 0.0f64);
    for py in 0..SIDE {
        for px in 0..SIDE {
            let p = py * SIDE + px;
            if interior(px, py, true) {
                far += 1;
                far_out += usize::from(mean[p].abs() > 4.0 * se[p]);
            } else if interior(px, py, false) {
                worst_near = worst_near.max(mean[p].abs() - 4.0 * se[p]);
                assert!(
                    mean[p].abs() <= bound + 4.0 * se[p],
                    "({px}, {py}): bias {:.3e} beyond the bound {bound:.3e} (se {:.2e})",
                    mean[p],
                    se[p]
                );
            }
        }
    }
    eprintln!(
        "half tail: {far_out} of {far} pixels away from the edge beyond 4 standard errors; \
         beside it the largest bias less 4 standard errors {worst_near:.3e} (bound {bound:.3e})"
    );
    assert!(
        far_out * 50 <= far,
        "{far_out} of {far} beyond 4 standard errors"
    );
}
