//! The byte matrices `P_b = T_{b_7} T_{b_6} ... T_{b_0}` of single-level evaluation, each
//! product formed in double-double arithmetic (about 106 bits) and rounded to `f64` once.
//!
//! `(T_d)_{i,l} = sqrt2 h_{2i+d-l}` with `sqrt2` in double-double, so each entry of `P_b`
//! is within half an ulp of the product of the exact digit matrices of the `f64` filter `h`.
//! Products formed in `f64` instead take seven roundings of a `(2p-1)`-wide matrix product
//! plus the rounding of `sqrt2 h`: their scaling-function values are several times further
//! from the exact ones than tables rounded once, which limited the single-scale least squares
//! at round-off (docs/measurements/one-d.md, "Least squares at round-off").
//!
//! Cost: 30 double-double products for the 16 four-digit tables and 256 for the bytes,
//! `(2p - 1)^3` multiply-adds each, once per filter bank.

/// A double-double number `hi + lo`, `|lo| <= ulp(hi) / 2`.
#[derive(Clone, Copy, Default, Debug)]
struct Dd(f64, f64);

/// `a + b = s + e` exactly (Knuth's two-sum).
#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `a * b = p + e` exactly (Dekker's split product; no fused multiply-add needed).
#[inline]
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    const SPLIT: f64 = 134_217_729.0; // 2^27 + 1
    let p = a * b;
    let split = |x: f64| {
        let t = SPLIT * x;
        let hi = t - (t - x);
        (hi, x - hi)
    };
    let (ah, al) = split(a);
    let (bh, bl) = split(b);
    (p, ((ah * bh - p) + ah * bl + al * bh) + al * bl)
}

impl Dd {
    #[inline]
    fn renormalized(s: f64, e: f64) -> Dd {
        let t = s + e;
        Dd(t, e - (t - s))
    }
    #[inline]
    fn add(self, o: Dd) -> Dd {
        let (s, e) = two_sum(self.0, o.0);
        let (t, f) = two_sum(self.1, o.1);
        let r = Dd::renormalized(s, e + t);
        Dd::renormalized(r.0, r.1 + f)
    }
    #[inline]
    fn mul(self, o: Dd) -> Dd {
        let (p, e) = two_prod(self.0, o.0);
        Dd::renormalized(p, e + (self.0 * o.1 + self.1 * o.0))
    }
}

/// `sqrt(2)` to double-double precision: `SQRT_2 + (2 - SQRT_2^2) / (2 SQRT_2)`.
fn sqrt2() -> Dd {
    let hi = std::f64::consts::SQRT_2;
    let (p, e) = two_prod(hi, hi);
    Dd(hi, ((2.0 - p) - e) / (2.0 * hi))
}

/// `a b` for row-major `w x w` matrices.
fn product(a: &[Dd], b: &[Dd], w: usize) -> Vec<Dd> {
    let mut c = vec![Dd::default(); w * w];
    for i in 0..w {
        for k in 0..w {
            let x = a[i * w + k];
            if x.0 == 0.0 {
                continue;
            }
            for j in 0..w {
                let y = b[k * w + j];
                if y.0 != 0.0 {
                    c[i * w + j] = c[i * w + j].add(x.mul(y));
                }
            }
        }
    }
    c
}

/// `P_b` for `b = 0..256`, row-major `(2p-1) x (2p-1)` blocks, for the length-`2p` low-pass
/// filter `h`: `P_b = T_{b_7} ... T_{b_0}` (`b_7` the most significant bit), each entry the
/// double-double product rounded to `f64`.
pub(super) fn byte_tables(h: &[f64]) -> Vec<f64> {
    let w = h.len() - 1;
    let r2 = sqrt2();
    let digit = |d: usize| -> Vec<Dd> {
        let mut t = vec![Dd::default(); w * w];
        for i in 0..w {
            for l in 0..w {
                let k = 2 * i as i64 + d as i64 - l as i64;
                if (0..h.len() as i64).contains(&k) {
                    t[i * w + l] = r2.mul(Dd(h[k as usize], 0.0));
                }
            }
        }
        t
    };
    let t = [digit(0), digit(1)];
    // Four-digit tables N_q = T_{q_3} T_{q_2} T_{q_1} T_{q_0}, built one leading digit at a
    // time: the tables of k + 1 digits are T_d times those of k digits.
    let mut nibbles: Vec<Vec<Dd>> = vec![t[0].clone(), t[1].clone()];
    for digits in 1..4 {
        let mut next = Vec::with_capacity(nibbles.len() * 2);
        for td in &t {
            for n in &nibbles {
                next.push(product(td, n, w));
            }
        }
        // Index: leading digit d is bit `digits` of the new index.
        debug_assert_eq!(next.len(), 1 << (digits + 1));
        nibbles = next;
    }
    let mut out = Vec::with_capacity(256 * w * w);
    for b in 0..256usize {
        let p = product(&nibbles[b >> 4], &nibbles[b & 15], w);
        out.extend(p.iter().map(|x| x.0 + x.1));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Double-double products are exact to ~1e-32 relative: `(1 + 2^-30)^2` has the
    /// `2^-60` term an `f64` product loses.
    #[test]
    fn double_double_keeps_what_f64_loses() {
        let a = Dd(1.0 + 2f64.powi(-30), 0.0);
        let p = a.mul(a);
        assert_eq!(p.0, 1.0 + 2f64.powi(-29));
        assert_eq!(p.1, 2f64.powi(-60));
        let s = sqrt2().mul(sqrt2());
        assert!((s.0 - 2.0).abs() + s.1.abs() < 1e-30, "{s:?}");
    }

    /// Against the tables multiplied in `f64` (the previous construction): the same matrices
    /// to the rounding of seven `f64` products (a few `1e-15`), and the identity
    /// `P_{0} v(0) = v(0)` of the values at the integers holds to `f64` rounding.
    #[test]
    fn byte_tables_match_f64_products() {
        for p in [1usize, 2, 3, 6, 10] {
            let bank = crate::basis::FilterBank::new(p, crate::basis::FilterFamily::Extremal)
                .expect("bank");
            let h = &bank.interior.h;
            let w = 2 * p - 1;
            let tables = byte_tables(h);
            let digit = |d: usize| crate::basis::cdv::digit_matrix(h, d);
            for b in [0usize, 1, 77, 128, 255] {
                let mut m = nalgebra::DMatrix::<f64>::identity(w, w);
                for bit in (0..8).rev() {
                    m *= digit((b >> bit) & 1);
                }
                for i in 0..w {
                    for l in 0..w {
                        let d = (tables[b * w * w + i * w + l] - m[(i, l)]).abs();
                        assert!(d < 1e-13, "p = {p}, byte {b}, ({i}, {l}): {d:e}");
                    }
                }
            }
            let v0 = &bank.interior.values_at_integers;
            for i in 0..w {
                let pv: f64 = (0..w).map(|l| tables[i * w + l] * v0[l]).sum();
                assert!((pv - v0[i]).abs() < 1e-14, "p = {p}: P_0 v(0) at {i}");
            }
        }
    }
}
