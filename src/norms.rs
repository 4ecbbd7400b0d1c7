//! Norms without overflow or underflow: `sqrt(sum x_i^2 / n)` for values up to `f64::MAX`.
//!
//! The sum of squares is kept as `scale^2 * ssq` with `scale = max |x_i|` seen so far (the
//! LAPACK `dnrm2` recurrence): `ssq` stays in `[1, n]`, so no square overflows or
//! underflows, and `rms = scale * sqrt(ssq / n)` is finite whenever every `x_i` is.

/// `sqrt(sum x_i^2 / n)` by the scaled recurrence; `0` for no values; `NaN` if any value is
/// `NaN`, `inf` only if a value is infinite.
pub fn rms(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut scale = 0.0f64;
    let mut ssq = 1.0f64;
    let mut n = 0usize;
    for x in values {
        n += 1;
        if x.is_nan() {
            return f64::NAN;
        }
        let a = x.abs();
        if a == 0.0 {
            continue;
        }
        if a.is_infinite() {
            return f64::INFINITY;
        }
        if scale < a {
            ssq = 1.0 + ssq * (scale / a) * (scale / a);
            scale = a;
        } else {
            ssq += (a / scale) * (a / scale);
        }
    }
    if n == 0 || scale == 0.0 {
        return 0.0;
    }
    scale * (ssq / n as f64).sqrt()
}

/// RMS of `a_i - b_i` over the common length, with each difference formed as
/// `a_i - b_i` (itself finite unless the two have opposite signs near `f64::MAX`; then
/// the halves are subtracted and the result doubled, so it stays finite).
pub fn rms_difference(a: &[f64], b: &[f64]) -> f64 {
    let halves = a
        .iter()
        .zip(b)
        .any(|(x, y)| (x - y).is_infinite() && x.is_finite() && y.is_finite());
    if halves {
        2.0 * rms(a.iter().zip(b).map(|(x, y)| x / 2.0 - y / 2.0))
    } else {
        rms(a.iter().zip(b).map(|(x, y)| x - y))
    }
}

/// A number for a message: positional for ordinary magnitudes, `{:e}` for the extreme
/// (`|x| >= 1e6` or `0 < |x| < 1e-4`), so no message prints hundreds of digits.
pub fn show(x: f64) -> String {
    let a = x.abs();
    if x.is_finite() && a != 0.0 && !(1e-4..1e6).contains(&a) {
        format!("{x:e}")
    } else {
        format!("{x}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn extremes_stay_finite_and_exact_cases_hold() {
        assert_eq!(rms([3.0, 4.0, 0.0, 0.0].iter().copied()), 2.5);
        assert_eq!(rms(std::iter::empty()), 0.0);
        let big = rms([f64::MAX, -f64::MAX]);
        assert!((big / f64::MAX - 1.0).abs() < 1e-15, "{big}");
        let tiny = rms([f64::MIN_POSITIVE * 1e-10; 4]);
        assert!(
            (tiny / (f64::MIN_POSITIVE * 1e-10) - 1.0).abs() < 1e-6,
            "{tiny}"
        );
        assert!(rms([1.0, f64::NAN]).is_nan());
        let d = rms_difference(&[f64::MAX, 0.0], &[-f64::MAX, 0.0]);
        assert!(d.is_infinite() || d > 1e308, "{d}");
        assert_eq!(rms_difference(&[1.0, 2.0], &[1.0, 2.0]), 0.0);
        assert_eq!(show(-1e308), "-1e308");
        assert_eq!(show(0.25), "0.25");
        assert_eq!(show(0.0), "0");
    }
}
