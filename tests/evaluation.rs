//! Exact pointwise evaluation against independent references: a recursive evaluator of the
//! refinement equation at dyadic rationals (a different algorithm from the digit-matrix walk),
//! published exact values, the interval FWT, and identities (refinement between levels,
//! reflection symmetry, reproduction of polynomials) over random positions.

#![allow(clippy::needless_range_loop)] // the reference solver is written as plain index loops on purpose
use std::collections::HashMap;

use proptest::prelude::*;
use rkwave::basis::filters::daubechies_lowpass;
use rkwave::basis::{BasisValue, CdvBasis, FilterBank, FilterFamily, FunctionKind, Side};

/// `phi_std(k / 2^r)` by direct recursion on `phi(x) = sqrt2 sum_k h_k phi(2x - k)`,
/// memoized, starting from the values at the integers obtained by solving the eigenproblem
/// with plain Gaussian elimination (independent of rkwave's code).
struct Recursive {
    h: Vec<f64>,
    integers: Vec<f64>,
    memo: HashMap<(i64, u32), f64>,
}

impl Recursive {
    fn new(h: Vec<f64>) -> Self {
        let n = h.len() - 1; // integers 0..=2p-1, phi(0) = phi(2p-1) = 0 for p >= 2
                             // phi(k) = sqrt2 sum_j h_{2k-j} phi(j), k = 1..n-1; plus sum phi(k) = 1.
        let m = n - 1;
        let mut a = vec![vec![0.0; m + 1]; m];
        for (row, k) in (1..n).enumerate() {
            for (col, j) in (1..n).enumerate() {
                let idx = 2 * k as i64 - j as i64;
                if (0..h.len() as i64).contains(&idx) {
                    a[row][col] = std::f64::consts::SQRT_2 * h[idx as usize];
                }
            }
            a[row][row] -= 1.0;
        }
        // replace the last row by the normalization
        for col in 0..m {
            a[m - 1][col] = 1.0;
        }
        a[m - 1][m] = 1.0;
        for row in 0..m - 1 {
            a[row][m] = 0.0;
        }
        // Gaussian elimination with partial pivoting
        for c in 0..m {
            let piv = (c..m)
                .max_by(|&x, &y| a[x][c].abs().total_cmp(&a[y][c].abs()))
                .unwrap();
            a.swap(c, piv);
            for r in 0..m {
                if r != c {
                    let f = a[r][c] / a[c][c];
                    for k in c..=m {
                        a[r][k] -= f * a[c][k];
                    }
                }
            }
        }
        let mut integers = vec![0.0; n + 1];
        for k in 1..n {
            integers[k] = a[k - 1][m] / a[k - 1][k - 1];
        }
        Self {
            h,
            integers,
            memo: HashMap::new(),
        }
    }

    /// `phi_std(num / 2^r)`.
    fn phi(&mut self, num: i64, r: u32) -> f64 {
        let last = (self.h.len() - 1) as i64;
        if num <= 0 || num >= last << r {
            return 0.0;
        }
        if r == 0 {
            return self.integers[num as usize];
        }
        if num % 2 == 0 {
            return self.phi(num / 2, r - 1);
        }
        if let Some(&v) = self.memo.get(&(num, r)) {
            return v;
        }
        // phi(x) = sqrt2 sum_k h_k phi(2x - k), 2x = num / 2^(r-1)
        let mut s = 0.0;
        for k in 0..self.h.len() {
            s += self.h[k] * self.phi(num - ((k as i64) << (r - 1)), r - 1);
        }
        let v = std::f64::consts::SQRT_2 * s;
        self.memo.insert((num, r), v);
        v
    }
}

fn value_of(out: &[BasisValue], index: usize) -> Option<f64> {
    out.iter().find(|v| v.index == index).map(|v| v.value)
}

