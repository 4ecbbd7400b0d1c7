//! Exact pointwise evaluation of every nonzero function of `Psi(n, N)` at a position, all
//! levels in one pass (Daubechies–Lagarias digit recursion).
//!
//! For `t` in `[0, 1)` let `v(t) = (phi(t), phi(t+1), ..., phi(t+2p-2))` (support `[0, 2p-1]`).
//! The refinement equation gives `v((t+d)/2) = T_d v(t)`; with the binary digits
//! `x = 0.d_1 d_2 ... d_K` of an `f64` (finitely many), `v(frac(2^j x)) =
//! T_{d_{j+1}} ... T_{d_K} v(0)`. Walking the digits from the last to the first yields `v` at
//! every level; wavelet values follow from the next finer level through
//! `w((t+d)/2) = U_d v(t)`, `(U_d)_{i,l} = sqrt2 g_{2i+d-l}`. Digits below the finest level are
//! consumed eight at a time through precomputed products.
//!
//! Edge functions obey `phi_L(u) = sqrt2 H phi_L(2u) + sqrt2 h Phi(2u)`: with
//! `a_j = phi_L(2^j x)`, `a_j = sqrt2 H a_{j+1} + sqrt2 h phi_{j+1}` where `phi_{j+1}` holds the
//! interior values `phi(2^{j+1} x - m)`, `m = p..3p-2`, already known from the walk. The
//! recursion starts at the first level where the point leaves the edge support (`a = 0`) or
//! becomes an integer (`a = phi_L(c)`, exact values at the integers). The right edge is the left
//! construction of the reversed filter in the reflected coordinate `1 - x` (exact in `f64` for
//! `x >= 1/2`, the only place right edge functions live).
//!
//! Convention at discontinuities (Haar): right limits inside `[0, 1)`, left limits at `x = 1`,
//! so the last cell is closed.

use super::bank::{DigitTables, EdgeTables};
use super::CdvBasis;

