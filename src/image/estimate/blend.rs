//! Two estimates of the same pixels combined per pixel by their estimated risks.
//!
//! For estimates `a_P` and `b_P` of the pixel `t_P` with errors of variance `R^a_P` and
//! `R^b_P`, the combination `w_P a_P + (1 - w_P) b_P` (weights summing to 1, so no bias is
//! added where both are unbiased) has, for uncorrelated errors, the variance
//! `w² R^a + (1 - w)² R^b`, least at the inverse-risk weight
//!
//! `w_P = R^b_P / (R^a_P + R^b_P)`,
//!
//! where it is `R^a R^b / (R^a + R^b) <= min(R^a, R^b)`. With correlated errors the least
//! variance needs their covariance, which neither risk estimate gives; the inverse-risk weight
//! then still lies in `[0, 1]`, so each combined pixel lies between its two inputs and, the
//! squared error being convex, its error is at most the larger of the two.
//!
//! Risk estimates can be negative (SURE is unbiased, not positive); they are taken as
//! `max(R, 0)`. A zero risk takes all the weight (`w = 1` where `R^a = 0 < R^b`); where both are
//! zero, or either is not finite-or-infinite (NaN), the weight is `1/2`. An infinite risk takes
//! none.
//!
//! **More than two estimates** ([`inverse_risk_weights`], [`blend_by_risks`]): for `K`
//! estimates with uncorrelated errors of variances `R^k`, the weights summing to 1 that
//! minimise `sum_k w_k² R^k` are `w_k = (1 / R^k) / sum_j (1 / R^j)` (Lagrange: `w_k R^k` is
//! the same for every `k`), with the least variance `1 / sum_j (1 / R^j) <= min_k R^k`; for
//! `K = 2` this is the weight above. Zero risks share all the weight equally; infinite ones
//! take none; where every risk is infinite, or any is NaN, the weights are equal. Again each
//! combined pixel lies in the convex hull of its inputs.

use crate::image::PixelImage;

/// The weight `w = R^b / (R^a + R^b)` of the estimate of risk `risk_a` against one of risk
/// `risk_b` (module docs).
pub fn inverse_risk_weight(risk_a: f64, risk_b: f64) -> f64 {
    if risk_a.is_nan() || risk_b.is_nan() {
        return 0.5;
    }
    let (ra, rb) = (risk_a.max(0.0), risk_b.max(0.0));
    match (ra.is_infinite(), rb.is_infinite()) {
        (true, true) => 0.5,
        (true, false) => 0.0,
        (false, true) => 1.0,
        _ if ra + rb == 0.0 => 0.5,
        _ => rb / (ra + rb),
    }
}

/// The weights `w_k = (1 / R^k) / sum_j (1 / R^j)` of `K` estimates of risks `risks` (module
/// docs; negative risks count as 0).
pub fn inverse_risk_weights(risks: &[f64]) -> Vec<f64> {
    let k = risks.len();
    let equal = vec![1.0 / k as f64; k];
    if risks.iter().any(|r| r.is_nan()) {
        return equal;
    }
    let r: Vec<f64> = risks.iter().map(|x| x.max(0.0)).collect();
    let zeros = r.iter().filter(|&&x| x == 0.0).count();
    if zeros > 0 {
        return r
            .iter()
            .map(|&x| if x == 0.0 { 1.0 / zeros as f64 } else { 0.0 })
            .collect();
    }
    if r.iter().all(|x| x.is_infinite()) {
        return equal;
    }
    // scaled by the least risk so that tiny and huge risks neither overflow nor underflow
    let least = r.iter().copied().fold(f64::INFINITY, f64::min);
    let inv: Vec<f64> = r.iter().map(|&x| least / x).collect();
    let total: f64 = inv.iter().sum();
    inv.iter().map(|x| x / total).collect()
}

/// `sum_k w_{k,P} x^k_P` in every channel, `w_{k,P}` the [`inverse_risk_weights`] of the
/// risks `risks[k][P]`. Returns the image and the weights per estimate and pixel.
///
/// Panics if the images differ in plane or channels, or a risk list is not one per pixel.
pub fn blend_by_risks(images: &[&PixelImage], risks: &[&[f64]]) -> (PixelImage, Vec<Vec<f64>>) {
    assert!(
        !images.is_empty() && images.len() == risks.len(),
        "one risk list per estimate"
    );
    let plane = images[0].plane;
    let channels = images[0].channels.len();
    assert!(
        images
            .iter()
            .all(|x| x.plane == plane && x.channels.len() == channels),
        "the estimates are of one plane and channel count"
    );
    let pixels = plane.pixels();
    assert!(risks.iter().all(|r| r.len() == pixels), "one risk a pixel");
    let mut weights = vec![vec![0.0; pixels]; images.len()];
    let mut out = PixelImage::zeros(plane, channels);
    for p in 0..pixels {
        let w = inverse_risk_weights(&risks.iter().map(|r| r[p]).collect::<Vec<_>>());
        for (k, (&wk, image)) in w.iter().zip(images).enumerate() {
            weights[k][p] = wk;
            for (o, x) in out.channels.iter_mut().zip(&image.channels) {
                o[p] += wk * x[p];
            }
        }
    }
    (out, weights)
}

