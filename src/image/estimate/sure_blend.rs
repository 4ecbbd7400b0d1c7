//! Two estimates of the same pixels combined by the SURE of the combination itself.
//!
//! For estimates `a = f(m)` and `b = g(m)` of the box pixels `m` (the mean of each pixel's
//! samples, unbiased with variance `v_P`) with divergences `d^a_P = da_P / dm_P` and `d^b_P`,
//! the combination `x_w = w a + (1 - w) b` has divergence `w d^a + (1 - w) d^b`, so its SURE
//! over a window `W` (per channel weighted by `omega`),
//!
//! `SURE_W(w) = sum_W omega ((x_w - m)² - v + 2 v (w d^a + (1 - w) d^b))`,
//!
//! is a quadratic in `w` fixed by its two ends, the estimates' own SUREs `R^a_W = SURE_W(1)`
//! and `R^b_W = SURE_W(0)`, and the observable `Q_W = sum_W omega (a - b)²`:
//!
//! `SURE_W(w) = (1 - w) R^b_W + w R^a_W - w (1 - w) Q_W`
//!
//! (expand `(x_w - m)² = (b - m)² + 2 w (b - m)(a - b) + w² (a - b)²`: the divergence term is
//! linear in `w`, and `2 (b - m)(a - b) = (a - m)² - (b - m)² - (a - b)²`). No covariance of
//! the two errors is needed: `Q_W` carries it. With `Q_W > 0` its least value over `[0, 1]` is at
//!
//! `w_W = min(max((R^b_W - R^a_W + Q_W) / (2 Q_W), 0), 1)`,
//!
//! where `SURE_W(w_W) <= min(R^a_W, R^b_W)`. Where the errors are uncorrelated,
//! `E[Q_W] = E[R^a_W] + E[R^b_W]` (true risks) and `w_W` is the inverse-risk weight
//! `R^b / (R^a + R^b)` ([`super::blend`], the least variance for uncorrelated errors); where
//! both estimates err the same way (texture past Nyquist that both smooth) `Q_W` is smaller
//! than the sum of the risks and the weight moves to the better estimate. Where `Q_W = 0`
//! the two agree on the window and the less risky end is taken (`a` only where strictly
//! less); where a sum is not finite, `w = 0` (`b`), counted.

/// The weights of least SURE of the combination, and what they did.
#[derive(Debug, Clone, PartialEq)]
pub struct SureWeights {
    /// `w_P`, the weight of `a` per pixel (`1 - w_P` that of `b`).
    pub weight: Vec<f64>,
    /// Pixels at `w = 0` (all `b`).
    pub at_zero: usize,
    /// Pixels at `w = 1` (all `a`).
    pub at_one: usize,
    /// Pixels whose window had `Q_W = 0` (the estimates agree there).
    pub flat: usize,
    /// Pixels whose risks or `Q_W` were not finite (`w = 0`).
    pub not_finite: usize,
}

/// `SURE_W(w) = (1 - w) R^b + w R^a - w (1 - w) Q` (module docs).
pub fn combination_risk(w: f64, risk_a: f64, risk_b: f64, q: f64) -> f64 {
    (1.0 - w) * risk_b + w * risk_a - w * (1.0 - w) * q
}

