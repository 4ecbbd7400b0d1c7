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
use super::digits::{matvec, DigitChain, DigitChains, Position};
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

#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
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
    /// Working vectors of [`edge_recursion`].
    edge_scratch: [Vec<f64>; 3],
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
            edge_scratch: Default::default(),
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
            left_levels = edge_recursion(
                &self.walk,
                &pos,
                tab,
                (n, top, start),
                &mut self.edge,
                &mut self.edge_scratch,
            );
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
                    (n, top, start),
                    &mut self.right_edge,
                    &mut self.edge_scratch,
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
/// `j = lo..=top` in `edge` (`p` values per level; `levels = (lo, top, start)`, `scratch`
/// the three working vectors, kept by the evaluator). Returns the number of stored levels.
fn edge_recursion(
    walk: &Walk,
    pos: &Position,
    tab: &EdgeTables,
    (lo, top, start): (u32, u32, u32),
    edge: &mut Vec<f64>,
    scratch: &mut [Vec<f64>; 3],
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
    let [a, next, phi] = scratch;
    for (v, len) in [(&mut *a, p), (&mut *next, p), (&mut *phi, w)] {
        v.clear();
        v.resize(len, 0.0);
    }
    direct(start, a);
    for j in (start..=top).filter(|&j| j >= lo) {
        direct(j, next);
        let l = (j - lo) as usize;
        edge[l * p..(l + 1) * p].copy_from_slice(next);
    }
    for j in (lo..start).rev() {
        interior_near_edge(walk, j + 1, phi);
        for (k, nk) in next.iter_mut().enumerate() {
            *nk = dot(&tab.h_edge[k * p..(k + 1) * p], a)
                + dot(&tab.h_interior[k * w..(k + 1) * w], phi);
        }
        std::mem::swap(a, next);
        if j <= top {
            let l = (j - lo) as usize;
            edge[l * p..(l + 1) * p].copy_from_slice(a);
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