/// Interior scaling functions and wavelets at interior dyadic positions agree with the
/// recursive evaluator to 1e-12 (values are O(2^{j/2}); both are exact up to rounding).
#[test]
fn interior_values_match_an_independent_recursive_evaluator() {
    for p in 2..=8 {
        let family = FilterFamily::cdv_default(p);
        let h = daubechies_lowpass(p, family);
        let g: Vec<f64> = (0..2 * p)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 } * h[2 * p - 1 - k])
            .collect();
        let mut rec = Recursive::new(h.clone());
        let n = rkwave::basis::minimum_level(p);
        let basis = CdvBasis::new(p, family, n, n + 3, rkwave::sampling::Domain::UNIT).unwrap();
        let mut ev = basis.evaluator();
        let r = n + 12; // dyadic resolution of the test positions
        let mut worst: f64 = 0.0;
        for step in 0..400u64 {
            let num = (step * 2654435761) % (1u64 << r);
            let x = num as f64 / (1u64 << r) as f64;
            let out = ev.eval(x).unwrap();
            for v in &out {
                let id = basis.function(v.index);
                if id.side != Side::Interior {
                    continue;
                }
                let j = id.level;
                let m = id.index as i64;
                // phi_{j,m}(x) = 2^{j/2} phi_std(2^j x - m + p - 1); positions num / 2^r.
                let shift = |mm: i64| {
                    (num as i64) * (1i64 << j) / (1i64 << j) - ((mm - p as i64 + 1) << (r - j))
                };
                let expect = match id.kind {
                    FunctionKind::Scaling => 2f64.powf(j as f64 / 2.0) * rec.phi(shift(m), r - j),
                    FunctionKind::Wavelet => {
                        // psi_std(y) = sqrt2 sum_k g_k phi_std(2y - k)
                        let y = shift(m); // y / 2^(r-j)
                        let mut s = 0.0;
                        for (k, gk) in g.iter().enumerate() {
                            s += gk * rec.phi(y - ((k as i64) << (r - j - 1)), r - j - 1);
                        }
                        2f64.powf(j as f64 / 2.0) * std::f64::consts::SQRT_2 * s
                    }
                };
                worst = worst.max((v.value - expect).abs());
            }
        }
        assert!(
            worst < 1e-12,
            "p = {p}: interior values differ from the recursive evaluator by {worst:e}"
        );
    }
}

/// `db2`: `phi(1/2) = (2 + sqrt3)/4`, `phi(1) = (1 + sqrt3)/2`, `phi(2) = (1 - sqrt3)/2`
/// (standard support `[0, 3]`), through interior functions of `V_4` at positions `k / 16`.
#[test]
fn db2_exact_values() {
    let basis = CdvBasis::new(
        2,
        FilterFamily::Extremal,
        4,
        4,
        rkwave::sampling::Domain::UNIT,
    )
    .unwrap();
    let mut ev = basis.evaluator();
    let s3 = 3f64.sqrt();
    // phi_{4,m}(x) = 4 phi_cdv(16x - m) = 4 phi_std(16x - m + 1); interior m = 2..13.
    let m = 6usize;
    for (y, expect) in [
        (0.5, (2.0 + s3) / 4.0),
        (1.0, (1.0 + s3) / 2.0),
        (2.0, (1.0 - s3) / 2.0),
    ] {
        let x = (y + m as f64 - 1.0) / 16.0;
        let out = ev.eval(x).unwrap();
        let v = value_of(&out, m).expect("function present");
        assert!(
            (v / 4.0 - expect).abs() < 1e-15,
            "phi({y}) = {} expected {expect}",
            v / 4.0
        );
    }
}