/// The weights `w_W` of `a` against `b` of least SURE of the combination (module docs), from
/// the estimates' own risks `risk_a`, `risk_b` and `q` = `Q_W`, per pixel (each its
/// window's, on one scale).
///
/// Panics if the three are not of one length.
pub fn weights_from_risks(risk_a: &[f64], risk_b: &[f64], q: &[f64]) -> SureWeights {
    assert!(
        risk_a.len() == q.len() && risk_b.len() == q.len(),
        "one risk of each estimate and one Q a pixel"
    );
    let mut out = SureWeights {
        weight: vec![0.0; q.len()],
        at_zero: 0,
        at_one: 0,
        flat: 0,
        not_finite: 0,
    };
    for (p, ((&ra, &rb), &qp)) in risk_a.iter().zip(risk_b).zip(q).enumerate() {
        let wp = if !(ra.is_finite() && rb.is_finite() && qp.is_finite()) {
            out.not_finite += 1;
            0.0
        } else if qp > 0.0 {
            ((rb - ra + qp) / (2.0 * qp)).clamp(0.0, 1.0)
        } else {
            out.flat += 1;
            if ra < rb {
                1.0
            } else {
                0.0
            }
        };
        out.weight[p] = wp;
        if wp == 0.0 {
            out.at_zero += 1;
        } else if wp == 1.0 {
            out.at_one += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::estimate::blend::combine;
    use crate::image::estimate::blend::inverse_risk_weight;
    use crate::image::ImagePlane;
    use crate::image::PixelImage;

    struct Rng(u64);
    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// On random windows (values, box pixels, variances, divergences and weights `omega`),
    /// the SURE of the combination summed directly equals the quadratic from the two ends
    /// and `Q` at every `w` of a grid (to rounding), and the chosen weight is its least value
    /// over a grid of 201 weights in `[0, 1]`, at most both ends.
    #[test]
    fn the_quadratic_is_the_sure_of_the_combination_and_the_weight_its_minimiser() {
        let mut rng = Rng(11);
        for _ in 0..200 {
            let n = 1 + (rng.uniform() * 40.0) as usize;
            let mut draw = |lo: f64, hi: f64| -> Vec<f64> {
                (0..n).map(|_| lo + (hi - lo) * rng.uniform()).collect()
            };
            let (a, b, m) = (draw(-1.0, 1.0), draw(-1.0, 1.0), draw(-1.0, 1.0));
            let (v, da, db, omega) = (
                draw(0.0, 0.3),
                draw(-0.2, 1.2),
                draw(-0.2, 1.2),
                draw(0.5, 2.0),
            );
            let direct = |w: f64| -> f64 {
                (0..n)
                    .map(|i| {
                        let x = w * a[i] + (1.0 - w) * b[i];
                        let d = w * da[i] + (1.0 - w) * db[i];
                        omega[i] * ((x - m[i]).powi(2) - v[i] + 2.0 * v[i] * d)
                    })
                    .sum()
            };
            let q: f64 = (0..n).map(|i| omega[i] * (a[i] - b[i]).powi(2)).sum();
            let (ra, rb) = (direct(1.0), direct(0.0));
            let scale = 1.0 + ra.abs() + rb.abs() + q;
            for k in 0..=20 {
                let w = k as f64 / 20.0;
                let gap = (combination_risk(w, ra, rb, q) - direct(w)).abs();
                assert!(gap <= 1e-12 * scale, "w {w}: {gap}");
            }
            let chosen = weights_from_risks(&[ra], &[rb], &[q]).weight[0];
            let least = combination_risk(chosen, ra, rb, q);
            for k in 0..=200 {
                let w = k as f64 / 200.0;
                assert!(least <= direct(w) + 1e-12 * scale, "w {w} chosen {chosen}");
            }
            assert!(least <= ra.min(rb) + 1e-12 * scale);
        }
    }

    /// Where `Q` is the sum of the two risks (uncorrelated errors in expectation) the weight
    /// is the inverse-risk weight; where `Q` is smaller (positively correlated errors) it
    /// moves to the estimate of lesser risk.
    #[test]
    fn uncorrelated_errors_give_the_inverse_risk_weight_and_correlated_move_to_the_better() {
        for (ra, rb) in [(1.0, 3.0), (2.5e-4, 1e-4), (7.0, 7.0), (0.3, 2.2)] {
            let w = weights_from_risks(&[ra], &[rb], &[ra + rb]).weight[0];
            assert!(
                (w - inverse_risk_weight(ra, rb)).abs() <= 1e-12,
                "{ra} {rb}"
            );
            let correlated = weights_from_risks(&[ra], &[rb], &[0.5 * (ra + rb)]).weight[0];
            if ra < rb {
                assert!(correlated > w);
            } else if ra > rb {
                assert!(correlated < w);
            } else {
                assert_eq!(correlated, w);
            }
        }
    }

    /// `Q = 0` takes the less risky end, a NaN gives `w = 0`, both counted; the combination
    /// lies between its inputs.
    #[test]
    fn agreeing_estimates_and_nan_risks_are_decided_and_counted() {
        let s = weights_from_risks(
            &[1.0, 2.0, f64::NAN, 1.0],
            &[2.0, 1.0, 1.0, 1.0],
            &[0.0, 0.0, 1.0, 0.0],
        );
        assert_eq!(s.weight, vec![1.0, 0.0, 0.0, 0.0]);
        assert_eq!((s.flat, s.not_finite, s.at_zero, s.at_one), (3, 1, 3, 1));
        let plane = ImagePlane::new(4, 4).unwrap();
        let n = plane.pixels();
        let a = PixelImage {
            plane,
            channels: vec![vec![0.5; n], (0..n).map(|p| -(p as f64)).collect()],
        };
        let c = PixelImage {
            plane,
            channels: vec![(0..n).map(|p| p as f64).collect(), vec![0.25; n]],
        };
        let w: Vec<f64> = (0..n).map(|p| (p % 5) as f64 / 4.0).collect();
        let out = combine(&a, &c, &w);
        for ch in 0..2 {
            for p in 0..n {
                let (x, y, z) = (a.channels[ch][p], c.channels[ch][p], out.channels[ch][p]);
                assert!(x.min(y) - 1e-12 <= z && z <= x.max(y) + 1e-12);
            }
        }
    }
}