/// One nonzero (structurally: its support contains the point's finest cell) basis function and
/// its value.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BasisValue {
    /// Global index in `Psi(n, N)` (see [`super::FunctionId`]).
    pub index: usize,
    /// `Psi_index(x)`.
    pub value: f64,
}

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
    fn digit(&self, i: u32) -> usize {
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

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `y = A x`, `A` row-major `y.len() x x.len()`, each entry summed from 0 in column order.
/// The widths of p = 1..4 (`2p - 1`) as constants ([`matvec_fixed`]: the same sums in the
/// same order, unrolled).
#[inline]
fn matvec(a: &[f64], x: &[f64], y: &mut [f64]) {
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

/// Per-level interior values of one digit walk.
#[derive(Clone, Debug, Default)]
struct Walk {
    w: usize,
    lo: u32,
    hi: u32,
    cells: Vec<u64>,
    v: Vec<f64>,
    wav: Vec<f64>,
}

impl Walk {
    /// `v` at levels `lo..=hi`, wavelet values at `lo..=wav_hi`; `v` at `hi` from `chain`
    /// (the states of the digits below `hi`, shared by the walks of one position).
    fn run(
        &mut self,
        tab: &DigitTables,
        chain: &mut DigitChain,
        pos: &Position,
        lo: u32,
        hi: u32,
        wav_hi: u32,
    ) {
        let w = tab.width;
        let levels = (hi - lo + 1) as usize;
        self.w = w;
        self.lo = lo;
        self.hi = hi;
        self.cells.clear();
        self.cells.extend((lo..=hi).map(|j| pos.cell(j)));
        self.v.resize(levels * w, 0.0);
        self.wav.resize(levels * w, 0.0);
        let top = (hi - lo) as usize * w;
        if pos.one {
            for l in 0..levels {
                self.v[l * w..(l + 1) * w].copy_from_slice(&tab.v1);
            }
            let (v, wav) = (&self.v, &mut self.wav);
            for l in 0..levels.min((wav_hi + 1).saturating_sub(lo) as usize) {
                matvec(
                    &tab.u[1],
                    &v[l * w..(l + 1) * w],
                    &mut wav[l * w..(l + 1) * w],
                );
            }
            return;
        }
        // v at the deepest level: digits hi+1..=K, last first (the chain's state S(hi)).
        self.v[top..top + w].copy_from_slice(chain.state(tab, pos, hi));
        for j in (lo..hi).rev() {
            let l = (j - lo) as usize;
            let d = pos.digit(j + 1);
            let (below, above) = self.v.split_at_mut((l + 1) * w);
            let finer = &above[..w];
            matvec(&tab.t[d], finer, &mut below[l * w..]);
            if j <= wav_hi {
                matvec(&tab.u[d], finer, &mut self.wav[l * w..(l + 1) * w]);
            }
        }
    }

    fn level(&self, j: u32) -> &[f64] {
        let l = (j - self.lo) as usize;
        &self.v[l * self.w..(l + 1) * self.w]
    }

    fn wavelets(&self, j: u32) -> &[f64] {
        let l = (j - self.lo) as usize;
        &self.wav[l * self.w..(l + 1) * self.w]
    }

    fn cell(&self, j: u32) -> u64 {
        self.cells[(j - self.lo) as usize]
    }
}

/// The states `S(j) = v(frac(2^j t))` of one position's digit walk, computed as a walk to
/// level `j` computes them ([`Walk::run`]) and kept for every later walk of the same position
/// (the multilevel evaluator walks one position once per level). With `K` the position's
/// last binary digit, a walk to `j` applies the byte products of the digits `K-7..K`,
/// `K-15..K-8`, ... down to level `j + r`, `r = (K - j) mod 8`, then the single digits
/// `d_{j+r}, ..., d_{j+1}`, so
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
    fn state<'s>(&'s mut self, tab: &'s DigitTables, pos: &Position, j: u32) -> &'s [f64] {
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
    interior: DigitChain,
    mirror: DigitChain,
}

/// Evaluates `Psi(n, N)` at positions; holds scratch space, so make one per thread.
pub struct Evaluator<'a> {
    basis: &'a CdvBasis,
    walk: Walk,
    mirror: Walk,
    edge: Vec<f64>,
    right_edge: Vec<f64>,
    phi: Vec<f64>,
    wavelet: Vec<f64>,
    scale: Vec<f64>,
    chains: DigitChains,
}

impl CdvBasis {
    /// An evaluator with its own scratch space (one per thread).
    pub fn evaluator(&self) -> Evaluator<'_> {
        Evaluator::new(self)
    }
}

impl<'a> Evaluator<'a> {
    /// A new evaluator for `basis`.
    pub fn new(basis: &'a CdvBasis) -> Self {
        let amp = basis.amplitude();
        let scale = (0..=basis.fine() + 1)
            .map(|j| amp * 2f64.powf(j as f64 / 2.0))
            .collect();
        Self {
            basis,
            walk: Walk::default(),
            mirror: Walk::default(),
            edge: Vec::new(),
            right_edge: Vec::new(),
            phi: vec![0.0; 2 * basis.p() - 1],
            wavelet: vec![0.0; basis.p()],
            scale,
            chains: DigitChains::default(),
        }
    }

    /// All structurally nonzero functions of `Psi(n, N)` at domain position `x`, in ascending
    /// global index, appended to `out` (which is cleared first).
    pub fn eval_into(
        &mut self,
        x: f64,
        out: &mut Vec<BasisValue>,
    ) -> Result<(), super::BasisError> {
        let t = self.basis.to_unit(x)?;
        self.eval_unit_into(t, out);
        Ok(())
    }

    /// As [`Evaluator::eval_into`], returning a new vector.
    pub fn eval(&mut self, x: f64) -> Result<Vec<BasisValue>, super::BasisError> {
        let mut out = Vec::new();
        self.eval_into(x, &mut out)?;
        Ok(out)
    }

    /// Evaluation at `t` in `[0, 1]` (unit coordinates; not checked).
    pub fn eval_unit_into(&mut self, t: f64, out: &mut Vec<BasisValue>) {
        self.eval_levels(t, out, Some(self.basis.fine()));
    }

