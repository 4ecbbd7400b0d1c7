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
    assert_eq!(a.plane, b.plane, "the two estimates are of one plane");
    assert_eq!(
        a.channels.len(),
        b.channels.len(),
        "and of one channel count"
    );
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
    let channels = a
        .channels
        .iter()
        .zip(&b.channels)
        .map(|(ca, cb)| {
            ca.iter()
                .zip(cb)
                .zip(&weight)
                .map(|((&x, &y), &w)| w * x + (1.0 - w) * y)
                .collect()
        })
        .collect();
    (
        PixelImage {
            plane: a.plane,
            channels,
        },
        weight,
    )
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