/// The coefficients of one level's functions in the next level (the FWT step) reproduce the
/// values: `f_{j,k}(x) = sum_i A[k, i] phi_{j+1,i}(x)` for every function of `V_j` and `W_j`.
fn check_refinement(p: usize, j: u32, xs: &[f64]) -> f64 {
    let family = FilterFamily::cdv_default(p);
    let bank = FilterBank::shared(p, family).unwrap();
    let coarse = CdvBasis::with_bank(bank.clone(), j, j, rkwave::sampling::Domain::UNIT).unwrap();
    let fine =
        CdvBasis::with_bank(bank.clone(), j + 1, j + 1, rkwave::sampling::Domain::UNIT).unwrap();
    let mut ce = coarse.evaluator();
    let mut fe = fine.evaluator();
    let size = 1usize << j;
    let mut worst: f64 = 0.0;
    for &x in xs {
        let c = ce.eval(x).unwrap();
        let f = fe.eval(x).unwrap();
        let fine_scaling: HashMap<usize, f64> = f
            .iter()
            .filter(|v| v.index < 2 * size)
            .map(|v| (v.index, v.value))
            .collect();
        for v in &c {
            let expansion = local_synthesis(&bank, j, v.index);
            let s: f64 = expansion
                .iter()
                .map(|(i, w)| w * fine_scaling.get(i).copied().unwrap_or(0.0))
                .sum();
            worst = worst.max((s - v.value).abs() / 2f64.powf(j as f64 / 2.0));
        }
    }
    worst
}