    /// As [`Evaluator::eval_unit_into`], with the wavelets only up to level `depth` (none
    /// when `depth < n`; `depth` above `N` means `N`): the scaling functions of `V_n` and
    /// `psi_{j,k}(t)` for `n <= j <= min(depth, N)`, exactly the values the full evaluation
    /// gives for them. For an adaptive set whose deepest function with `t` in its support
    /// is at level `depth` (its local depth at `t`), the levels below contribute nothing at
    /// `t`; the cost drops from `O((N - n) p^2)` to `O((depth - n) p^2)` plus
    /// `O((K - depth) p^2 / 8)` for the binary digits of `t` beyond `depth` (byte tables).
    pub fn eval_unit_to_depth_into(&mut self, t: f64, depth: i64, out: &mut Vec<BasisValue>) {
        let n = self.basis.coarse() as i64;
        let top = (depth >= n).then(|| depth.min(self.basis.fine() as i64) as u32);
        self.eval_levels(t, out, top);
    }

    /// Only the scaling functions of `V_n` (global indices `< 2^n`) at `t` in `[0, 1]`: the
    /// single-scale evaluation used to evaluate a reconstruction after FWT synthesis.
    pub fn eval_scaling_unit_into(&mut self, t: f64, out: &mut Vec<BasisValue>) {
        self.eval_levels(t, out, None);
    }

    /// [`Evaluator::eval_unit_into`] with the digit states of `t` shared through `chains`
    /// with the other evaluators of the same coordinate (bases on the same filters and
    /// domain): the same values bit for bit ([`DigitChain`]).
    pub(crate) fn eval_unit_sharing_into(
        &mut self,
        t: f64,
        chains: &mut DigitChains,
        out: &mut Vec<BasisValue>,
    ) {
        self.eval_levels_sharing(t, out, Some(self.basis.fine()), chains);
    }

    /// [`Evaluator::eval_scaling_unit_into`] sharing `chains` as
    /// [`Evaluator::eval_unit_sharing_into`] does.
    pub(crate) fn eval_scaling_unit_sharing_into(
        &mut self,
        t: f64,
        chains: &mut DigitChains,
        out: &mut Vec<BasisValue>,
    ) {
        self.eval_levels_sharing(t, out, None, chains);
    }

    /// The scaling functions of `V_n` and the wavelets of levels `n..=wavelet_top` at `t`
    /// (`None`: no wavelet; `wavelet_top <= N`).
    fn eval_levels(&mut self, t: f64, out: &mut Vec<BasisValue>, wavelet_top: Option<u32>) {
        let mut chains = std::mem::take(&mut self.chains);
        self.eval_levels_sharing(t, out, wavelet_top, &mut chains);
        self.chains = chains;
    }

