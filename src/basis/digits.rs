//! A position's binary digits and the digit products of its exact evaluation
//! (`eval.rs`): `t = m 2^-K` exactly, its cells and digits, the small matrix-vector
//! product of the digit recursion, and the states of the digit walk shared between the
//! evaluations of several levels at one position ([`DigitChain`]).

use super::bank::DigitTables;

/// `t = m 2^-k` exactly, `m` odd, for `0 < t < 1` (every such f64 is dyadic; subnormals
/// included, `k <= 1074`).
pub(super) fn odd_mantissa(t: f64) -> (u64, u32) {
    let bits = t.to_bits();
    let exp = ((bits >> 52) & 0x7ff) as i64;
    let frac = bits & ((1u64 << 52) - 1);
    let (mut m, mut k) = if exp == 0 {
        (frac, 1074i64)
    } else {
        (frac | (1u64 << 52), 1075 - exp)
    };
    let tz = m.trailing_zeros() as i64;
    m >>= tz;
    k -= tz;
    (m, k as u32)
}

/// `floor(2^j m 2^-k)`: the index of the level-`j` cell holding `t = m 2^-k`.
#[inline]
pub(super) fn dyadic_cell(m: u64, k: u32, j: u32) -> u64 {
    if j >= k {
        m << (j - k)
    } else {
        let s = k - j;
        if s >= 64 {
            0
        } else {
            m >> s
        }
    }
}

/// Binary digit `d_i` of `t = m 2^-k = 0.d_1 d_2 ...`.
#[inline]
pub(super) fn dyadic_digit(m: u64, k: u32, i: u32) -> usize {
    if i > k {
        return 0;
    }
    let s = k - i;
    if s >= 64 {
        0
    } else {
        ((m >> s) & 1) as usize
    }
}

/// A position `t = m 2^-k` in `[0, 1]` (`m` odd, or `m = 0`), or the right end.
#[derive(Clone, Copy, Debug)]
pub(super) struct Position {
    pub(super) m: u64,
    pub(super) k: u32,
    pub(super) one: bool,
}

impl Position {
    pub(super) fn new(t: f64) -> Self {
        if t >= 1.0 {
            return Self {
                m: 0,
                k: 0,
                one: true,
            };
        }
        if t <= 0.0 {
            return Self {
                m: 0,
                k: 0,
                one: false,
            };
        }
        let (m, k) = odd_mantissa(t);
        Self { m, k, one: false }
    }

    /// `floor(2^j t)` (the last cell `2^j - 1` at `t = 1`).
    pub(super) fn cell(&self, j: u32) -> u64 {
        if self.one {
            return (1u64 << j) - 1;
        }
        dyadic_cell(self.m, self.k, j)
    }

    /// Binary digit `d_i` of `t = 0.d_1 d_2 ...`.
    pub(super) fn digit(&self, i: u32) -> usize {
        dyadic_digit(self.m, self.k, i)
    }

    /// Eight digits `d_{i..i+7}` as a byte (`d_i` most significant).
    pub(super) fn byte(&self, i: u32) -> usize {
        let s = self.k as i64 - (i as i64 + 7);
        if s >= 64 {
            0
        } else if s >= 0 {
            ((self.m >> s) & 0xff) as usize
        } else {
            ((self.m << (-s)) & 0xff) as usize
        }
    }
}

/// `y = A x`, `A` row-major `y.len() x x.len()`, each entry summed from 0 in column order.
/// The widths of p = 1..4 (`2p - 1`) as constants ([`matvec_fixed`]: the same sums in the
/// same order, unrolled).
#[inline]
pub(super) fn matvec(a: &[f64], x: &[f64], y: &mut [f64]) {
    match x.len() {
        1 => matvec_fixed::<1>(a, x, y),
        3 => matvec_fixed::<3>(a, x, y),
        5 => matvec_fixed::<5>(a, x, y),
        7 => matvec_fixed::<7>(a, x, y),
        _ => matvec_dynamic(a, x, y),
    }
}

/// [`matvec`] for `x` of `W` entries.
#[inline]
fn matvec_fixed<const W: usize>(a: &[f64], x: &[f64], y: &mut [f64]) {
    let x: &[f64; W] = x.try_into().expect("W entries");
    for (i, yi) in y.iter_mut().enumerate() {
        let row: &[f64; W] = a[i * W..(i + 1) * W].try_into().expect("W entries");
        let mut s = 0.0;
        for l in 0..W {
            s += row[l] * x[l];
        }
        *yi = s;
    }
}

#[inline]
fn matvec_dynamic(a: &[f64], x: &[f64], y: &mut [f64]) {
    let w = x.len();
    for (i, yi) in y.iter_mut().enumerate() {
        let row = &a[i * w..(i + 1) * w];
        let mut s = 0.0;
        for l in 0..w {
            s += row[l] * x[l];
        }
        *yi = s;
    }
}

/// The states `S(j) = v(frac(2^j t))` of one position's digit walk, computed as the
/// evaluator's walk to level `j` computes them and kept for every later walk of the same
/// position (the multilevel evaluator walks one position once per level). With `K` the
/// position's last binary digit, a walk to `j` applies the byte products of the digits
/// `K-7..K`, `K-15..K-8`, ... down to level `j + r`, `r = (K - j) mod 8`, then the single
/// digits `d_{j+r}, ..., d_{j+1}`, so
///
/// ```text
/// S(j) = v(0)                               j >= K,
/// S(j) = P_{d_{j+1} .. d_{j+8}} S(j + 8)    K - j a positive multiple of 8,
/// S(j) = T_{d_{j+1}} S(j + 1)               otherwise:
/// ```
///
/// the same products in the same order, so a state from the chain is the walk's own bit for
/// bit, at the cost of one walk to the lowest level asked for instead of one per level.
#[derive(Clone, Debug, Default)]
pub(crate) struct DigitChain {
    /// The tables' address and the position `m 2^-K` the states belong to.
    key: (usize, u64, u32),
    /// `stamp[j] == generation`: `S(j)` is known for the current key.
    generation: u32,
    stamp: Vec<u32>,
    /// `S(j)` at `j w..(j + 1) w`.
    states: Vec<f64>,
    pending: Vec<u32>,
    input: Vec<f64>,
}

