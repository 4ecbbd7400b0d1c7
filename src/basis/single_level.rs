//! Single-level evaluation: the scaling functions of one level `V_J` at a position, the digit
//! recursion run for that level only.
//!
//! With `t = 0.d_1 d_2 ... d_K` (an `f64` has finitely many digits) and the cell
//! `c = floor(2^J t)`, the interior values `phi(2^J t - m)`, `m = c - 2p + 2 ..= c`, are
//! `v(frac(2^J t)) = P_{B_1} P_{B_2} ... P_{B_q} v(0)` where `B_1, B_2, ...` are the digits
//! `d_{J+1} ... d_K` taken eight at a time (the last byte padded with zero digits, harmless
//! because `T_0 v(0) = v(0)`) and `P_B` is the product of the eight digit matrices of byte `B`
//! (precomputed in [`super::bank::DigitTables`]). That is `ceil((K - J) / 8)` products of a
//! `(2p-1) x (2p-1)` matrix with a vector and nothing else: no level below `J`, no wavelet, no
//! allocation.
//!
//! A point whose cell lies within `2p - 1` cells of an end of `[0, 1]` involves edge
//! functions, whose values come from a recursion over finer levels: there the multilevel
//! [`Evaluator`] answers (a fraction `2 (2p - 1) / 2^J` of uniformly spread points).
//!
//! The functions with a structurally nonzero value at a point have consecutive indices, so a
//! row of the single-scale observation matrix `K_J` is `(first, values)`.

use super::digits::Position;
use super::{BasisValue, CdvBasis, Evaluator, MAX_VANISHING_MOMENTS};

/// Longest row: `p` edge functions plus `2p - 1` interior translates overlap on at most
/// `3p - 2` consecutive indices.
pub const MAX_ROW: usize = 3 * MAX_VANISHING_MOMENTS - 2;

/// Width of the interior state `v(t)` at the largest `p`.
const MAX_WIDTH: usize = 2 * MAX_VANISHING_MOMENTS - 1;

/// Evaluates the scaling functions of `V_n` (`n` = the basis's coarse level) at positions;
/// holds scratch space, so make one per thread.
pub struct SingleLevelEvaluator<'a> {
    basis: &'a CdvBasis,
    general: Evaluator<'a>,
    list: Vec<BasisValue>,
    row: [f64; MAX_ROW],
    scale: f64,
}

impl CdvBasis {
    /// An evaluator of the scaling functions of `V_n` alone (`n` = the coarse level), one per
    /// thread: the single-scale rows of least squares and of evaluation after FWT synthesis.
    pub fn single_level_evaluator(&self) -> SingleLevelEvaluator<'_> {
        SingleLevelEvaluator::new(self)
    }
}

impl<'a> SingleLevelEvaluator<'a> {
    /// A new evaluator of the scaling functions of `V_n`, `n = basis.coarse()`.
    pub fn new(basis: &'a CdvBasis) -> Self {
        Self {
            basis,
            general: Evaluator::new(basis),
            list: Vec::with_capacity(MAX_ROW),
            row: [0.0; MAX_ROW],
            scale: basis.amplitude() * 2f64.powf(basis.coarse() as f64 / 2.0),
        }
    }

    /// The structurally nonzero scaling functions of `V_n` at `t` in `[0, 1]` (unit
    /// coordinates; not checked): `(first, values)` with `values[k] = phi_{n, first + k}(t)`
    /// (domain normalisation included), the same numbers as
    /// [`Evaluator::eval_scaling_unit_into`] gives.
    pub fn row_unit(&mut self, t: f64) -> (usize, &[f64]) {
        let bank = self.basis.bank();
        let p = bank.p();
        let e = bank.edge_count();
        let w = 2 * p - 1;
        let level = self.basis.coarse();
        let pos = Position::new(t);
        let c = pos.cell(level);
        let right = (1u64 << level) - 1 - c;
        let interior = !pos.one && (e == 0 || (c >= w as u64 && right >= w as u64));
        if !interior {
            self.general.eval_scaling_unit_into(t, &mut self.list);
            let first = self.list.first().map_or(0, |v| v.index);
            for (k, v) in self.list.iter().enumerate() {
                debug_assert_eq!(v.index, first + k, "single-level rows are consecutive");
                self.row[k] = v.value;
            }
            return (first, &self.row[..self.list.len()]);
        }
        let tab = &bank.digits;
        let a = match w {
            1 => byte_products::<1>(&tab.bytes, &tab.v0, &pos, level),
            3 => byte_products::<3>(&tab.bytes, &tab.v0, &pos, level),
            5 => byte_products::<5>(&tab.bytes, &tab.v0, &pos, level),
            7 => byte_products::<7>(&tab.bytes, &tab.v0, &pos, level),
            9 => byte_products::<9>(&tab.bytes, &tab.v0, &pos, level),
            11 => byte_products::<11>(&tab.bytes, &tab.v0, &pos, level),
            13 => byte_products::<13>(&tab.bytes, &tab.v0, &pos, level),
            15 => byte_products::<15>(&tab.bytes, &tab.v0, &pos, level),
            17 => byte_products::<17>(&tab.bytes, &tab.v0, &pos, level),
            19 => byte_products::<19>(&tab.bytes, &tab.v0, &pos, level),
            _ => unreachable!("2p - 1 is odd and at most {MAX_WIDTH}"),
        };
        // v[i] = phi(2^J t - m) with m = c + p - 1 - i: ascending m is descending i.
        for (k, r) in self.row[..w].iter_mut().enumerate() {
            *r = self.scale * a[w - 1 - k];
        }
        ((c as usize + 1) - p, &self.row[..w])
    }
}

/// `v(frac(2^J t)) = P_{B_1} P_{B_2} ... P_{B_q} v(0)` at the fixed width `W = 2p - 1`: the
/// byte matrices (row-major `W x W` blocks of `tables`) applied from the last byte to the
/// first. A compile-time width lets the `W x W` products unroll without bounds checks (the
/// same products summed in the same order as a plain loop).
fn byte_products<const W: usize>(
    tables: &[f64],
    v0: &[f64],
    pos: &Position,
    level: u32,
) -> [f64; MAX_WIDTH] {
    let mut a = [0.0f64; W];
    a.copy_from_slice(v0);
    if pos.k > level {
        let bytes = (pos.k - level).div_ceil(8);
        for q in (0..bytes).rev() {
            let byte = pos.byte(level + 1 + 8 * q);
            let m = &tables[byte * W * W..(byte + 1) * W * W];
            let mut b = [0.0f64; W];
            for (i, bi) in b.iter_mut().enumerate() {
                let row = &m[i * W..(i + 1) * W];
                *bi = row.iter().zip(&a).fold(0.0, |s, (x, y)| s + x * y);
            }
            a = b;
        }
    }
    let mut out = [0.0f64; MAX_WIDTH];
    out[..W].copy_from_slice(&a);
    out
}