    /// [`Self::eval_levels`] with the digit states from `chains`.
    fn eval_levels_sharing(
        &mut self,
        t: f64,
        out: &mut Vec<BasisValue>,
        wavelet_top: Option<u32>,
        chains: &mut DigitChains,
    ) {
        let with_wavelets = wavelet_top.is_some();
        out.clear();
        let basis = self.basis;
        let bank = basis.bank();
        let p = bank.p();
        let e = bank.edge_count();
        let n = basis.coarse();
        let fine = wavelet_top.map_or(n, |j| j.min(basis.fine()));
        let top = if with_wavelets { fine + 1 } else { n };
        let pos = Position::new(t);
        let w = 2 * p - 1;

        // Left edge start level (first level at or beyond which the value is direct).
        let left_start =
            (e > 0 && !pos.one && pos.cell(n) < w as u64).then(|| edge_start(&pos, n, w));
        let hi = left_start.map_or(top, |s| s.max(top));
        self.walk
            .run(&bank.digits, &mut chains.interior, &pos, n, hi, fine);

        // Left edge values a_j, j = n..=top, and the scaling output.
        let mut left_levels = 0;
        if let (Some(start), Some(tab)) = (left_start, bank.left_tables.as_ref()) {
            left_levels = edge_recursion(&self.walk, &pos, tab, n, top, start, &mut self.edge);
        }

        // Right edge in the reflected coordinate.
        let right_cell = |j: u32| (1u64 << j) - 1 - pos.cell(j);
        let mut right_levels = 0;
        if e > 0 && right_cell(n) < w as u64 {
            let y = if pos.one { 0.0 } else { 1.0 - t };
            let ypos = Position::new(y);
            let start = edge_start(&ypos, n, w);
            self.mirror.run(
                &bank.reversed_digits,
                &mut chains.mirror,
                &ypos,
                n,
                start.max(top),
                n,
            );
            if let Some(tab) = bank.right_tables.as_ref() {
                right_levels = edge_recursion(
                    &self.mirror,
                    &ypos,
                    tab,
                    n,
                    top,
                    start,
                    &mut self.right_edge,
                );
            }
        }

        // Scaling functions at level n.
        let size = 1u64 << n;
        let sc = self.scale[n as usize];
        if left_levels > 0 {
            let c = pos.cell(n);
            let a = &self.edge[0..p];
            for (k, &ak) in a.iter().enumerate() {
                if c < (p + k) as u64 {
                    out.push(BasisValue {
                        index: k,
                        value: sc * ak,
                    });
                }
            }
        }
        push_interior(
            out,
            self.walk.level(n),
            self.walk.cell(n),
            p,
            e,
            size,
            0,
            sc,
        );
        if right_levels > 0 {
            let r = right_cell(n);
            for k in (0..p).rev() {
                if r < (p + k) as u64 {
                    out.push(BasisValue {
                        index: (size - 1) as usize - k,
                        value: sc * self.right_edge[k],
                    });
                }
            }
        }

        if !with_wavelets {
            return;
        }
        // Wavelets at levels n..=N.
        for j in n..=fine {
            let size = 1u64 << j;
            let sc = self.scale[j as usize];
            let base = size as usize;
            let c = pos.cell(j);
            if left_levels > 0 && c < w as u64 {
                let tab = bank
                    .left_tables
                    .as_ref()
                    .expect("edge tables exist when e > 0");
                let l = (j - n) as usize;
                edge_wavelets(
                    tab,
                    &self.edge[(l + 1) * p..(l + 2) * p],
                    &self.walk,
                    j + 1,
                    &mut self.phi,
                    &mut self.wavelet,
                );
                for (k, v) in self.wavelet.iter().enumerate() {
                    if c < (p + k) as u64 {
                        out.push(BasisValue {
                            index: base + k,
                            value: sc * v,
                        });
                    }
                }
            }
            push_interior(out, self.walk.wavelets(j), c, p, e, size, base, sc);
            let r = right_cell(j);
            if right_levels > 0 && r < w as u64 {
                let tab = bank
                    .right_tables
                    .as_ref()
                    .expect("edge tables exist when e > 0");
                let l = (j - n) as usize;
                edge_wavelets(
                    tab,
                    &self.right_edge[(l + 1) * p..(l + 2) * p],
                    &self.mirror,
                    j + 1,
                    &mut self.phi,
                    &mut self.wavelet,
                );
                for k in (0..p).rev() {
                    if r < (p + k) as u64 {
                        out.push(BasisValue {
                            index: base + (size - 1) as usize - k,
                            value: sc * self.wavelet[k],
                        });
                    }
                }
            }
        }
    }
}

/// Pushes the interior translates `m = c + p - 1 - i` (ascending) of one level.
#[allow(clippy::too_many_arguments)]
fn push_interior(
    out: &mut Vec<BasisValue>,
    vals: &[f64],
    c: u64,
    p: usize,
    e: usize,
    size: u64,
    base: usize,
    sc: f64,
) {
    let w = vals.len();
    for i in (0..w).rev() {
        let m = c as i64 + p as i64 - 1 - i as i64;
        if m >= e as i64 && m < size as i64 - e as i64 {
            out.push(BasisValue {
                index: base + m as usize,
                value: sc * vals[i],
            });
        }
    }
}