impl DigitChain {
    /// `S(j)` of `pos` (not at the right end) under the digit tables `tab`.
    pub(super) fn state<'s>(
        &'s mut self,
        tab: &'s DigitTables,
        pos: &Position,
        j: u32,
    ) -> &'s [f64] {
        let (w, k) = (tab.width, pos.k);
        if j >= k {
            return &tab.v0;
        }
        let key = (tab as *const DigitTables as usize, pos.m, k);
        if key != self.key || self.generation == 0 {
            self.key = key;
            self.generation = self.generation.wrapping_add(1);
            if self.generation == 0 {
                self.stamp.fill(0);
                self.generation = 1;
            }
        }
        if self.stamp.len() < k as usize {
            self.stamp.resize(k as usize, 0);
        }
        if self.states.len() < k as usize * w {
            self.states.resize(k as usize * w, 0.0);
        }
        let step = |l: u32| if (k - l) % 8 == 0 { 8 } else { 1 };
        self.pending.clear();
        let mut cur = j;
        while cur < k && self.stamp[cur as usize] != self.generation {
            self.pending.push(cur);
            cur += step(cur);
        }
        while let Some(l) = self.pending.pop() {
            let source = l + step(l);
            self.input.clear();
            self.input.extend_from_slice(if source >= k {
                &tab.v0
            } else {
                &self.states[source as usize * w..(source as usize + 1) * w]
            });
            let matrix = if step(l) == 8 {
                let byte = pos.byte(l + 1);
                &tab.bytes[byte * w * w..(byte + 1) * w * w]
            } else {
                &tab.t[pos.digit(l + 1)][..]
            };
            let l = l as usize;
            matvec(matrix, &self.input, &mut self.states[l * w..(l + 1) * w]);
            self.stamp[l] = self.generation;
        }
        &self.states[j as usize * w..(j as usize + 1) * w]
    }
}

/// The digit chains of one coordinate (the interior walk's and the right edge's reflected
/// one), shared by the evaluators of several levels at the same coordinate ([`DigitChain`]).
#[derive(Clone, Debug, Default)]
pub(crate) struct DigitChains {
    pub(super) interior: DigitChain,
    pub(super) mirror: DigitChain,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::basis::FilterBank;

    /// `S(j)` as a walk to level `j` alone forms it (the loop [`DigitChain`] replaced): the
    /// byte products of the digits from the last up, then single digits.
    fn walk_alone(tab: &DigitTables, pos: &Position, j: u32) -> Vec<f64> {
        let w = tab.width;
        let (mut cur, mut nxt) = (tab.v0.clone(), vec![0.0; w]);
        let mut remaining = pos.k.saturating_sub(j);
        while remaining >= 8 {
            let byte = pos.byte(j + remaining - 7);
            matvec(&tab.bytes[byte * w * w..(byte + 1) * w * w], &cur, &mut nxt);
            std::mem::swap(&mut cur, &mut nxt);
            remaining -= 8;
        }
        while remaining > 0 {
            matvec(&tab.t[pos.digit(j + remaining)], &cur, &mut nxt);
            std::mem::swap(&mut cur, &mut nxt);
            remaining -= 1;
        }
        cur
    }

    /// One chain asked for the levels of a position in a scrambled order (so states are
    /// reused from earlier requests, deeper and shallower) gives every walk's state bit for
    /// bit, for seeded positions with 1 to 53 significant digits, subnormal ones and both
    /// families' tables of several orders; positions alternate so the key changes.
    #[test]
    fn the_shared_chain_is_each_walk_bit_for_bit() {
        let mut seed = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            seed = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
            crate::image::adaptive::oracle::mix64(seed)
        };
        for p in [1usize, 2, 3, 4, 6] {
            let bank = FilterBank::new(p, crate::basis::FilterFamily::Extremal).expect("bank");
            let mut chain = DigitChain::default();
            for trial in 0..300 {
                let t = match trial % 5 {
                    0 => (next() >> 11) as f64 / (1u64 << 53) as f64,
                    1 => (next() % 4096) as f64 / 4096.0,
                    2 => f64::from_bits(next() % (1u64 << 52)),
                    3 => 0.5,
                    _ => (next() >> 11) as f64 / (1u64 << 53) as f64 * 1e-3,
                };
                let pos = Position::new(t);
                if pos.one {
                    continue;
                }
                for tab in [&bank.digits, &bank.reversed_digits] {
                    for i in 0..40u32 {
                        let j = (i * 17 + trial) % (pos.k + 12);
                        let got: Vec<u64> = chain
                            .state(tab, &pos, j)
                            .iter()
                            .map(|v| v.to_bits())
                            .collect();
                        let want: Vec<u64> = walk_alone(tab, &pos, j)
                            .iter()
                            .map(|v| v.to_bits())
                            .collect();
                        assert_eq!(got, want, "p = {p}, t = {t:e}, level {j}");
                    }
                }
            }
        }
    }
}