/// Fine-level expansion of function `index` (layout `[s | d]` of level `j`), written out from
/// the refinement matrices directly (works at any level without full-size vectors).
fn local_synthesis(bank: &FilterBank, j: u32, index: usize) -> Vec<(usize, f64)> {
    let p = bank.p();
    let e = bank.edge_count();
    let size = 1usize << j;
    let fine = 2 * size;
    let (wavelet, k) = if index < size {
        (false, index)
    } else {
        (true, index - size)
    };
    let mut out = Vec::new();
    if k >= e && k < size - e {
        for i in (-(p as i64) + 1)..=(p as i64) {
            let w = if wavelet {
                bank.interior.gc(i)
            } else {
                bank.interior.hc(i)
            };
            out.push(((2 * k as i64 + i) as usize, w));
        }
        return out;
    }
    let (edge, r, left) = if k < e {
        (bank.left.as_ref().unwrap(), k, true)
    } else {
        (bank.right.as_ref().unwrap(), size - 1 - k, false)
    };
    let (me, mi) = if wavelet {
        (&edge.g_edge, &edge.g_interior)
    } else {
        (&edge.h_edge, &edge.h_interior)
    };
    let place = |i: usize| if left { i } else { fine - 1 - i };
    for l in 0..p {
        out.push((place(l), me[(r, l)]));
    }
    for q in 0..mi.ncols() {
        out.push((place(p + q), mi[(r, q)]));
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Refinement relation between levels at random positions (relative to `2^{j/2}`), 1e-13.
    #[test]
    fn refinement_relation_between_levels(p in 1usize..=10, x in 0.0f64..=1.0, extra in 0u32..3) {
        let j = rkwave::basis::minimum_level(p) + extra;
        let err = check_refinement(p, j, &[x]);
        prop_assert!(err < 1e-13, "p = {}, j = {}, x = {}: {:e}", p, j, x, err);
    }

    /// Reflection: the basis of the reversed filter at `1 - x` equals the basis at `x` with
    /// left and right exchanged (`m -> 2^j - 1 - m`), wavelets up to the sign `-1`.
    #[test]
    fn reflection_symmetry(p in 1usize..=10, x in 0.5f64..=1.0) {
        let family = FilterFamily::cdv_default(p);
        let h = daubechies_lowpass(p, family);
        let rev: Vec<f64> = h.iter().rev().copied().collect();
        let bank = std::sync::Arc::new(FilterBank::from_lowpass(&h, family).unwrap());
        let bank_rev = std::sync::Arc::new(FilterBank::from_lowpass(&rev, family).unwrap());
        let n = rkwave::basis::minimum_level(p);
        let a = CdvBasis::with_bank(bank, n, n + 2, rkwave::sampling::Domain::UNIT).unwrap();
        let b = CdvBasis::with_bank(bank_rev, n, n + 2, rkwave::sampling::Domain::UNIT).unwrap();
        let va = a.evaluator().eval(x).unwrap();
        let vb = b.evaluator().eval(1.0 - x).unwrap();
        for v in &va {
            let id = a.function(v.index);
            let size = 1usize << id.level;
            let mirrored = rkwave::basis::FunctionId { index: size - 1 - id.index, ..id }.global();
            let sign = if id.kind == FunctionKind::Wavelet && id.side == Side::Interior { -1.0 } else { 1.0 };
            let w = value_of(&vb, mirrored).unwrap_or(0.0);
            let edge_wavelet = id.kind == FunctionKind::Wavelet && id.side != Side::Interior;
            let err = if edge_wavelet { (v.value.abs() - w.abs()).abs() } else { (v.value - sign * w).abs() };
            prop_assert!(err < 1e-11 * 2f64.powf(id.level as f64 / 2.0), "p = {} x = {} {:?}: {} vs {}", p, x, id, v.value, w);
        }
    }
}

/// Values stay exact at the extremes: levels 25–30 at 0, 1, dyadic points and one ulp beside
/// them satisfy the refinement relation between levels (relative 1e-12), and are finite.
#[test]
fn extreme_levels_and_positions() {
    let mut xs = vec![
        0.0,
        1.0,
        f64::MIN_POSITIVE,
        5e-324,
        1.0 - f64::EPSILON / 2.0,
        0.5,
        0.25,
        0.75,
    ];
    for &d in &[
        0.5,
        0.25,
        0.375,
        1.0 / 1024.0,
        3.0 / (1u64 << 30) as f64,
        1.0 - 1.0 / (1u64 << 29) as f64,
    ] {
        xs.push(d);
        xs.push(f64::from_bits(d.to_bits() + 1));
        xs.push(f64::from_bits(d.to_bits() - 1));
    }
    for p in [1usize, 2, 3, 6, 10] {
        for j in [25u32, 28, 30] {
            let err = check_refinement(p, j, &xs);
            assert!(
                err < 1e-12,
                "p = {p}, level {j}: refinement relation off by {err:e}"
            );
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// Pointwise values of every function of `Psi(n, N)` agree with its FWT synthesis into
    /// `V_{N+1}` evaluated at the same dyadic position (relative to `2^{(N+1)/2}`), 1e-12.
    #[test]
    fn values_agree_with_fwt_synthesis_at_dyadic_positions(p in 1usize..=8, depth in 0u32..3, num in 0u64..=4096) {
        let family = FilterFamily::cdv_default(p);
        let n = rkwave::basis::minimum_level(p);
        let fine = n + depth;
        let basis = CdvBasis::new(p, family, n, fine, rkwave::sampling::Domain::UNIT).unwrap();
        let top = CdvBasis::new(p, family, fine + 1, fine + 1, rkwave::sampling::Domain::UNIT).unwrap();
        let x = num as f64 / 4096.0;
        let values = basis.evaluator().eval(x).unwrap();
        let fine_values = top.evaluator().eval(x).unwrap();
        let dim = basis.dimension();
        for v in &values {
            let unit: Vec<f64> = (0..dim).map(|i| if i == v.index { 1.0 } else { 0.0 }).collect();
            let coefficients = rkwave::basis::fwt::synthesis(basis.bank(), n, fine, &unit);
            let s: f64 = fine_values.iter().filter(|f| f.index < dim).map(|f| coefficients[f.index] * f.value).sum();
            let scale = 2f64.powf((fine + 1) as f64 / 2.0);
            prop_assert!((s - v.value).abs() < 1e-12 * scale, "p = {} x = {} a = {}: {} vs {}", p, x, v.index, s, v.value);
        }
    }
}