/// First level `>= lo` where the edge value is direct: the point is outside the edge support
/// `[0, 2p-1)` (value 0) or an integer (value at the integers).
fn edge_start(pos: &Position, lo: u32, w: usize) -> u32 {
    let mut j = lo;
    loop {
        if pos.cell(j) >= w as u64 || j >= pos.k {
            return j;
        }
        j += 1;
    }
}

/// Interior values `phi(2^j x - m)`, `m = p..3p-2`, from the walk.
fn interior_near_edge(walk: &Walk, j: u32, out: &mut [f64]) {
    let c = walk.cell(j) as i64;
    let v = walk.level(j);
    for (q, o) in out.iter_mut().enumerate() {
        let i = c - 1 - q as i64;
        *o = if (0..v.len() as i64).contains(&i) {
            v[i as usize]
        } else {
            0.0
        };
    }
}

/// Runs `a_j = sqrt2 H a_{j+1} + sqrt2 h phi_{j+1}` from `start` down to `lo`; stores `a_j` for
/// `j = lo..=top` in `edge` (`p` values per level). Returns the number of stored levels.
fn edge_recursion(
    walk: &Walk,
    pos: &Position,
    tab: &EdgeTables,
    lo: u32,
    top: u32,
    start: u32,
    edge: &mut Vec<f64>,
) -> usize {
    let p = tab.count;
    let w = 2 * p - 1;
    let levels = (top - lo + 1) as usize;
    edge.clear();
    edge.resize(levels * p, 0.0);
    let direct = |j: u32, a: &mut [f64]| {
        let c = pos.cell(j);
        if c < w as u64 && j >= pos.k {
            a.copy_from_slice(&tab.values_at_integers[c as usize]);
        } else {
            a.iter_mut().for_each(|x| *x = 0.0);
        }
    };
    let mut a = vec![0.0; p];
    let mut next = vec![0.0; p];
    let mut phi = vec![0.0; w];
    direct(start, &mut a);
    for j in (start..=top).filter(|&j| j >= lo) {
        direct(j, &mut next);
        let l = (j - lo) as usize;
        edge[l * p..(l + 1) * p].copy_from_slice(&next);
    }
    for j in (lo..start).rev() {
        interior_near_edge(walk, j + 1, &mut phi);
        for (k, nk) in next.iter_mut().enumerate() {
            *nk = dot(&tab.h_edge[k * p..(k + 1) * p], &a)
                + dot(&tab.h_interior[k * w..(k + 1) * w], &phi);
        }
        std::mem::swap(&mut a, &mut next);
        if j <= top {
            let l = (j - lo) as usize;
            edge[l * p..(l + 1) * p].copy_from_slice(&a);
        }
    }
    levels
}

/// Edge wavelet values `b_j = sqrt2 G a_{j+1} + sqrt2 g phi_{j+1}` into `out` (`p` values;
/// `phi` is scratch of length `2p - 1`).
fn edge_wavelets(
    tab: &EdgeTables,
    a_finer: &[f64],
    walk: &Walk,
    finer: u32,
    phi: &mut [f64],
    out: &mut [f64],
) {
    let p = out.len();
    let w = phi.len();
    interior_near_edge(walk, finer, phi);
    for (k, o) in out.iter_mut().enumerate() {
        *o = dot(&tab.g_edge[k * p..(k + 1) * p], a_finer)
            + dot(&tab.g_interior[k * w..(k + 1) * w], phi);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            let bank = crate::basis::FilterBank::new(p, crate::basis::FilterFamily::Extremal)
                .expect("bank");
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
                        let got: Vec<u64> =
                            chain.state(tab, &pos, j).iter().map(|v| v.to_bits()).collect();
                        let want: Vec<u64> =
                            walk_alone(tab, &pos, j).iter().map(|v| v.to_bits()).collect();
                        assert_eq!(got, want, "p = {p}, t = {t:e}, level {j}");
                    }
                }
            }
        }
    }
}