/// `w_P a_P + (1 - w_P) b_P` in every channel, `w_P` the [`inverse_risk_weight`] of the risks
/// per pixel (`risk_a[P]`, `risk_b[P]`). Returns the image and the weights of `a`.
///
/// Panics if the images differ in plane or channels, or a risk list is not one per pixel.
pub fn blend_by_risk(
    a: &PixelImage,
    risk_a: &[f64],
    b: &PixelImage,
    risk_b: &[f64],
) -> (PixelImage, Vec<f64>) {
    let pixels = a.plane.pixels();
    assert!(
        risk_a.len() == pixels && risk_b.len() == pixels,
        "one risk a pixel"
    );
    let weight: Vec<f64> = risk_a
        .iter()
        .zip(risk_b)
        .map(|(&ra, &rb)| inverse_risk_weight(ra, rb))
        .collect();
    (combine(a, b, &weight), weight)
}

/// `w_P a_P + (1 - w_P) b_P` in every channel.
///
/// Panics if the images differ in plane or channels or `weight` is not one a pixel.
pub fn combine(a: &PixelImage, b: &PixelImage, weight: &[f64]) -> PixelImage {
    assert_eq!(a.plane, b.plane, "the two estimates are of one plane");
    assert_eq!(
        a.channels.len(),
        b.channels.len(),
        "and of one channel count"
    );
    assert_eq!(weight.len(), a.plane.pixels(), "one weight a pixel");
    PixelImage {
        plane: a.plane,
        channels: a
            .channels
            .iter()
            .zip(&b.channels)
            .map(|(ca, cb)| {
                ca.iter()
                    .zip(cb)
                    .zip(weight)
                    .map(|((&x, &y), &w)| w * x + (1.0 - w) * y)
                    .collect()
            })
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image::ImagePlane;

    fn image(plane: ImagePlane, seed: u64) -> PixelImage {
        let mut s = seed;
        let mut next = move || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        PixelImage {
            plane,
            channels: (0..3)
                .map(|_| (0..plane.pixels()).map(|_| next()).collect())
                .collect(),
        }
    }

    /// The weight of the inverse-risk combination minimises `w² Ra + (1 - w)² Rb` (the
    /// variance of uncorrelated errors): its derivative `2 w Ra - 2 (1 - w) Rb` vanishes there,
    /// and the least variance is `Ra Rb / (Ra + Rb)`, below both.
    #[test]
    fn the_weight_minimises_the_variance_of_uncorrelated_errors() {
        for (ra, rb) in [(1.0, 3.0), (2.5e-4, 1e-4), (7.0, 7.0), (1e-9, 2.0)] {
            let w = inverse_risk_weight(ra, rb);
            assert!(
                (w * ra - (1.0 - w) * rb).abs() <= 1e-12 * (ra + rb),
                "{ra} {rb}"
            );
            let var = w * w * ra + (1.0 - w) * (1.0 - w) * rb;
            assert!((var - ra * rb / (ra + rb)).abs() <= 1e-12 * (ra + rb));
            assert!(var <= ra.min(rb) * (1.0 + 1e-12));
            // and the weights of the two estimates sum to 1 whichever is named first
            assert!((w + inverse_risk_weight(rb, ra) - 1.0).abs() <= 1e-15);
        }
    }

    #[test]
    fn an_infinite_risk_takes_no_weight_and_a_zero_risk_all() {
        assert_eq!(inverse_risk_weight(f64::INFINITY, 1.0), 0.0);
        assert_eq!(inverse_risk_weight(1.0, f64::INFINITY), 1.0);
        assert_eq!(inverse_risk_weight(0.0, 1.0), 1.0);
        assert_eq!(inverse_risk_weight(-3.0, 1.0), 1.0); // a negative SURE counts as 0
        assert_eq!(inverse_risk_weight(0.0, 0.0), 0.5);
        assert_eq!(inverse_risk_weight(f64::NAN, 1.0), 0.5);
        assert_eq!(inverse_risk_weight(f64::INFINITY, f64::INFINITY), 0.5);
    }

    /// The `K`-estimate weights minimise `sum_k w_k² R^k` under `sum_k w_k = 1`: every
    /// `w_k R^k` is the same (the Lagrange condition), the weights sum to 1, the variance is
    /// `1 / sum_k (1 / R^k)`, below every `R^k`; for two estimates they are the pair's weight.
    #[test]
    fn the_weights_of_k_estimates_minimise_the_variance_of_uncorrelated_errors() {
        for risks in [
            vec![1.0, 3.0, 0.5],
            vec![2.5e-4, 1e-4, 7e-2, 3e-9],
            vec![7.0, 7.0, 7.0],
        ] {
            let w = inverse_risk_weights(&risks);
            let sum: f64 = w.iter().sum();
            assert!((sum - 1.0).abs() <= 1e-12);
            let var: f64 = w.iter().zip(&risks).map(|(w, r)| w * w * r).sum();
            let least = 1.0 / risks.iter().map(|r| 1.0 / r).sum::<f64>();
            assert!((var - least).abs() <= 1e-12 * least, "{risks:?}");
            for (wk, rk) in w.iter().zip(&risks) {
                assert!((wk * rk - least).abs() <= 1e-12 * least);
                assert!(var <= rk * (1.0 + 1e-12));
            }
        }
        for (ra, rb) in [(1.0, 3.0), (2.5e-4, 1e-4)] {
            let w = inverse_risk_weights(&[ra, rb]);
            assert!((w[0] - inverse_risk_weight(ra, rb)).abs() <= 1e-15);
        }
        assert_eq!(inverse_risk_weights(&[0.0, 1.0, 0.0]), vec![0.5, 0.0, 0.5]);
        assert_eq!(inverse_risk_weights(&[f64::INFINITY, 1.0, 3.0])[0], 0.0);
        assert_eq!(inverse_risk_weights(&[f64::NAN, 1.0]), vec![0.5, 0.5]);
        assert_eq!(inverse_risk_weights(&[-1.0, 1.0]), vec![1.0, 0.0]);
    }

    /// Each pixel of the `K`-estimate blend lies between the least and largest of its inputs.
    #[test]
    fn the_blend_of_k_estimates_lies_in_their_range() {
        let plane = ImagePlane::new(9, 7).unwrap();
        let (a, b, c) = (image(plane, 1), image(plane, 2), image(plane, 3));
        let n = plane.pixels();
        let ra: Vec<f64> = (0..n).map(|p| 0.1 + p as f64).collect();
        let rb: Vec<f64> = (0..n).map(|p| 2.0 + (p % 5) as f64).collect();
        let rc: Vec<f64> = (0..n).map(|p| if p % 3 == 0 { 0.0 } else { 1.5 }).collect();
        let (out, w) = blend_by_risks(&[&a, &b, &c], &[&ra, &rb, &rc]);
        for p in 0..n {
            let total: f64 = w.iter().map(|wk| wk[p]).sum();
            assert!((total - 1.0).abs() <= 1e-12);
            for ch in 0..3 {
                let xs = [a.channels[ch][p], b.channels[ch][p], c.channels[ch][p]];
                let lo = xs.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let z = out.channels[ch][p];
                assert!(lo - 1e-12 <= z && z <= hi + 1e-12);
                if p % 3 == 0 {
                    assert_eq!(z.to_bits(), xs[2].to_bits());
                }
            }
        }
    }

    /// Where `b`'s risk is infinite the blend is `a` bit for bit, and vice versa; elsewhere
    /// each pixel lies between its inputs in every channel.
    #[test]
    fn the_blend_equals_one_input_where_the_other_risk_is_infinite_and_lies_between() {
        let plane = ImagePlane::new(9, 7).unwrap();
        let (a, b) = (image(plane, 1), image(plane, 2));
        let n = plane.pixels();
        let ra: Vec<f64> = (0..n)
            .map(|p| match p % 4 {
                0 => f64::INFINITY,
                _ => 0.1 + p as f64,
            })
            .collect();
        let rb: Vec<f64> = (0..n)
            .map(|p| match p % 4 {
                1 => f64::INFINITY,
                _ => 2.0 + (p % 5) as f64,
            })
            .collect();
        let (out, w) = blend_by_risk(&a, &ra, &b, &rb);
        assert_eq!(w.len(), n);
        for (p, wp) in w.iter().enumerate() {
            for c in 0..3 {
                let (x, y, z) = (a.channels[c][p], b.channels[c][p], out.channels[c][p]);
                match p % 4 {
                    0 => assert_eq!(z.to_bits(), y.to_bits()),
                    1 => assert_eq!(z.to_bits(), x.to_bits()),
                    _ => assert!(
                        x.min(y) - 1e-15 <= z && z <= x.max(y) + 1e-15,
                        "{x} {y} {z}"
                    ),
                }
            }
            assert!((0.0..=1.0).contains(wp));
        }
    }
}
